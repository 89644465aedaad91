"""Route planner (seed section 3.4): cubic segments between nodes, constraints, cost, speed profile.

For each pair of consecutive nodes the cubic family of seed eqs. (38)-(40f) has two free
parameters, the tangent magnitudes (a, b) (see ``lotsen.planning.cubic``). The planner

1. evaluates a coarse log-spaced grid of (a, b) plus the seed's own +-1 candidates at once with
   numpy on a coarse delta grid,
2. rejects candidates violating the length bound (40g), the curvature bound (40h), or the
   navigable water with clearance (shapely, vectorised over candidates),
3. picks the cheapest by V (41) and refines it continuously: by default a vectorised pattern
   search (5 x 5 grids of halving width, feasible points only); optionally a bounded Nelder-Mead
   (scipy.optimize), which reaches the same cost about 3.5 x slower (bench/bench_planning.py),
4. discretises the winner at <= spacing_m in arc length and re-verifies every constraint there,
5. when every length/curvature-feasible candidate is blocked by obstacles, inserts intermediate
   nodes along the shortest visibility-graph detour (scipy.sparse.csgraph) and plans those parts,
6. builds the speed reference (42) with lateral and longitudinal acceleration limits.

Pure: no I/O; errors are PlanningError / ConfigError naming the segment or node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Literal

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from lotsen.errors import ConfigError, PlanningError
from lotsen.model.angles import wrap_angle
from lotsen.planning import cubic
from lotsen.planning.dubins import dubins_waypoints, dubins_words
from lotsen.planning.path import Path, SegmentMetrics
from lotsen.planning.route import Route, RouteNode, validate_route
from lotsen.planning.speed import speed_profile
from lotsen.settings import number_of
from lotsen.settings import value_range as _r

#: extra clearance for the coarse candidate check: covers the chord-vs-arc sagitta between
#: coarse samples (<= (0.6 m)^2 / (8 R_min) for R_min >= 1 m); the fine check is exact.
_COARSE_MARGIN_M = 0.05


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings; lengths in metres, speeds m/s, accelerations m/s^2."""

    # seed eq. (40g): arc length <= ratio x straight distance
    length_ratio_max: float = field(default=1.15, metadata=_r(1.01, 10.0))
    min_turn_radius_m: float = field(default=1.0, metadata=_r(0.05, 100.0))  # seed eq. (40h): |curvature| <= 1 / R_min
    clearance_m: float = field(default=0.5, metadata=_r(0.0, 50.0))  # minimum distance to non-navigable water
    gamma1: float = field(default=1.0, metadata=_r(1e-6, 1e6))  # seed eq. (41): weight of sum l_disk (per metre)
    gamma2: float = field(default=0.01, metadata=_r(0.0, 1e6))  # seed eq. (41): weight of sum |c_disk| at spacing_m
    # extension: weight of bending energy int kappa^2 ds (m); 0 = seed
    gamma3: float = field(default=1.0, metadata=_r(0.0, 1e6))
    spacing_m: float = field(default=0.01, metadata=_r(0.001, 1.0))  # max distance between path points (seed: 1 cm)
    a_lat_max_mps2: float = field(default=0.3, metadata=_r(0.01, 10.0))  # v <= sqrt(a_lat_max / |kappa|)
    a_long_max_mps2: float = field(default=0.2, metadata=_r(0.01, 10.0))  # |dv/dt| <= a_long_max
    speed_max_mps: float = field(default=1.5, metadata=_r(0.05, 5.0))
    grid_n: int = field(default=9, metadata=_r(2, 50))  # coarse grid is grid_n x grid_n tangent-magnitude pairs
    # tangent magnitude range, as a fraction of straight distance
    tangent_min: float = field(default=0.1, metadata=_r(0.01, 10.0))
    tangent_max: float = field(default=2.5, metadata=_r(0.02, 20.0))
    refine: str = "zoom"                # refinement of the best grid candidate: "zoom" (vectorised
                                        # pattern search), "nelder-mead" (scipy, bounded) or "none"
    detour: bool = True                 # insert nodes around obstacles instead of failing
    stop_at_end: bool = True            # the path comes to rest at the last node, where the boat holds
                                        # after AUTO (brakes within a_long_max); false keeps its speed

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, (bool, str)):
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"planner.{f.name}: expected a finite number, got {v!r}")
        positive = ("min_turn_radius_m", "spacing_m", "a_lat_max_mps2", "a_long_max_mps2",
                    "speed_max_mps", "tangent_min", "tangent_max", "gamma1")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(f"planner.{name}: {getattr(self, name):g} must be positive")
        for name in ("clearance_m", "gamma2", "gamma3"):
            if getattr(self, name) < 0:
                raise ConfigError(f"planner.{name}: {getattr(self, name):g} is negative")
        if self.length_ratio_max <= 1.0:
            raise ConfigError(f"planner.length_ratio_max: {self.length_ratio_max:g} must exceed 1")
        if self.refine not in ("zoom", "nelder-mead", "none"):
            raise ConfigError(f"planner.refine: {self.refine!r} is not one of zoom, nelder-mead, none")
        if self.grid_n < 2:
            raise ConfigError(f"planner.grid_n: {self.grid_n} must be at least 2")
        if self.tangent_max <= self.tangent_min:
            raise ConfigError("planner.tangent_max must exceed planner.tangent_min")
        for f in fields(self):  # each setting's physical range (settings.Number; from a config or in code)
            number = number_of(f.metadata, integer=isinstance(getattr(self, f.name), int))
            if number is not None:
                number.check(getattr(self, f.name), f"planner.{f.name}")


# --------------------------------------------------------------------------------------------
# navigable water
# --------------------------------------------------------------------------------------------
class _Water:
    """Navigable water with the clearance applied, prepared for fast vectorised checks."""

    def __init__(self, route: Route, clearance_m: float) -> None:
        self.clearance_m = clearance_m
        self.free = route.free_region()
        self.safe = self.free.buffer(-(clearance_m + 1e-3), quad_segs=16)
        self.safe_coarse = self.free.buffer(-(clearance_m + _COARSE_MARGIN_M), quad_segs=16)
        self.boundary = self.free.boundary
        for g in (self.safe, self.safe_coarse, self.boundary):
            shapely.prepare(g)
        # named parts, to say *what* blocks a segment
        self.parts: list[tuple[str, object]] = []
        self.has_area = route.area is not None
        if route.area is not None:
            self.parts.append(("area", Polygon(route.area).exterior))
        for i, r in enumerate(route.obstacles):
            poly = Polygon(r.polygon)
            self.parts.append((f"obstacles[{i}]", poly if r.forbidden == "inside" else poly.exterior))

    def covers_coarse(self, pts: np.ndarray) -> np.ndarray:
        """pts (k, m, 2) -> bool (k,): polyline inside water with clearance (+ coarse margin)."""
        return shapely.covers(self.safe_coarse, shapely.linestrings(pts))

    def covers(self, pts: np.ndarray) -> bool:
        return bool(self.safe.covers(LineString(pts)))

    def clearance(self, pts: np.ndarray) -> float:
        return float(shapely.distance(self.boundary, LineString(pts)))

    def blockers(self, pts: np.ndarray) -> list[str]:
        line = LineString(pts)
        return [name for name, g in self.parts if g.distance(line) < self.clearance_m]

    def nearest_part(self, p: Point) -> tuple[str, float]:
        if not self.parts:
            return "navigable water", float(self.boundary.distance(p))
        d = [(g.exterior.distance(p) if isinstance(g, Polygon) else g.distance(p), name)
             for name, g in self.parts]
        dist, name = min(d)
        return name, float(dist)


# --------------------------------------------------------------------------------------------
# one segment
# --------------------------------------------------------------------------------------------
@dataclass
class _Piece:
    """A chosen cubic between two planner nodes."""

    coef: np.ndarray
    fine: dict
    label: str
    straight_m: float
    v0: float
    v1: float
    tried: int
    cost: float
    detour: bool = False


@dataclass
class _Failure:
    kind: Literal["geometry", "blocked"]
    reason: str
    tried: int


class _Basis:
    """Monomial basis of r, r', r'' on a fixed coarse delta grid, and trapezoid weights, so that
    evaluating k candidates is three small matrix products (the refinement calls this often)."""

    _cache: dict[int, "_Basis"] = {}

    def __init__(self, m: int) -> None:
        d = np.linspace(0.0, 1.0, m)
        one, zero = np.ones(m), np.zeros(m)
        self.B0 = np.stack([one, d, d**2, d**3], axis=1)                 # r   = B0 @ coef
        self.B1 = np.stack([zero, one, 2 * d, 3 * d**2], axis=1)         # r'  = B1 @ coef
        self.B2 = np.stack([zero, zero, 2 * one, 6 * d], axis=1)         # r'' = B2 @ coef
        w = np.full(m, 1.0 / (m - 1))
        w[0] = w[-1] = 0.5 / (m - 1)
        self.w = w                                                       # trapezoid in delta

    @classmethod
    def get(cls, m: int) -> "_Basis":
        if m not in cls._cache:
            cls._cache[m] = cls(m)
        return cls._cache[m]


def _candidate_stats(coef: np.ndarray, m: int, cfg: PlannerConfig):
    """Coarse evaluation of k candidates: points (k, m, 2), length, max |kappa|, cost V (k,)."""
    B = _Basis.get(m)
    r = B.B0 @ coef
    dr = B.B1 @ coef
    ddr = B.B2 @ coef
    speed = np.sqrt(dr[..., 0] ** 2 + dr[..., 1] ** 2)
    cross = np.abs(dr[..., 0] * ddr[..., 1] - dr[..., 1] * ddr[..., 0])
    speed = np.maximum(speed, 1e-12)
    abs_k = cross / speed**3                                    # |kappa|, seed eq. (40h)
    length = (speed @ B.w)                                      # int |r'| d delta
    turn = (cross / speed**2) @ B.w                             # int |kappa| ds
    bend = (abs_k * cross / speed**2) @ B.w                     # int kappa^2 ds
    # seed eq. (41): sum l_disk = length; sum |c_disk| at even spacing = int |kappa| ds / spacing
    cost = cfg.gamma1 * length + cfg.gamma2 * turn / cfg.spacing_m + cfg.gamma3 * bend
    max_k = abs_k.max(axis=-1)
    # A cusp (r' passes through zero: the curve stops and reverses) has no finite curvature at any
    # sample, so the curvature bound alone misses it. Between samples the tangent may turn at most
    # k_max x the arc length between them (+ slack); a reversal breaks that and is infeasible.
    ds = 0.5 * (speed[..., 1:] + speed[..., :-1]) * (1.0 / (m - 1))
    cos_turn = (dr[..., 1:, 0] * dr[..., :-1, 0] + dr[..., 1:, 1] * dr[..., :-1, 1]) / (speed[..., 1:] * speed[..., :-1])
    turn_between = np.arccos(np.clip(cos_turn, -1.0, 1.0))
    cusp = (turn_between > 1.5 * ds / cfg.min_turn_radius_m + 0.05).any(axis=-1)
    max_k = np.where(cusp, np.inf, max_k)
    return r, length, max_k, cost


def _coarse_points(straight_m: float) -> int:
    return int(np.clip(math.ceil(straight_m * 1.2 / 0.25), 48, 600))


def _plan_segment(p0: np.ndarray, psi0: float, p1: np.ndarray, psi1: float, water: _Water,
                  cfg: PlannerConfig, method: str = "optimise") -> tuple[np.ndarray, dict, int, float] | _Failure:
    """Choose the cubic between two poses.

    Returns (coef (4, 2), fine points, candidates evaluated, cost V) or a _Failure saying why.
    """
    straight = float(np.hypot(*(p1 - p0)))
    t0, t1 = cubic.unit_tangent(psi0), cubic.unit_tangent(psi1)
    k_max = 1.0 / cfg.min_turn_radius_m
    len_max = cfg.length_ratio_max * straight
    m = _coarse_points(straight)
    # the coefficients are affine in the tangent magnitudes: coef = C0 + a Ca + b Cb
    C0 = cubic.hermite_coefficients(p0, p1, t0, t1, 0.0, 0.0)
    Ca = cubic.hermite_coefficients(p0, p1, t0, t1, 1.0, 0.0) - C0
    Cb = cubic.hermite_coefficients(p0, p1, t0, t1, 0.0, 1.0) - C0
    tried = 0

    def coefs(ab: np.ndarray) -> np.ndarray:
        return C0 + ab[:, 0, None, None] * Ca + ab[:, 1, None, None] * Cb

    def evaluate(ab: np.ndarray):
        """-> points, length, max|kappa|, cost, geometry-ok, fully-feasible masks."""
        nonlocal tried
        tried += len(ab)
        pts, length, max_k, cost = _candidate_stats(coefs(ab), m, cfg)
        ok_len = length <= len_max * (1 - 1e-4)                         # seed eq. (40g)
        ok_k = max_k <= k_max * (1 - 1e-3)                              # seed eq. (40h)
        geom = ok_len & ok_k
        feas = geom.copy()
        if geom.any():
            feas[geom] = water.covers_coarse(pts[geom])                  # area, obstacles
        return pts, length, max_k, cost, ok_len, ok_k, feas

    # the seed's candidates: a base cubic (a = b = L), then each free parameter moved by +-1 in turn
    seed_ab = np.array([(straight, straight), (straight + 1, straight), (straight - 1, straight),
                        (straight, straight + 1), (straight, straight - 1)])
    seed_ab = seed_ab[(seed_ab > 0).all(axis=1)]
    if method == "seed":
        ab = seed_ab
    else:
        u = np.geomspace(cfg.tangent_min, cfg.tangent_max, cfg.grid_n) * straight
        ab = np.vstack([np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1).reshape(-1, 2), seed_ab])
    pts, length, max_k, cost, ok_len, ok_k, feas = evaluate(ab)
    if method != "seed" and not (ok_len & ok_k).any():
        # the feasible set can be a thin sliver between the length and curvature bounds: look
        # again on a dense grid before giving up (only on this rare path)
        u = np.geomspace(cfg.tangent_min, cfg.tangent_max, 4 * cfg.grid_n) * straight
        ab = np.vstack([ab, np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1).reshape(-1, 2)])
        pts, length, max_k, cost, ok_len, ok_k, feas = evaluate(ab)
    geom_ok = ok_len & ok_k
    if not geom_ok.any():
        turn_deg = math.degrees(abs(wrap_angle(psi1 - psi0)))
        if not ok_len.any():
            why = (f"the shortest candidate has length ratio {length.min() / straight:.2f} "
                   f"> {cfg.length_ratio_max:g}")
        elif not ok_k.any():
            why = (f"the smallest peak curvature is {max_k.min():.2f} 1/m > {k_max:.2f} 1/m "
                   f"(min turn radius {cfg.min_turn_radius_m:g} m)")
        else:
            why = (f"no candidate meets both length ratio <= {cfg.length_ratio_max:g} and "
                   f"curvature <= {k_max:.2f} 1/m")
        return _Failure("geometry", (
            f"a heading change of {turn_deg:.0f} deg over {straight:.2f} m cannot be met: {why}; "
            "move the nodes apart, align their headings with the leg, or add a node"), tried)
    if not feas.any():
        idx = np.flatnonzero(geom_ok)
        best_geom = idx[np.argmin(cost[idx])]
        names = water.blockers(pts[best_geom]) or ["non-navigable water"]
        return _Failure("blocked", (
            f"every candidate within the length and curvature bounds passes closer than "
            f"{cfg.clearance_m:g} m to {', '.join(names)}"), tried)
    order = np.flatnonzero(feas)[np.argsort(cost[feas])]
    choices = [(float(cost[i]), ab[i]) for i in order[:4]]

    if method != "seed" and cfg.refine != "none":
        lo, hi = math.log(cfg.tangent_min * straight), math.log(cfg.tangent_max * straight)
        step = math.log(cfg.tangent_max / cfg.tangent_min) / (cfg.grid_n - 1)
        x_best, c_best = np.log(choices[0][1]), choices[0][0]
        if cfg.refine == "zoom":
            # pattern search: 5 x 5 feasible-only grids around the incumbent, halving the width
            offs = np.linspace(-1.0, 1.0, 5)
            off2 = np.stack(np.meshgrid(offs, offs, indexing="ij"), axis=-1).reshape(-1, 2)
            width = step
            for _ in range(5):
                x = np.clip(x_best + width * off2, lo, hi)
                _, _, _, c, _, _, f = evaluate(np.exp(x))
                if f.any():
                    j = np.flatnonzero(f)[np.argmin(c[f])]
                    if c[j] < c_best:
                        x_best, c_best = x[j], float(c[j])
                width *= 0.5
        else:  # bounded Nelder-Mead (scipy) on V with a penalty outside the feasible set
            # scipy only where it is used: the web server and the recorder import planning for
            # its types and must not carry scipy (~45 MB a process)
            from scipy.optimize import minimize

            def objective(x: np.ndarray) -> float:
                _, ln, mk, v, _, _, f = evaluate(np.exp(x)[None])
                if f[0]:
                    return float(v[0])
                viol = max(0.0, ln[0] / len_max - 1) + max(0.0, mk[0] / k_max - 1)
                return float(v[0]) + 1e3 * (1 + viol)

            simplex = np.clip(np.array([x_best, x_best + [step / 2, 0], x_best + [0, step / 2]]), lo, hi)
            res = minimize(objective, x_best, method="Nelder-Mead", bounds=[(lo, hi), (lo, hi)],
                           options={"initial_simplex": simplex, "xatol": 1e-3,
                                    "fatol": 1e-5 * max(c_best, 1e-9), "maxfev": 80})
            if res.fun < c_best:
                x_best, c_best = res.x, float(res.fun)
        if c_best < choices[0][0]:
            choices.insert(0, (c_best, np.exp(x_best)))
    for c_v, ab_i in choices:
        c = coefs(np.asarray(ab_i)[None])[0]
        fine = _discretise(c, cfg.spacing_m)
        if _verify(fine, straight, water, cfg) is None:
            return c, fine, tried, c_v
    return _Failure("blocked", "no candidate passed the fine (1 cm) verification of the constraints", tried)


def _discretise(coef: np.ndarray, spacing_m: float) -> dict[str, np.ndarray]:
    """Points evenly spaced in arc length, at most spacing_m apart (seed: max 1 cm)."""
    n_dense = 257
    for _ in range(6):
        dense = np.linspace(0.0, 1.0, n_dense)
        _, dr, _ = cubic.evaluate(coef, dense)
        sp = np.hypot(dr[:, 0], dr[:, 1])
        # arc length s(delta) by the trapezoid rule on a dense grid, inverted by interpolation
        s_dense = np.concatenate([[0.0], np.cumsum(0.5 * (sp[1:] + sp[:-1]) * np.diff(dense))])
        n = max(1, math.ceil(s_dense[-1] / (0.98 * spacing_m)))
        delta = np.interp(np.linspace(0.0, s_dense[-1], n + 1), s_dense, dense)
        delta[0], delta[-1] = 0.0, 1.0
        r, dr, ddr = cubic.evaluate(coef, delta)
        if np.hypot(*np.diff(r, axis=0).T).max() <= spacing_m:
            break
        n_dense *= 4   # |r'| varies a lot along this cubic: invert s(delta) on a finer grid
    kappa, _ = cubic.curvature(dr, ddr)
    return {"pts": r, "heading": cubic.heading(dr), "kappa": kappa}


def _verify(fine: dict[str, np.ndarray], straight: float, water: _Water, cfg: PlannerConfig) -> str | None:
    """Exact constraint check on the fine points; None if all hold, else the violated one."""
    pts = fine["pts"]
    step = np.hypot(*np.diff(pts, axis=0).T)
    if step.max() > cfg.spacing_m:
        return "spacing"
    if step.sum() > cfg.length_ratio_max * straight:
        return "length"
    if not np.all(np.abs(fine["kappa"]) <= 1.0 / cfg.min_turn_radius_m):
        return "curvature"
    # heading continuity between points (catches a cusp, where the sampled curvature stays finite)
    dpsi = np.abs(np.diff(np.unwrap(fine["heading"])))
    if np.any(dpsi > 1.5 * step / cfg.min_turn_radius_m + 1e-3):
        return "curvature"
    if not water.covers(pts):
        return "clearance"
    return None


# --------------------------------------------------------------------------------------------
# detour around obstacles
# --------------------------------------------------------------------------------------------
def _visibility_path(p0: np.ndarray, p1: np.ndarray, water: _Water, offset_m: float) -> np.ndarray | None:
    """Shortest polyline p0 -> p1 whose legs stay in the water with clearance; corners are the
    vertices of the water shrunk by clearance + offset (so the smoothed curve has room)."""
    shrunk = water.free.buffer(-(water.clearance_m + offset_m), quad_segs=2).simplify(0.05)
    verts = []
    for poly in getattr(shrunk, "geoms", [shrunk]):
        if poly.is_empty:
            continue
        for ring in (poly.exterior, *poly.interiors):
            verts.extend(np.asarray(ring.coords)[:-1])
    pts = np.vstack([p0, p1, *verts]) if verts else np.vstack([p0, p1])
    n = len(pts)
    i, j = np.triu_indices(n, k=1)
    segs = np.stack([pts[i], pts[j]], axis=1)
    ok = water.covers_coarse(segs)
    w = np.hypot(*(pts[j] - pts[i]).T)
    i, j, w = i[ok], j[ok], w[ok]
    from scipy.sparse import csr_matrix  # see the Nelder-Mead branch: scipy only where used
    from scipy.sparse.csgraph import dijkstra

    graph = csr_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))), shape=(n, n))
    dist, pred = dijkstra(graph, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(dist[1]):
        return None
    order = [1]
    while order[-1] != 0:
        order.append(pred[order[-1]])
    return pts[order[::-1]]


def _detour(p0, psi0, v0, p1, psi1, v1, water: _Water, cfg: PlannerConfig, label: str
            ) -> list[_Piece] | None:
    r = cfg.min_turn_radius_m
    for offset in (0.5 * r, 1.0 * r, 2.0 * r, 3.0 * r):
        poly = _visibility_path(p0, p1, water, offset)
        if poly is None or len(poly) < 3:
            continue
        legs = np.diff(poly, axis=0)
        leg_len = np.hypot(*legs.T)
        u = legs / leg_len[:, None]
        bis = u[:-1] + u[1:]
        headings = [psi0, *np.arctan2(bis[:, 1], bis[:, 0]), psi1]   # along the detour
        frac = np.concatenate([[0.0], np.cumsum(leg_len)]) / leg_len.sum()
        speeds = v0 + (v1 - v0) * frac                                 # interpolated speeds
        pieces = []
        for k in range(len(poly) - 1):
            res = _plan_segment(poly[k], headings[k], poly[k + 1], headings[k + 1], water, cfg)
            if isinstance(res, _Failure):
                break
            coef, fine, tried, cost = res
            pieces.append(_Piece(coef, fine, f"{label} detour part {k}", float(leg_len[k]),
                                 float(speeds[k]), float(speeds[k + 1]), tried, cost, detour=True))
        else:
            return pieces
    return None


# --------------------------------------------------------------------------------------------
# whole route
# --------------------------------------------------------------------------------------------
def _check_nodes_against_config(nodes: list[RouteNode], labels: list[str], water: _Water,
                                cfg: PlannerConfig) -> None:
    for k, n in enumerate(nodes):
        if n.speed_mps > cfg.speed_max_mps:
            raise ConfigError(f"{labels[k]}.speed_mps: {n.speed_mps:g} exceeds speed_max_mps "
                              f"{cfg.speed_max_mps:g}")
        p = Point(n.north_m, n.east_m)
        if not water.safe.covers(p):
            at = f"{labels[k]} (north {n.north_m:g}, east {n.east_m:g})"
            if not water.free.covers(p):
                # outside the water altogether: its distance to an edge is no "clearance"
                where = "outside the navigable area" if water.has_area else "not in navigable water"
                inside = [name for name, g in water.parts if name.startswith("obstacles[")
                          and isinstance(g, Polygon) and g.covers(p)]
                raise PlanningError(f"{at} is {where}" + (f" (inside {', '.join(inside)})" if inside else "")
                                    + "; move it into open water")
            name, d = water.nearest_part(p)
            raise PlanningError(
                f"{at} is {d:.2f} m from {name}, closer than the clearance {cfg.clearance_m:g} m; "
                "move it into open water")


def _plan_pieces(nodes: list[RouteNode], labels: list[str], water: _Water, cfg: PlannerConfig,
                 method: str = "optimise") -> list[_Piece]:
    pieces: list[_Piece] = []
    for k in range(len(nodes) - 1):
        a, b = nodes[k], nodes[k + 1]
        p0, p1 = np.array([a.north_m, a.east_m]), np.array([b.north_m, b.east_m])
        label = f"segment {k} ({labels[k]} -> {labels[k + 1]})"
        res = _plan_segment(p0, a.heading_rad, p1, b.heading_rad, water, cfg, method)
        if isinstance(res, _Failure):
            if res.kind == "blocked" and cfg.detour and method != "seed":
                parts = _detour(p0, a.heading_rad, a.speed_mps, p1, b.heading_rad, b.speed_mps,
                                water, cfg, label)
                if parts is not None:
                    pieces.extend(parts)
                    continue
                raise PlanningError(f"{label}: {res.reason}, and no detour through the navigable "
                                    f"area with clearance {cfg.clearance_m:g} m was found")
            raise PlanningError(f"{label}: {res.reason}")
        coef, fine, tried, cost = res
        pieces.append(_Piece(coef, fine, label, float(np.hypot(*(p1 - p0))), a.speed_mps, b.speed_mps, tried, cost))
    return pieces


def _assemble(pieces: list[_Piece], water: _Water, cfg: PlannerConfig) -> Path:
    pts, hdg, kap, metrics_raw, node_s, node_v = [], [], [], [], [0.0], [pieces[0].v0]
    s0 = 0.0
    for j, pc in enumerate(pieces):
        fine = pc.fine
        sl = slice(0 if j == 0 else 1, None)   # consecutive pieces share their node point
        p = fine["pts"]
        length = float(np.hypot(*np.diff(p, axis=0).T).sum())
        pts.append(p[sl])
        hdg.append(fine["heading"][sl])
        kap.append(fine["kappa"][sl])
        metrics_raw.append((pc, p, length, s0, float(np.abs(fine["kappa"]).max())))
        s0 += length
        node_s.append(s0)
        node_v.append(pc.v1)
    P = np.concatenate(pts)
    kappa = np.concatenate(kap)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(P, axis=0).T))])
    v = speed_profile(s, kappa, np.array(node_s), np.array(node_v), cfg.a_lat_max_mps2,
                      cfg.a_long_max_mps2, cfg.speed_max_mps, rest_at_end=cfg.stop_at_end)
    metrics = []
    for pc, p, length, s_start, max_k in metrics_raw:
        step = max(1, int(round(0.05 / cfg.spacing_m)))            # clearance on a 5 cm subset
        sub = np.vstack([p[::step], p[-1:]])
        metrics.append(SegmentMetrics(
            label=pc.label, length_m=round(length, 4), straight_m=round(pc.straight_m, 4),
            length_ratio=round(length / pc.straight_m, 5), max_curvature_1pm=round(max_k, 5),
            min_clearance_m=round(water.clearance(sub), 4), candidates_tried=pc.tried,
            cost=round(pc.cost, 4), s_start_m=round(s_start, 4), s_end_m=round(s_start + length, 4),
            detour=pc.detour))
    return Path(north_m=P[:, 0], east_m=P[:, 1], heading_rad=np.concatenate(hdg),
                curvature_1pm=kappa, speed_mps=v, s_m=s, segments=tuple(metrics))


def plan_route(route: Route, config: PlannerConfig | None = None, method: str = "optimise") -> Path:
    """Plan the path harbour -> nodes[0] -> ... -> nodes[-1] (seed section 3.4).

    ``method="seed"`` reproduces the seed's candidate set (base cubic, each free parameter moved
    by +-1 in turn, no detours) for comparison.
    Raises ConfigError for invalid routes and PlanningError when a segment cannot be planned.
    """
    cfg = config or PlannerConfig()
    validate_route(route)
    water = _Water(route, cfg.clearance_m)
    nodes = route.all_nodes()
    labels = [Route.node_label(k) for k in range(len(nodes))]
    _check_nodes_against_config(nodes, labels, water, cfg)
    return _assemble(_plan_pieces(nodes, labels, water, cfg, method), water, cfg)


def plan_return_route(route: Route, north_m: float, east_m: float, heading_rad: float,
                      config: PlannerConfig | None = None, speed_mps: float | None = None,
                      arrival_heading_rad: float | None = None) -> Path:
    """Plan from the vessel's pose back to the harbour (arriving at speed 0), inside the water.

    For each arrival heading (``arrival_heading_rad``, or by default both the harbour heading and
    its reverse, since the harbour heading is the departure direction and a boat usually comes
    back the way it left) the planner tries the direct cubic (with obstacle detours); if one
    segment cannot turn enough (the harbour is behind the vessel), Dubins paths at 2, 3 and 5 x the
    minimum turn radius give intermediate nodes (turn, run, turn), planned as usual. The shortest
    feasible path wins. ``speed_mps`` is the cruise speed back (default: median route speed).
    """
    cfg = config or PlannerConfig()
    validate_route(route)
    for name, v in (("north_m", north_m), ("east_m", east_m), ("heading_rad", heading_rad)):
        if not math.isfinite(v):
            raise ConfigError(f"return start {name}: {v} is not a finite number")
    if speed_mps is None:
        speed_mps = float(np.median([n.speed_mps for n in route.nodes])) or 0.5
    speed_mps = min(max(speed_mps, 0.05), cfg.speed_max_mps)
    water = _Water(route, cfg.clearance_m)
    start = RouteNode(north_m, east_m, heading_rad, speed_mps)
    h = route.harbour
    if math.hypot(north_m - h.north_m, east_m - h.east_m) < 0.05:
        raise PlanningError("return route: the vessel is already at the harbour")
    _check_nodes_against_config([start], ["return start"], water, cfg)
    arrivals = ([h.heading_rad, wrap_angle(h.heading_rad + math.pi)]
                if arrival_heading_rad is None else [arrival_heading_rad])
    best: Path | None = None
    errors = []
    for psi_goal in arrivals:
        goal = RouteNode(h.north_m, h.east_m, psi_goal, 0.0)
        try:
            path = _return_path(start, goal, water, cfg)
        except PlanningError as exc:
            errors.append(f"arriving at {math.degrees(psi_goal):.0f} deg: {exc}")
            continue
        if best is None or path.length_m < best.length_m:
            best = path
    if best is None:
        raise PlanningError("return route: no path back to the harbour found (" + "; ".join(errors) + ")")
    return best


def _return_path(start: RouteNode, goal: RouteNode, water: _Water, cfg: PlannerConfig) -> Path:
    try:
        return _assemble(_plan_pieces([start, goal], ["start", "harbour"], water, cfg), water, cfg)
    except PlanningError as exc:
        first_error = exc
    s_pose = (start.north_m, start.east_m, start.heading_rad)
    g_pose = (goal.north_m, goal.east_m, goal.heading_rad)
    for factor in (2.0, 3.0, 5.0):
        radius = factor * cfg.min_turn_radius_m
        for _, word, params in dubins_words(s_pose, g_pose, radius):
            poses = dubins_waypoints(s_pose, word, params, radius)
            nodes = [start] + [RouteNode(n, e, psi, start.speed_mps) for n, e, psi in poses[:-1]] + [goal]
            labels = ["start"] + [f"turn node {i}" for i in range(len(nodes) - 2)] + ["harbour"]
            try:
                return _assemble(_plan_pieces(nodes, labels, water, cfg), water, cfg)
            except PlanningError:
                continue
    raise first_error
