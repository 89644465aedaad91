"""The identification problem, frozen: what is to be estimated from what, judged on which data.

One `IdentificationProblem` is what `lotsen identify`, the lab loop and the benches hand to
`lotsen.sysid.identify.identify`: the records to estimate from and the held-out records that judge
the answer (and where they come from), the coefficients' names, physical bounds and scale, the values
fixed with where each came from, the optional model terms, the hull's measured geometry, whether the
lake's environment (current, wind, gusts) is estimated too, and how the solvers run. Estimators
(lotsen.sysid.estimators) read it and never change it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

from lotsen.messages import SeaState
from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselGeometry, VesselParameters
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.sysid.data import IdRecord
from lotsen.sysid.estimate import NAMES, SCALE_GROUP, SolverOptions, parameter_bounds, parameter_scale

#: CPU seconds per row of a record (estimation and held-out rows together), measured on this project's
#: 2-core machine with the whole `identify` (equation error, output error, prediction; 2026-11-28): calm
#: 10-min records of the 6-DOF hull (33 600 rows) 4.4 s, 0.13 ms a row, of lotsen's simulator (14 400
#: rows) 2.8 s, 0.19 ms; lake records of the hull 12.3 s (0.37 ms), of lotsen's simulator 12.9 s
#: (0.90 ms). Rounded up, so that the time said first is not an underestimate.
CPU_S_PER_ROW = {"calm": 2.5e-4, "lake": 1.0e-3, "single": 1.0e-4}
#: the default budget of one identification: a record that would need more is refused before any work,
#: with the time it would take (a 50-MB record of repeated zigzags computed for minutes without a word)
DEFAULT_BUDGET_CPU_S = 120.0


@dataclass(frozen=True)
class IdentificationProblem:
    """Records, held-out records, what is fixed and why, and how to estimate (module docstring)."""

    records: tuple[IdRecord, ...]
    validation: tuple[IdRecord, ...]
    fixed: Mapping[str, float] = field(default_factory=dict)
    #: where each fixed value came from ("--fix", "the default scale", "boat file", ...): the parameter
    #: file says the answer holds only if these are right
    provenance: Mapping[str, str] = field(default_factory=dict)
    geometry: VesselGeometry = DEFAULT_GEOMETRY
    start: VesselParameters = DEFAULT_PARAMETERS  # --init: where a search without a better start begins
    in_use: VesselParameters | None = None  # the model the boat flies now (None: `start`): the judge's baseline
    lake: bool = False  # current, wind and gusts estimated with the coefficients
    terms: tuple[str, ...] | None = None  # optional model terms to estimate; None: chosen by held-out prediction
    method: str = "multiple"  # "multiple": equation error + multiple shooting; "single": windowed single shooting
    #: which data judged the answer, as the report and the parameter file say it
    validation_source: str = ""
    held_out: bool = True  # the validation records were not estimated from
    solver: SolverOptions = SolverOptions()
    #: the records' sea state from their own IMU (lotsen.sysid.waves; None: not known, no IMU)
    sea: SeaState | None = None

    @property
    def model_in_use(self) -> VesselParameters:
        return self.in_use or self.start

    @property
    def gap_s(self) -> float:
        return self.solver.gap_s

    @property
    def free_names(self) -> tuple[str, ...]:
        """The coefficients estimated: every one not fixed (an optional term only when named in `terms`
        or while `terms` is still to be chosen)."""
        return tuple(n for n in NAMES if n not in self.fixed
                     and (n not in OPTIONAL_TERMS or self.terms is None or n in self.terms))

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        """Each coefficient's physical range (the parameter metadata, seed eq. 16a-c strict)."""
        lo, hi = parameter_bounds()
        return {n: (float(a), float(b)) for n, a, b in zip(NAMES, lo, hi)}

    @property
    def scale(self) -> dict[str, float]:
        """Each coefficient's typical magnitude: relative steps and relative uncertainties."""
        return dict(zip(NAMES, map(float, parameter_scale(self.start.with_updates(**self.fixed).to_vector()))))

    @property
    def anchor(self) -> str | None:
        """The fixed coefficient that sets the common scale of mass, damping and thrust."""
        return next((n for n in SCALE_GROUP if n in self.fixed), None)

    @property
    def tested_fixed(self) -> tuple[str, ...]:
        """Fixed values other than the scale's anchor: assumptions the record can contradict."""
        return tuple(n for n in self.fixed if n != self.anchor)

    def solver_options(self, **changes: object) -> SolverOptions:
        """The solvers' options for this problem (its geometry and lake flag), with `changes`."""
        return replace(self.solver, geometry=self.geometry, lake=self.lake, **changes)  # type: ignore[arg-type]

    @property
    def n_rows(self) -> int:
        rows = sum(len(r.t) for r in self.records)
        if self.held_out:
            rows += sum(len(r.t) for r in self.validation)
        return rows

    def expected_cpu_s(self) -> float:
        """About how long the identification will take (CPU seconds; CPU_S_PER_ROW), before any work."""
        kind = "single" if self.method == "single" else ("lake" if self.lake else "calm")
        return self.n_rows * CPU_S_PER_ROW[kind]


def held_out_split(records: Sequence[IdRecord], validation: Sequence[IdRecord] | None,
                   holdout: float) -> tuple[tuple[IdRecord, ...], tuple[IdRecord, ...], str, bool]:
    """(records to estimate from, records to judge on, which data judge, whether they are held out):
    `validation` when given (another record); else the last `holdout` of each record; with neither,
    the estimation data themselves (nothing held out: an answer is then not judged on new data)."""
    records = tuple(records)
    if validation:
        return records, tuple(validation), ", ".join(r.source for r in validation) + " (another record)", True
    if holdout > 0:
        est, val = [], []
        for r in records:
            t_split = r.t[0] + (1 - holdout) * r.duration_s
            est.append(r.slice(r.t[0], t_split))
            val.append(r.slice(t_split, r.t[-1] + 1))
        src = f"the last {100 * holdout:.0f} % of " + ", ".join(r.source for r in records)
        return tuple(est), tuple(val), src, True
    return records, records, "the estimation data themselves (nothing held out)", False


def budget_refusal(problem: IdentificationProblem, budget_cpu_s: float) -> str | None:
    """Why the problem is too large for `budget_cpu_s` (None when it fits), said before any work."""
    need = problem.expected_cpu_s()
    if need <= budget_cpu_s:
        return None
    total_s = sum(r.duration_s for r in problem.records)
    fit_s = total_s * budget_cpu_s / need
    return (f"{problem.n_rows} rows ({total_s / 60:.1f} min of record) would take about {_minutes(need)} of CPU, "
            f"more than the budget of {_minutes(budget_cpu_s)}: identify a part of it (about "
            f"{math.floor(fit_s / 60):.0f} min fits; a 10-min record determines the coefficients), or raise the "
            "budget with --max-cpu")


def _minutes(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"

