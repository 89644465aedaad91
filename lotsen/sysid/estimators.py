"""Estimators of one identification problem: `estimator.estimate(problem, start) -> Estimate`.

Every estimator reads the frozen problem (lotsen.sysid.problem) and a start, and returns an
`Estimate`: the coefficients with their covariance and intervals, whether and where the search
converged, the lake's environment it found, and its own diagnostics. None of them judges: the one
judge (lotsen.sysid.judge) scores every estimate alike on the held-out data.

- `EquationError`: the equations of motion fitted to the record (lotsen.sysid.equation_error); it
  depends on the data only, and is the other estimators' start.
- `OutputError`: multiple shooting over the whole record (lotsen.sysid.multiple); on a lake a
  steady-wind stage, then the gust factors free.
- `SingleShooting`: Levenberg-Marquardt in independent windows (lotsen.sysid.estimate; --method single).

The shooting intervals of `OutputError` are independent given the parameters: the command hands a
parallel map (lotsen.sysid.parallel) to its constructor, and the algorithm stays pure; the answer is
the same to the last digit with 1 and N workers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from lotsen.model import VesselParameters
from lotsen.sysid.data import MEAN_FORWARD, IdRecord
from lotsen.sysid.equation_error import EquationErrorResult, estimate_equation_error
from lotsen.sysid.estimate import (
    NAMES, EstimationError, Identifiability, IdentificationResult, SolverOptions, estimate, parameter_bounds,
)
from lotsen.sysid.multiple import (
    MultipleShootingProblem, MultipleShootingResult, ShootingStart, estimate_multiple_shooting, shooting_point,
)
from lotsen.sysid.parallel import SERIAL, Map
from lotsen.sysid.problem import IdentificationProblem
from lotsen.sysid.sensitivity import ENV_NAMES

Progress = Callable[[int, float], None]

#: from the equation-error start a boat built like the model converges in 5-10 iterations; after this
#: many a record the model cannot explain is recognised (multiple.estimate_multiple_shooting's misfit_check)
MISFIT_CHECK_ITERATIONS = 15
STEADY_WIND_ITERATIONS = 8  # the lake model's steady-wind stages (the environment alone, then with the coefficients)
GUST_ITERATIONS = 60  # its last stage, per noise pass
# ... and both of its passes together: a record the model does not explain, whose gusts kept the track test
# from stopping it, ran 20 + 16 (the 6-DOF hull's lake record, seed 2: 17 s of CPU, the 20-s bar near); a
# record of the model's structure converged in 35 (lotsen's lake record 2500: 11 s)
GUST_TOTAL_ITERATIONS = 80
# the wind's drag coefficients in the output-error lake model: within this fraction of the nominal hull's
# (1 % was right for lotsen's own generator, whose boat has exactly the nominal coefficients; another
# hull's wind is another form, and the equation-error start has found its values)
LAKE_WIND_SPREAD = 0.5
# in calm water the track's correlation shows a model that cannot explain the record sooner (no gusts
# to settle): 10 iterations from the equation-error start (a boat built like the model: converged in 7)
CALM_MISFIT_CHECK_ITERATIONS = 10


@dataclass(frozen=True)
class Start:
    """Where an estimator starts: coefficients, and on a lake the environment (ENV_NAMES order)."""

    params: VesselParameters
    environment: np.ndarray | None = None


@dataclass
class Estimate:
    """One estimator's answer (module docstring). `result` holds the values, their std and covariance,
    the free names, the iterations, whether the search converged and the identifiability analysis."""

    estimator: str  # "equation error" | "output error" | "single shooting"
    result: IdentificationResult
    environment: np.ndarray | None = None  # lake: the ENV_NAMES values it predicts with
    diagnostics: MultipleShootingResult | EquationErrorResult | None = None

    @property
    def params(self) -> VesselParameters:
        return self.result.params

    @property
    def converged(self) -> bool:
        return self.result.converged

    @property
    def physical(self) -> bool:
        """Whether the estimate claims to be the hull's physical coefficients when the judge finds no
        fault: the output-error estimates (maximum likelihood of the record); the equation-error fit is
        biased by the noise in its regressors and is effective at best."""
        return self.estimator != "equation error"

    @property
    def shooting(self) -> MultipleShootingResult | None:
        d = self.diagnostics
        return d if isinstance(d, MultipleShootingResult) else None

    def at_bounds(self) -> list[str]:
        """The free coefficients that ended at a physical bound, as "NAME = VALUE"."""
        lo, hi = parameter_bounds()
        out = []
        for n in self.result.free_names:
            i = NAMES.index(n)
            v = getattr(self.params, n)
            if v <= lo[i] or v >= hi[i]:
                out.append(f"{n} = {v:g}")
        return out


class EquationError:
    """The equations of motion fitted to the record (lotsen.sysid.equation_error); `terms`: the optional
    model terms estimated; `hold`: another equation-error estimate of the same records whose motion
    samples are taken and whose kappa, current and wind are kept (the optional terms' trial solves only
    the linear part again); its
    independent solves run on `parallel` (lotsen.sysid.parallel)."""

    name = "equation error"

    def __init__(self, terms: Sequence[str] = (), hold: Estimate | None = None, parallel: Map = SERIAL) -> None:
        self.terms = tuple(terms)
        self.hold = hold
        self.parallel = parallel

    def estimate(self, problem: IdentificationProblem, start: Start) -> Estimate:
        bias0 = None
        if problem.lake:
            bias0 = MultipleShootingProblem(problem.records,
                                            problem.solver_options(gyro_bias=True)).initial_gyro_bias()
        held = self.hold.diagnostics if self.hold is not None else None
        ee = estimate_equation_error(problem.records, problem.fixed, start.params,
                                     problem.solver_options(terms=self.terms), bias0,
                                     hold=held if isinstance(held, EquationErrorResult) else None,
                                     parallel=self.parallel)
        return Estimate(self.name, equation_error_result(ee, problem.fixed), ee.environment, ee)


def equation_error_result(ee: EquationErrorResult, fixed: dict | object) -> IdentificationResult:
    """An equation-error estimate as an IdentificationResult (diagonal covariance from its intervals)."""
    names = tuple(ee.free_names)
    std = {n: float(ee.std.get(n, math.inf)) for n in names}
    var = np.array([std[n] ** 2 if math.isfinite(std[n]) else np.inf for n in names])
    rel = {n: std[n] / abs(getattr(ee.params, n)) if getattr(ee.params, n) else math.inf for n in names}
    ident = Identifiability(np.zeros(0), [], False, rel, [n for n in names if rel[n] * 1.96 > 0.05], math.inf)
    fisher = np.diag(np.where(np.isfinite(var) & (var > 0), 1.0 / np.where(var > 0, var, 1.0), 0.0))
    return IdentificationResult(ee.params, std, dict(fixed), names, np.diag(var), fisher,  # type: ignore[arg-type]
                                np.zeros((0, 6)), ee.cost, 0, 1.0, 0, True, ident, "equation error")


class OutputError:
    """Multiple shooting over the whole record from the start (lotsen.sysid.multiple); on a lake the
    coefficients, current and steady wind together (gust factors held) for a few iterations, then the
    gust factors free. Stopped early when the track's errors stay correlated (a model that cannot
    explain the record: no physical answer will come of more iterations). The shooting intervals run
    on `parallel` (lotsen.sysid.parallel: the built-in map, or the command's pool)."""

    name = "output error"

    def __init__(self, progress: Progress | None = None, parallel: Map = SERIAL) -> None:
        self.progress = progress
        self.parallel = parallel

    def estimate(self, problem: IdentificationProblem, start: Start) -> Estimate:
        terms = tuple(problem.terms or ())
        if not problem.lake:
            calm = problem.solver_options(test_fixed=problem.tested_fixed, misfit_check=CALM_MISFIT_CHECK_ITERATIONS,
                                          terms=terms)
            res = estimate_multiple_shooting(problem.records, start.params, problem.fixed, calm, progress=self.progress,
                                             parallel=self.parallel)
            res = reconstruction_spread(problem.records, res, calm, self.parallel)
            return Estimate(self.name, res, None, res.details)
        # the steady-wind stages only bring coefficients, current and wind together before the gusts are
        # released: a few iterations each, the noise as assumed (its residuals carry the gusts by design)
        steady = problem.solver_options(gust_std=1e-3, max_iterations=STEADY_WIND_ITERATIONS, estimate_noise=False,
                                        wind_coefficient_spread=LAKE_WIND_SPREAD, terms=terms)
        # first the environment alone, the coefficients held at the start, from no wind (estimate_lake's
        # stage 0). From the equation-error fit's own environment the search fell into a wrong basin on
        # lotsen's lake records (seed 2500: m22 +6 %, X_uu -17 %, the track's errors correlated, no physical
        # answer in 60 iterations; that environment fits the equation-error coefficients better, so the
        # lower cost does not tell the basins apart); from no wind it reaches the boat's (core within
        # 0.6 %, converged in 35 iterations, 11 s)
        held = {**start.params.to_dict(), **problem.fixed}
        _, zero = shooting_point(problem.records, start.params, held, steady, parallel=self.parallel)
        params, first = shooting_point(problem.records, start.params, problem.fixed, steady, zero, self.progress,
                                       parallel=self.parallel)
        # the gusts free: a hard budget too (the gust factors can absorb the track's errors of a model that
        # does not explain the boat, so the track test alone let one record crawl 120 iterations, 58 s)
        gusts = problem.solver_options(max_iterations=min(problem.solver.max_iterations, GUST_ITERATIONS),
                                       test_fixed=problem.tested_fixed, misfit_check=MISFIT_CHECK_ITERATIONS,
                                       total_iterations=GUST_TOTAL_ITERATIONS,
                                       wind_coefficient_spread=LAKE_WIND_SPREAD, terms=terms)
        res = estimate_multiple_shooting(problem.records, params, problem.fixed, gusts, first, self.progress,
                                         parallel=self.parallel)
        res = reconstruction_spread(problem.records, res, gusts, self.parallel)
        return Estimate(self.name, res, _environment_of(res), res.details)


def reconstruction_spread(records: Sequence[IdRecord], res: IdentificationResult,
                          options: SolverOptions, parallel: Map = SERIAL) -> IdentificationResult:
    """`res` with the uncertainty of how the inputs moved within their logged intervals in its covariance.

    Achieved actuator values logged as interval means (input kind "mean") are reconstructed piecewise
    linearly, each interval's slope from its neighbours' means; the slope from the next interval alone
    (MEAN_FORWARD) is as defensible a guess, and the record cannot tell them apart. The estimate under
    that reconstruction, one Gauss-Newton step from `res` (the shift is small: one step reproduced the
    full re-estimation on 12 records), moves by h; the covariance grows by h h^T, as the two gust
    models' average does (the central reconstruction lies halfway between the two one-sided ones).
    Measured on 12 calm 10-min records of one boat of the model's structure (lotsen's simulator): the
    reported std was 0.51 of the spread over records (median over the 17 coefficients), the truth within
    3 sigma in 79 %; with the spread 0.93 and 96 %; on the same records with exact inputs it was 1.4
    without any spread, so this reconstruction was most of the over-confidence."""
    if not any(r.input_kind == "mean" for r in records) or not isinstance(res.details, MultipleShootingResult):
        return res
    d = res.details
    variant = [replace(r, input_kind=MEAN_FORWARD) if r.input_kind == "mean" else r for r in records]
    one = replace(options, max_iterations=1, total_iterations=None, estimate_noise=False, noise_std=d.noise_std,
                  test_fixed=(), misfit_check=0)
    env = list(d.environment.values.values()) if d.environment is not None else None
    try:
        moved, _ = shooting_point(variant, res.params, res.fixed, one, ShootingStart(d.nodes, env, d.gyro_bias),
                                  parallel=parallel)
    except EstimationError:
        return res
    names = res.free_names
    h = np.array([getattr(moved, n) - getattr(res.params, n) for n in names])
    cov = np.asarray(res.covariance, float) + np.outer(h, h)
    std = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(names)}
    shift = {n: float(h[i] / res.std[n]) if res.std[n] > 0 else math.inf for i, n in enumerate(names)}
    return replace(res, covariance=cov, std=std, details=replace(d, reconstruction_shift=shift))


class SingleShooting:
    """Levenberg-Marquardt in independent windows of `problem.solver.window_s` (lotsen.sysid.estimate):
    unbiased on sample-aligned data, but the windows throw information away (kept for comparison)."""

    name = "single shooting"

    def __init__(self, progress: Progress | None = None) -> None:
        self.progress = progress

    def estimate(self, problem: IdentificationProblem, start: Start) -> Estimate:
        if problem.lake:
            raise EstimationError("--method single has no lake model (current, wind): use the default multiple "
                                  "shooting with --lake")
        res = estimate(problem.records, start.params, problem.fixed, problem.solver_options(),
                       progress=self.progress)
        return Estimate(self.name, res, None, None)


def _environment_of(res: IdentificationResult) -> np.ndarray | None:
    env = res.details.environment if isinstance(res.details, MultipleShootingResult) else None
    if env is None:
        return None
    return np.array([env.values[n] for n in ENV_NAMES])
