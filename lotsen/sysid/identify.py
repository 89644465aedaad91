"""One identification, for the command, the lab loop and the benches alike: `identify(problem)`.

The problem (lotsen.sysid.problem) says what to estimate from what; the estimators
(lotsen.sysid.estimators) answer it: the equation-error fit first (it depends on the data alone),
the optional model terms it needs, then the output-error estimate from there (multiple shooting;
on a lake with current, wind and gusts), or single shooting in windows (`method="single"`); the one
judge (lotsen.sysid.judge) scores them all on the held-out records and writes the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from lotsen.messages import SeaState
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.sysid.data import IdRecord, check_excitation, check_record, split_segments
from lotsen.sysid.estimate import EstimationError
from lotsen.sysid.estimators import EquationError, Estimate, OutputError, SingleShooting, Start
from lotsen.sysid.judge import Identification, judge
from lotsen.sysid.parallel import SERIAL, Map
from lotsen.sysid.prediction import PredictionWindows, improvement, prediction_windows, score_windows
from lotsen.sysid.problem import IdentificationProblem, held_out_split

TERM_MIN_IMPROVEMENT = 0.05  # an optional model term is turned on when it predicts this much better

Say = Callable[[str], None]


@dataclass(frozen=True)
class Prepared:
    """What the identification of a problem needs that depends on its records alone, when the caller
    makes it beside the estimators (the command, in a process of its own): a getter each, asked for only
    where it is needed. The records' sea state (in place of `problem.sea`), the prediction windows of the
    estimation records (`estimation_windows`: the optional terms' choice) and of the held-out records
    (lotsen.sysid.judge.held_out_windows: the judge)."""

    sea: Callable[[], SeaState | None]
    estimation_windows: Callable[[], PredictionWindows]
    held_out_windows: Callable[[], PredictionWindows]


def identify(problem: IdentificationProblem, progress: Say | None = None, parallel: Map = SERIAL,
             prepared: Prepared | None = None) -> Identification:
    """The identification of `problem` (module docstring; docs/sysid.md, "How `lotsen identify`
    answers"). `progress` is told each stage and iteration in words; `parallel` is the map the
    estimators' independent pieces run on (lotsen.sysid.parallel: the same answer with any number of
    workers); `prepared`: what depends on the records alone, made by the caller beside the estimators
    (None: made here when needed). Raises DataError for a record no estimator can use,
    IdentifiabilityError when the only estimate leaves a direction undetermined."""
    say = progress or (lambda _msg: None)
    # the data's own faults first, in their own words (no excitation, a motionless boat, ...)
    for r in problem.records:
        check_record(r)
    check_excitation([seg for r in problem.records for seg in split_segments(r, problem.gap_s)])
    count = [0]

    def iteration(_i: int, cost: float) -> None:
        count[0] += 1
        say(f"iteration {count[0]}: cost {cost:.5g}")

    if problem.method == "single":
        say("single shooting in windows")
        single = SingleShooting(iteration).estimate(problem, Start(problem.start))
        return _judged(problem, [single], prepared)
    say("equation-error start")
    try:
        ee: Estimate | None = EquationError(tuple(problem.terms or ()), None, parallel).estimate(problem,
                                                                                               Start(problem.start))
    except (ValueError, np.linalg.LinAlgError, EstimationError):
        ee = None  # too few fixes for the splines: the output-error estimate starts from the problem's start
    note = ""
    if problem.terms is None:
        problem, ee, note = choose_terms(problem, ee, say, parallel,
                                         prepared.estimation_windows if prepared is not None else None)
    start = Start(ee.params, ee.environment) if ee is not None else Start(problem.start)
    say("output-error estimate (multiple shooting)")
    oe = OutputError(iteration, parallel).estimate(problem, start)
    say("open-loop prediction of the held-out data")
    ident = _judged(problem, [oe] + ([ee] if ee is not None else []), prepared)
    if note:
        ident.advice.insert(0, note)
    return ident


def _judged(problem: IdentificationProblem, estimates: list[Estimate], prepared: Prepared | None) -> Identification:
    if prepared is None:
        return judge(problem, estimates)
    return judge(replace(problem, sea=prepared.sea()), estimates, prepared.held_out_windows())


def estimation_windows(problem: IdentificationProblem) -> PredictionWindows:
    """The windows of the estimation records the optional terms are chosen on: the records alone decide."""
    return prediction_windows(problem.records, gap_s=problem.gap_s)


def choose_terms(problem: IdentificationProblem, ee: Estimate | None, say: Say, parallel: Map = SERIAL,
                 windows: Callable[[], PredictionWindows] | None = None
                 ) -> tuple[IdentificationProblem, Estimate | None, str]:
    """The optional model terms (lotsen.model.parameters.OPTIONAL_TERMS) the record needs: each turned on
    where the equation-error fit with it predicts the estimation records measurably better
    (TERM_MIN_IMPROVEMENT). Chosen on the estimation data, so that the held-out records judge the answer
    on data the choice was not made on. Returns the problem with its terms, the equation-error estimate
    to start from, and a note for the advice. `windows`: a getter of `estimation_windows(problem)` made
    beforehand."""
    cand = tuple(n for n in OPTIONAL_TERMS if n not in problem.fixed)
    off = replace(problem, terms=())
    if ee is None or not cand:
        return off, ee, ""
    say("optional model terms: " + ", ".join(cand))
    try:
        with_terms = EquationError(cand, ee, parallel).estimate(replace(problem, terms=cand), Start(problem.start))
    except (ValueError, np.linalg.LinAlgError, EstimationError):
        return off, ee, ""
    pw = windows() if windows is not None else estimation_windows(problem)  # the same windows for both
    s0, s1 = (score_windows(e.params, pw, problem.geometry, e.environment) for e in (ee, with_terms))
    gain = improvement(s1, s0) if s0.n_windows and s1.stable else 0.0
    many = len(cand) > 1
    if gain >= TERM_MIN_IMPROVEMENT:
        note = (f"optional term{'s' if many else ''} {', '.join(cand)} on: "
                + "; ".join(OPTIONAL_TERMS[n] for n in cand)
                + f" (the equation-error fit with {'them' if many else 'it'} predicts the estimation records "
                f"{100 * gain:.0f} % better)")
        return replace(problem, terms=cand), with_terms, note
    return off, ee, (f"optional term{'s' if many else ''} {', '.join(cand)} left off (with {'them' if many else 'it'} "
                     f"the prediction of the estimation records changes by {100 * gain:+.0f} %)")


def split_holdout(records: Sequence[IdRecord], holdout: float) -> tuple[list[IdRecord], list[IdRecord]]:
    """Each record cut in time: the first 1 - `holdout` for estimation, the rest for validation."""
    est, val, _, _ = held_out_split(records, None, holdout)
    return list(est), list(val)
