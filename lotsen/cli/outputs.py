"""What the commands write: plots and reports, checked before any work and written atomically.

Every output goes through `lotsen.files.atomic_output` / `write_output` (a temporary file beside
it, renamed over it at the end: a failed command leaves the old file whole) after
`lotsen.files.check_outputs` (its folder exists, it is not one of the command's inputs, hard and
symbolic links included, and no two outputs are one file). A plot's format is its suffix, checked
here before the command computes anything.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Iterable

from lotsen.errors import ConfigError
from lotsen.files import atomic_output

#: the suffixes a plot may have (matplotlib's Agg backend writes each by its suffix)
PLOT_FORMATS = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def check_plot_name(path: str | None, flag: str = "--plot") -> None:
    """Refuse a plot name whose suffix is not a format we write (before any work)."""
    if path is None:
        return
    suffix = Path(path).suffix.lower()
    if suffix not in PLOT_FORMATS:
        raise ConfigError(f"{flag} {path}: a plot is written in the format of its suffix, one of "
                          f"{', '.join(PLOT_FORMATS)} (got {suffix or 'none'!r})")


def save_plot(path: str, draw: Callable[[Path], Any], inputs: Iterable[str | None] = ()) -> None:
    """`draw(tmp)` writes the figure to a temporary file that becomes `path` when it succeeded."""
    check_plot_name(path)
    with atomic_output(path, inputs, ConfigError, "plot") as tmp:
        draw(tmp)
