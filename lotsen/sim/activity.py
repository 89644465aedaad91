"""How hard a trace's actuators worked (issue 46): servo travel, propeller speed change and reversals,
the motors' electrical energy and where it went. Pure functions of a trace (times and [alpha1, alpha2,
n1, n2, nt] rows), so a mission in simulated time, a live run's log and a bench measure alike."""

from __future__ import annotations

import math

import numpy as np

from lotsen.sim.simulator import propulsion_energy_j

#: a propeller's speed must leave +-this band on the other side to count as a reversal
REVERSAL_BAND_RPS = 5.0


def propeller_reversals(speeds_rps: np.ndarray, band_rps: float = REVERSAL_BAND_RPS) -> list[int]:
    """Reversals per propeller (columns of `speeds_rps`, rows in time): sign changes of the speed
    beyond +-band_rps (a speed within the band keeps the last direction)."""
    out = []
    for col in np.asarray(speeds_rps, dtype=float).reshape(len(speeds_rps), -1).T:
        d = np.sign(col) * (np.abs(col) > band_rps)
        d = d[d != 0]
        out.append(int(np.count_nonzero(d[1:] != d[:-1])))
    return out


def actuator_activity(t_s: np.ndarray, actuators: np.ndarray) -> dict[str, float]:
    """How hard the actuators work over a trace (rows [alpha1, alpha2, n1, n2, nt] at times t_s): the
    servos' azimuth travel (deg/s, both units summed), the propellers' speed change (rev/s per s, all
    three summed), their reversals per second (`propeller_reversals`) and the motors' electrical
    energy (J, `lotsen.sim.propulsion_energy_j`) and mean power (W). A controller that chases wave
    motion shows it here first: travel, speed change and reversals grow while tracking does not improve.
    Per propeller (azimuth 1, azimuth 2, bow): the energy and the reversals, and for the azimuths the
    share of the time astern (beyond REVERSAL_BAND_RPS): an azimuth pushing astern against the other, or
    the bow thruster holding a steady push, is where a mission's energy goes when it costs more than its
    route needs."""
    t = np.asarray(t_s, dtype=float)
    a = np.asarray(actuators, dtype=float).reshape(len(t), 5)
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if span <= 0.0:
        return {}
    # per propeller (the other two columns zeroed): the total is their sum (the power is a sum over them)
    by_propeller = [propulsion_energy_j(t, a[:, 2:5] * (np.arange(3) == i)) for i in range(3)]
    energy = sum(by_propeller)
    reversals = propeller_reversals(a[:, 2:5])
    return {"azimuth_travel_deg_per_s": round(math.degrees(float(np.sum(np.abs(np.diff(a[:, :2], axis=0))))) / span, 3),
            "propeller_speed_change_rps_per_s": round(float(np.sum(np.abs(np.diff(a[:, 2:5], axis=0)))) / span, 3),
            "reversals_per_s": round(sum(reversals) / span, 4),
            "reversals_per_s_by_propeller": [round(k / span, 4) for k in reversals],
            "energy_J": round(energy, 2), "mean_power_W": round(energy / span, 3),
            "energy_J_by_propeller": [round(e, 1) for e in by_propeller],
            "azimuth_astern_share": [round(float(np.mean(a[:, 2 + i] < -REVERSAL_BAND_RPS)), 3) for i in range(2)]}
