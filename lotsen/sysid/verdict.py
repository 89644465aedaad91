"""Whether an identification result may be used: a verdict in operator language.

An estimate is only as good as the model's fit to the record. Three things make the numbers
untrustworthy however small their intervals: the solver did not converge, a coefficient ended
at its physical bound (the data pull it somewhere unphysical), or the residuals of the track
stay correlated over a second or more, which means something the model lacks (a current, wind,
an actuator effect such as weaker astern thrust) drove the boat and the coefficients absorbed
it. Then the verdict is "refused" and `lotsen identify` exits non-zero; the loaders of parameter
files refuse such a file. Coefficients whose relative 1-sigma exceeds 7 % are "weakly
determined": up to four make the verdict "weak" (usable, named); more make it "refused". The core
coefficients a controller leans on are promised within 5 %: one whose relative 1-sigma exceeds
2.5 % (its 2-sigma interval wider than that promise) makes the verdict "refused".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

WEAK_RELATIVE_SIGMA = 0.07  # above this a coefficient is weakly determined
# above this a core coefficient is not determined well enough for the controller: with honest
# intervals a 2.5 % sigma leaves ~5 % odds of an error beyond 5 % (a random boat 10-40 % off the
# defaults answered Y_v 6.5 % off with a 3.3 % sigma under the old 7 % rule)
CORE_RELATIVE_SIGMA = 0.025
MAX_WEAK = 4  # more weakly determined coefficients than this: refused
# lag-1 s autocorrelation of the position residuals: white sensor noise gives ~0.1-0.2 on this
# project's records (a boat equal to its model); an unmodelled drive gives 0.7-1.0
MAX_TRACK_AUTOCORR = 0.5
TRACK_OUTPUTS = ("north", "east")
#: the coefficients a controller leans on (and a real hull is least sure of: they differ most from
#: the textbook prior); none of them may be weakly determined
CORE_PARAMETERS = ("m22", "m33", "X_u", "X_uu", "Y_v", "N_r", "mu_az", "mu_t")


@dataclass
class Verdict:
    verdict: str  # "ok" | "weak" | "refused"
    reasons: list[str] = field(default_factory=list)
    weakly_determined: list[str] = field(default_factory=list)
    track_autocorr_1s: float | None = None

    def to_json_dict(self) -> dict:
        return {"verdict": self.verdict, "reasons": list(self.reasons),
                "weakly_determined": list(self.weakly_determined),
                "track_autocorr_1s": None if self.track_autocorr_1s is None else round(self.track_autocorr_1s, 3)}


def judge(converged: bool, iterations: int, at_bounds: Sequence[str], relative_sigma: Mapping[str, float],
          residual_autocorr: Mapping[str, np.ndarray] | None, lag_1s: int = 8,
          core: Sequence[str] = ()) -> Verdict:
    """The verdict on one identification result (`lag_1s`: measurements per second of the track;
    `core`: the coefficients a controller leans on, which may not be weakly determined)."""
    reasons: list[str] = []
    if not converged:
        reasons.append(f"the estimate did not converge in {iterations} iterations: no set of coefficients "
                       "fits this record well")
    if at_bounds:
        reasons.append(f"{', '.join(at_bounds)} ended at the physical bound: the data pull "
                       f"{'it' if len(at_bounds) == 1 else 'them'} where no real hull is")
    ac = None
    if residual_autocorr:
        vals = [float(residual_autocorr[n][lag_1s - 1]) for n in TRACK_OUTPUTS
                if n in residual_autocorr and len(residual_autocorr[n]) >= lag_1s]
        ac = float(np.mean(vals)) if vals else None
        if ac is not None and ac > MAX_TRACK_AUTOCORR:
            reasons.append(f"the model does not explain the track: its errors stay correlated over 1 s "
                           f"({ac:.2f}; sensor noise alone gives about 0.2). Something the model lacks drove "
                           "the boat (a current, wind, weaker astern thrust, an offset GNSS antenna): the "
                           "coefficients took it up and their intervals are too narrow. Record in calm water, "
                           "give the hull's known geometry, or fix the coefficients you know")
    weak = sorted((n for n, r in relative_sigma.items() if r > WEAK_RELATIVE_SIGMA), key=lambda n: -relative_sigma[n])
    weak_core = sorted((n for n in core if relative_sigma.get(n, 0.0) > CORE_RELATIVE_SIGMA),
                       key=lambda n: -relative_sigma[n])
    if weak_core:
        listed = ", ".join(f"{n} +-{relative_sigma[n] * 100:.1f} %" for n in weak_core)
        reasons.append(f"the controller's core coefficients are not determined well enough ({listed}; 1-sigma "
                       f"above {CORE_RELATIVE_SIGMA * 100:.1f} %, they must be within 5 %): record longer or "
                       "richer manoeuvres")
    if len(weak) > MAX_WEAK:
        reasons.append(f"{len(weak)} coefficients are weakly determined (1-sigma above "
                       f"{WEAK_RELATIVE_SIGMA * 100:.0f} %: {', '.join(weak)}): record longer or richer "
                       "manoeuvres, or fix some of them")
    verdict = "refused" if reasons else ("weak" if weak else "ok")
    return Verdict(verdict, reasons, weak, ac)
