"""Errors that lotsen reports to a person: the message says what is wrong and where."""


class LotsenError(Exception):
    """Base class of every error meant for the operator (CLI prints it without a traceback)."""


class ConfigError(LotsenError):
    """A configuration, route, experiment or parameter file is invalid."""


class PlanningError(LotsenError):
    """A route cannot be planned; the message names the segment or node and the reason."""


class DataError(LotsenError):
    """Input data (CSV, log, sensor stream) cannot be used; the message names file and row."""
