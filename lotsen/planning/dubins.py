"""Shortest curvature-bounded paths between two poses (Dubins), used to seed return-to-harbour.

A Dubins path (turn-straight-turn or turn-turn-turn at a fixed radius) tells which way to turn
and where; ``dubins_waypoints`` converts it into route nodes (every <= 60 deg of turning), which the
cubic planner then smooths under its own constraints. Formulas after Shkel & Lumelsky (2001),
in the normalised frame (start at origin, goal on the x axis, distance d = D / R); the words are
verified by integration, so a wrong word can never be returned.
"""

from __future__ import annotations

import math

from lotsen.model.angles import TWO_PI as _TWO_PI, wrap_angle


def _mod(x: float) -> float:
    return x % _TWO_PI


def _words(alpha: float, beta: float, d: float) -> dict[str, tuple[float, float, float]]:
    sa, sb, ca, cb = math.sin(alpha), math.sin(beta), math.cos(alpha), math.cos(beta)
    c_ab = math.cos(alpha - beta)
    out: dict[str, tuple[float, float, float]] = {}
    p_sq = 2 + d * d - 2 * c_ab + 2 * d * (sa - sb)
    if p_sq >= 0:
        tmp = math.atan2(cb - ca, d + sa - sb)
        out["LSL"] = (_mod(tmp - alpha), math.sqrt(p_sq), _mod(beta - tmp))
    p_sq = 2 + d * d - 2 * c_ab + 2 * d * (sb - sa)
    if p_sq >= 0:
        tmp = math.atan2(ca - cb, d - sa + sb)
        out["RSR"] = (_mod(alpha - tmp), math.sqrt(p_sq), _mod(tmp - beta))
    p_sq = -2 + d * d + 2 * c_ab + 2 * d * (sa + sb)
    if p_sq >= 0:
        p = math.sqrt(p_sq)
        tmp = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        out["LSR"] = (_mod(tmp - alpha), p, _mod(tmp - beta))
    p_sq = -2 + d * d + 2 * c_ab - 2 * d * (sa + sb)
    if p_sq >= 0:
        p = math.sqrt(p_sq)
        tmp = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        out["RSL"] = (_mod(alpha - tmp), p, _mod(beta - tmp))
    tmp = (6 - d * d + 2 * c_ab + 2 * d * (sa - sb)) / 8
    if abs(tmp) <= 1:
        phi = math.atan2(ca - cb, d - sa + sb)
        p = _mod(_TWO_PI - math.acos(tmp))
        t = _mod(alpha - phi + _mod(p / 2))
        out["RLR"] = (t, p, _mod(alpha - beta - t + _mod(p)))
    tmp = (6 - d * d + 2 * c_ab + 2 * d * (sb - sa)) / 8
    if abs(tmp) <= 1:
        phi = math.atan2(ca - cb, d + sa - sb)
        p = _mod(_TWO_PI - math.acos(tmp))
        t = _mod(-alpha - phi + p / 2)
        out["LRL"] = (t, p, _mod(_mod(beta) - alpha - t + _mod(p)))
    return out


def _step(x: float, y: float, th: float, kind: str, amount: float, radius: float):
    """Move along one primitive in the math frame (x east, y north, th counter-clockwise)."""
    if kind == "S":
        return x + amount * radius * math.cos(th), y + amount * radius * math.sin(th), th
    if kind == "L":
        return (x + radius * (math.sin(th + amount) - math.sin(th)),
                y - radius * (math.cos(th + amount) - math.cos(th)), th + amount)
    return (x - radius * (math.sin(th - amount) - math.sin(th)),
            y + radius * (math.cos(th - amount) - math.cos(th)), th - amount)


def dubins_words(start: tuple[float, float, float], goal: tuple[float, float, float],
                 radius_m: float) -> list[tuple[float, str, tuple[float, float, float]]]:
    """All valid Dubins words from start to goal, shortest first: (length_m, word, (t, p, q)).

    Poses are (north_m, east_m, heading_rad) in NED.
    """
    x0, y0, th0 = start[1], start[0], math.pi / 2 - start[2]
    x1, y1, th1 = goal[1], goal[0], math.pi / 2 - goal[2]
    dx, dy = x1 - x0, y1 - y0
    d = math.hypot(dx, dy) / radius_m
    theta = _mod(math.atan2(dy, dx)) if d > 0 else 0.0
    alpha, beta = _mod(th0 - theta), _mod(th1 - theta)
    found = []
    for word, params in _words(alpha, beta, d).items():
        x, y, th = x0, y0, th0
        for kind, amount in zip(word, params):
            x, y, th = _step(x, y, th, kind, amount, radius_m)
        err = math.hypot(x - x1, y - y1) + radius_m * abs(wrap_angle(th - th1))
        if err < 1e-6 * max(1.0, radius_m * d):
            found.append((radius_m * sum(params), word, params))
    return sorted(found)


def dubins_waypoints(start: tuple[float, float, float], word: str, params: tuple[float, float, float],
                     radius_m: float, max_turn_rad: float = math.pi / 3,
                     min_gap_m: float = 0.3) -> list[tuple[float, float, float]]:
    """Poses (north, east, heading) along a Dubins path: after each primitive and every
    ``max_turn_rad`` inside arcs. Excludes the start pose, includes the goal."""
    x, y, th = start[1], start[0], math.pi / 2 - start[2]
    poses = []
    for kind, amount in zip(word, params):
        pieces = 1 if kind == "S" else max(1, math.ceil(amount / max_turn_rad - 1e-9))
        for _ in range(pieces):
            x, y, th = _step(x, y, th, kind, amount / pieces, radius_m)
            poses.append((y, x, wrap_angle(math.pi / 2 - th)))
    # drop poses closer than min_gap to the previous kept one (short straights), never the goal
    kept: list[tuple[float, float, float]] = []
    prev = (start[0], start[1])
    for i, p in enumerate(poses):
        last = i == len(poses) - 1
        if math.hypot(p[0] - prev[0], p[1] - prev[1]) < min_gap_m:
            if last:
                if kept:
                    kept[-1] = p
                else:
                    kept.append(p)
            continue
        kept.append(p)
        prev = (p[0], p[1])
    return kept
