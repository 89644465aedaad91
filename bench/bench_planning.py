"""Route planning benchmark: a 20-node route (target <= 100 ms), refinement variants, and the
seed's +-1 candidate method as the peer (cost V of eq. 41 and time, in the same run).

    python -m bench.run planning     (harness)    or    python bench/bench_planning.py
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np

from lotsen.errors import PlanningError
from lotsen.planning import HarbourNode, PlannerConfig, Region, Route, RouteNode, plan_route

TARGET_MS = 100.0


def twenty_node_route(seed: int = 3) -> Route:
    """20 nodes on a wavy loop in a 40 m x 40 m basin, headings perturbed +-20 deg, speeds
    0.4-0.8 m/s, with two obstacles off the path (they still cost a clearance check per candidate)."""
    rng = np.random.default_rng(seed)
    nodes = []
    for k in range(20):
        th = 2 * math.pi * (k + 1) / 21
        rad = 14.0 + 2.5 * math.sin(3 * th)
        n, e = 20 + rad * math.sin(th), 20 - rad * math.cos(th)
        nodes.append(RouteNode(n, e, th + math.radians(rng.uniform(-20, 20)), float(rng.uniform(0.4, 0.8))))
    return Route(HarbourNode(20.0, 4.0, 0.0), tuple(nodes),
                 area=((0.0, 0.0), (40.0, 0.0), (40.0, 40.0), (0.0, 40.0)),
                 obstacles=(Region(((18.0, 18.0), (22.0, 18.0), (22.0, 22.0), (18.0, 22.0))),
                            Region(((34.0, 36.0), (37.0, 36.0), (37.0, 39.0), (34.0, 39.0)))))


def _time(fn, runs: int):
    out, times = None, []
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return out, statistics.median(times)


def run(quick: bool = False) -> list[dict]:
    runs = 3 if quick else 7
    route = twenty_node_route()
    rows = []
    plan_route(route)  # warm-up (imports, caches)
    variants = [("grid 9x9 + zoom refinement (default)", PlannerConfig(), "optimise"),
                ("grid 9x9 + Nelder-Mead (scipy)", PlannerConfig(refine="nelder-mead"), "optimise"),
                ("grid 9x9 only", PlannerConfig(refine="none"), "optimise"),
                ("seed: base cubic, free coefficients +-1", PlannerConfig(), "seed")]
    base_v = base_ms = None
    for name, cfg, method in variants:
        try:
            path, ms = _time(lambda: plan_route(route, cfg, method=method), runs)
        except PlanningError as exc:
            rows.append({"case": name, "nodes": 21, "median_ms": None, "target_ms": TARGET_MS,
                         "pass": False, "cost_V": None, "note": f"failed: {exc}"})
            continue
        v = sum(m.cost for m in path.segments)
        if base_v is None:
            base_v, base_ms = v, ms
        is_default = base_ms == ms   # the target applies to the default planner
        rows.append({
            "case": name, "nodes": 21, "median_ms": round(ms, 1),
            "target_ms": TARGET_MS if is_default else None,
            "pass": bool(ms <= TARGET_MS) if is_default else None, "cost_V": round(v, 3), "V_ratio_to_default": round(v / base_v, 4),
            "time_ratio_to_default": round(ms / base_ms, 2), "length_m": round(path.length_m, 2),
            "max_curvature_1pm": round(float(np.abs(path.curvature_1pm).max()), 3),
            "candidates": sum(m.candidates_tried for m in path.segments), "points": len(path),
        })
    # a route that needs a detour around an obstacle on the straight line
    blocked = Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(30.0, 0.0, 0.0, 0.5),),
                    area=((-5.0, -15.0), (40.0, -15.0), (40.0, 15.0), (-5.0, 15.0)),
                    obstacles=(Region(((12.0, -3.0), (16.0, -3.0), (16.0, 3.0), (12.0, 3.0))),))
    path, ms = _time(lambda: plan_route(blocked), runs)
    rows.append({"case": "detour: obstacle on the straight line (1 segment)", "nodes": 2,
                 "median_ms": round(ms, 1), "target_ms": TARGET_MS, "pass": bool(ms <= TARGET_MS),
                 "cost_V": round(sum(m.cost for m in path.segments), 3), "length_m": round(path.length_m, 2),
                 "max_curvature_1pm": round(float(np.abs(path.curvature_1pm).max()), 3),
                 "candidates": sum(m.candidates_tried for m in path.segments), "points": len(path)})
    rows.extend(_robustness(n_segments=60 if quick else 200))
    return rows


def _robustness(n_segments: int) -> list[dict]:
    """Single segments with random end headings (+-60 deg off the leg, 3-15 m): how often does each
    method find a feasible cubic, and how do the costs compare where both do."""
    from lotsen.planning.planner import _Failure, _plan_segment, _Water

    rng = np.random.default_rng(7)
    cfg = PlannerConfig()
    water = _Water(Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(1.0, 0.0, 0.0, 0.5),),
                         area=((-30.0, -30.0), (30.0, -30.0), (30.0, 30.0), (-30.0, 30.0))), cfg.clearance_m)
    ok = {"optimise": 0, "seed": 0}
    ratios, t = [], {"optimise": 0.0, "seed": 0.0}
    for _ in range(n_segments):
        d = rng.uniform(3.0, 15.0)
        leg = rng.uniform(-math.pi, math.pi)
        p0 = np.zeros(2)
        p1 = d * np.array([math.cos(leg), math.sin(leg)])
        psi0, psi1 = leg + math.radians(rng.uniform(-60, 60)), leg + math.radians(rng.uniform(-60, 60))
        res = {}
        for method in ok:
            t0 = time.perf_counter()
            r = _plan_segment(p0, psi0, p1, psi1, water, cfg, method)
            t[method] += time.perf_counter() - t0
            if not isinstance(r, _Failure):
                ok[method] += 1
                res[method] = r[3]
        if len(res) == 2:
            ratios.append(res["seed"] / res["optimise"])
    return [{"case": f"random single segments (+-60 deg): {m}", "segments": n_segments,
             "feasible_pct": round(100.0 * ok[m] / n_segments, 1),
             "mean_ms_per_segment": round(1e3 * t[m] / n_segments, 2),
             "V_seed_over_optimise_median": round(float(np.median(ratios)), 4) if ratios else None,
             "V_seed_over_optimise_max": round(float(np.max(ratios)), 4) if ratios else None}
            for m in ok]


if __name__ == "__main__":
    for row in run():
        print(row)
