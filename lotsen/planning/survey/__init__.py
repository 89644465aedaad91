"""Survey patterns: parallel lines over an area (or given lines), with turnaround, entry corner,
crosshatch and one-sided spacing, expanded into route nodes the planner plans as usual.

    from lotsen.planning.survey import SurveyPattern, expand_survey, survey_lines
"""

from lotsen.planning.survey.expand import SurveyPlan, expand_survey, survey_polygon
from lotsen.planning.survey.lines import SurveyLine, coverage_polygon, strip_of, survey_lines
from lotsen.planning.survey.pattern import SurveyPattern, pattern_from_dict, pattern_to_dict

__all__ = ["SurveyLine", "SurveyPattern", "SurveyPlan", "coverage_polygon", "expand_survey", "pattern_from_dict",
           "pattern_to_dict", "strip_of", "survey_lines", "survey_polygon"]
