"""One identification as `lotsen identify` makes it, for the command and the lab loop alike.

`estimate_records` runs the chosen estimator (multiple shooting by default; `lake=True` adds the
current, the wind and the gusts; `method="single"` the windowed single shooting), and
`judge_identification` turns its result into what the parameter file holds: the coefficients,
their intervals, the verdict (lotsen.sysid.verdict) and, for lake records, the environment. A
result whose data leave a parameter direction undetermined is refused with an error
(`check_identifiable`), never written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselGeometry, VesselParameters
from lotsen.sysid.data import IdRecord
from lotsen.sysid.estimate import estimate, parameter_bounds
from lotsen.sysid.multiple import check_identifiable, estimate_lake_averaged, estimate_multiple_shooting
from lotsen.sysid.verdict import CORE_PARAMETERS, Verdict, judge

NAMES_INDEX = {n: i for i, n in enumerate(DEFAULT_PARAMETERS.names())}


def split_holdout(records: Sequence[IdRecord], holdout: float) -> tuple[list[IdRecord], list[IdRecord]]:
    """Each record cut in time: the first 1 - `holdout` for estimation, the rest for validation."""
    est, val = [], []
    for r in records:
        t_split = r.t[0] + (1 - holdout) * r.duration_s
        est.append(r.slice(r.t[0], t_split))
        val.append(r.slice(t_split, r.t[-1] + 1))
    return est, val


def estimate_records(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                     fixed: Mapping[str, float] | None = None, *, method: str = "multiple", lake: bool = False,
                     geometry: VesselGeometry = DEFAULT_GEOMETRY, noise_std: Mapping[str, float] | None = None,
                     window_s: float = 10.0, gap_s: float = 1.0, node_s: float = 2.0, max_iterations: int = 60,
                     gust_std: float = 0.3, estimate_noise: bool = True, gyro_offset: bool = False,
                     progress: Callable[[int, float], None] | None = None) -> Any:
    """The estimate on `records` from `theta0` with `fixed` held: single shooting in `window_s`
    windows (`method="single"`), the lake model (`lake=True`, always with a yaw-rate offset per
    record), or multiple shooting (`gyro_offset`: a constant yaw-rate offset per record too)."""
    fixed = dict(fixed or {})
    noise = dict(noise_std or {})
    if method == "single":
        return estimate(records, theta0, fixed, window_s=window_s, gap_s=gap_s, noise_std=noise,
                        geometry=geometry, max_iterations=max_iterations, progress=progress)
    if lake:
        return estimate_lake_averaged(records, theta0, fixed, gust_std=gust_std, gap_s=gap_s, noise_std=noise,
                                      geometry=geometry, node_s=node_s, max_iterations=max_iterations,
                                      estimate_noise=estimate_noise, progress=progress)
    return estimate_multiple_shooting(records, theta0, fixed, gap_s=gap_s, noise_std=noise, geometry=geometry,
                                      node_s=node_s, max_iterations=max_iterations,
                                      estimate_noise=estimate_noise, progress=progress, gyro_bias=gyro_offset)


def parameters_at_bounds(res: Any) -> list[str]:
    """The free coefficients that ended at a physical bound, as "NAME = VALUE"."""
    lo, hi = parameter_bounds()
    out = []
    for n in res.free_names:
        i = NAMES_INDEX[n]
        v = getattr(res.params, n)
        if v <= lo[i] or v >= hi[i]:
            out.append(f"{n} = {v:g}")
    return out


def identification_verdict(res: Any, at_bounds: Sequence[str]) -> Verdict:
    """The verdict on an identification result (lotsen.sysid.verdict.judge); the core coefficients
    a controller leans on may not be weakly determined."""
    rel_sigma = {n: res.std[n] / abs(getattr(res.params, n)) if getattr(res.params, n) else math.inf
                 for n in res.free_names}
    return judge(res.converged, res.iterations, [b.split(" = ")[0] for b in at_bounds], rel_sigma,
                 getattr(res.details, "residual_autocorr", None), core=CORE_PARAMETERS)


@dataclass
class Identification:
    """An identification result with its verdict: what `lotsen identify --out` writes."""

    result: Any  # IdentificationResult or MultipleShootingResult
    at_bounds: list[str]
    verdict: Verdict

    @property
    def refused(self) -> bool:
        return self.verdict.verdict == "refused"

    def to_json_dict(self) -> dict:
        """The parameter file: the coefficients, "std", "verdict", "identification" (the verdict's
        reasons) and, for lake records, "environment" (the non-numbers the loaders skip)."""
        res = self.result
        out = res.to_json_dict()
        v = self.verdict.to_json_dict()
        out.update(verdict=v.pop("verdict"), identification=v)
        env = getattr(res.details, "environment", None)
        if env is not None:
            out["environment"] = {"values": env.values, "std": env.std,
                                  "gust_factor_mean": float(env.gust_factor.mean()),
                                  "gust_factor_std": float(env.gust_factor.std()),
                                  "autocorrelation_factor": env.autocorrelation_factor}
        shift = getattr(res.details, "gust_interval_shift", None)
        if shift is not None:
            # null for a coefficient without a sigma to measure the shift in (strict JSON has no inf)
            out["gust_interval_shift_sigma"] = {n: round(v, 2) if math.isfinite(v) else None
                                                for n, v in shift.items()}
        return out


def judge_identification(res: Any) -> Identification:
    """Refuse an undetermined result (IdentifiabilityError), then judge it."""
    check_identifiable(res)
    at_bounds = parameters_at_bounds(res)
    return Identification(res, at_bounds, identification_verdict(res, at_bounds))
