"""`lotsen plan ROUTE.yaml --out path.json --plot path.png`: plan a route, save and draw the path."""

from __future__ import annotations

import argparse
import json
import math

from lotsen.cli.outputs import check_plot_name, save_plot
from lotsen.errors import ConfigError
from lotsen.files import atomic_output, check_outputs, write_output
from lotsen.settings import Number

#: the flags' physical ranges (the route file's own limits: lotsen.planning.route)
COORDINATE = Number(-2000.0, 2000.0, "m")
HEADING_DEG = Number(-360.0, 360.0, "deg")
NODE_SPEED = Number(0.05, 5.0, "m/s")  # a moving node's speed (lotsen.planning.route.MIN/MAX_SPEED_MPS)
LATITUDE, LONGITUDE = Number(-90.0, 90.0, "deg"), Number(-180.0, 180.0, "deg")
# the survey's ranges (lotsen.planning.survey.pattern; the route file's `survey:` has the same)
SPACING, ANGLE, TURNAROUND = Number(0.1, 100.0, "m"), Number(-360.0, 360.0, "deg"), Number(0.0, 100.0, "m")
ENTRY_CORNERS = ("top_left", "top_right", "bottom_left", "bottom_right")
SIDES = ("both", "port", "starboard")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "plan", help="plan a path through a route's nodes (cubic segments, speed profile)",
        description="Plan the path harbour -> nodes of ROUTE (YAML, GeoJSON, or a ground station's file: "
                    "QGroundControl .plan, QGC WPL 110 .waypoints/.txt, KML, GPX) and write it as JSON "
                    "and/or a plot; --export writes the route in another of these formats.")
    p.add_argument("route", help="route file (.yaml, .yml, .geojson, .plan, .waypoints, .txt, .kml, .gpx), or the "
                   "NAME of an example route (figure_eight, survey_lake, ...)")
    p.add_argument("--out", help="write the path as JSON (lotsen.path format)")
    p.add_argument("--plot", help="write a PNG of area, obstacles, nodes and the path coloured by speed")
    p.add_argument("--return-from", nargs=3, metavar=("NORTH", "EAST", "HEADING_DEG"),
                   help="plan the return to the harbour from this pose instead of the route "
                        "(north, east within 2000 m; heading within 360 deg)")
    p.add_argument("--length-ratio-max", type=Number(1.01, 10.0), help="seed eq. (40g) bound (default 1.15)")
    p.add_argument("--min-turn-radius", type=Number(0.1, 100.0, "m"), help="metres (default 1.0)")
    p.add_argument("--clearance", type=Number(0.0, 50.0, "m"), help="metres from obstacles (default 0.5)")
    p.add_argument("--speed-max", type=Number(0.05, 5.0, "m/s"), help="m/s (default 1.5)")
    p.add_argument("--export", metavar="FILE", help="write the route (not the path) as .yaml, .geojson, .plan, "
                   ".waypoints, .kml or .gpx (the format by the suffix; checked by planning it first)")
    p.add_argument("--origin", metavar="LAT,LON", help="geographic origin of the local frame (degrees) for a ground "
                   "station's file and for an export of a route without one; default: the route's, else its harbour")
    p.add_argument("--node-speed", type=NODE_SPEED, metavar="M/S", help="node speed where the file has none "
                   "(.waypoints, KML, GPX; a .plan's cruise speed; default 0.5)")
    s = p.add_argument_group("survey", "lines over an area: make a survey of the route's area (or change the "
                             "route's survey); the route's nodes, if any, are then refused")
    s.add_argument("--spacing", type=SPACING, metavar="M", help="distance between lines (0.1 to 100 m; for a "
                   "one-sided sensor the width it covers)")
    s.add_argument("--angle", type=ANGLE, metavar="DEG", help="direction of the lines, clockwise from north "
                   "(QGroundControl's survey angle; default 0)")
    s.add_argument("--line-speed", type=NODE_SPEED, metavar="M/S", help="speed on the lines (default 0.5)")
    s.add_argument("--turnaround", type=TURNAROUND, metavar="M", help="straight run before and after each line "
                   "(default 2 m)")
    s.add_argument("--entry", choices=ENTRY_CORNERS, help="the corner the first line starts at (default: the one "
                   "nearest the harbour)")
    s.add_argument("--crosshatch", action="store_true", help="fly the area again with lines at 90 deg")
    s.add_argument("--side", choices=SIDES, help="one-sided sensor (side-scan): the side it covers (default both)")
    e = p.add_argument_group("prediction", "time and energy predicted by flying the path on the model in use "
                             "(simulated time, seconds of CPU for a survey)")
    e.add_argument("--predict", action="store_true", help="predict the mission's time and the motors' energy")
    e.add_argument("--current", metavar="SPEED,TO_DEG", help="the current the estimator knows: speed (m/s) and the "
                   "direction it flows TO (deg)")
    e.add_argument("--wind", metavar="SPEED,FROM_DEG", help="the wind: speed (m/s) and the direction it comes FROM (deg)")
    e.add_argument("--params", metavar="PARAMS.json", help="the model in use (default: the default coefficients)")
    e.add_argument("--controller", default="mpc", choices=("mpc", "pursuit", "los", "lq"),
                   help="the path follower in use (default mpc)")
    p.set_defaults(func=run)


SURVEY_FLAGS = {"spacing": "spacing_m", "angle": "angle_deg", "line_speed": "speed_mps", "turnaround": "turnaround_m",
                "entry": "entry", "side": "side"}


def with_survey_flags(route, args):  # type: ignore[no-untyped-def]
    """`route` with the survey flags applied: its survey changed, or a survey of its area made;
    the route itself when no survey flag is given."""
    given = {key: getattr(args, flag) for flag, key in SURVEY_FLAGS.items() if getattr(args, flag, None) is not None}
    if getattr(args, "crosshatch", False):
        given["crosshatch"] = True
    if not given:
        return route
    from lotsen.planning.io import route_from_dict, route_to_dict

    data = route_to_dict(route)
    if data.get("nodes"):
        raise ConfigError(f"{args.route}: the route has nodes; the survey flags make lines over its area (remove the "
                          "nodes, or leave out --spacing, --angle, ...)")
    data.pop("nodes", None)
    data["survey"] = {**data.get("survey", {}), **given}
    return route_from_dict(data)


def return_pose(values: list[str] | None) -> tuple[float, float, float] | None:
    """--return-from NORTH EAST HEADING_DEG, each in its physical range."""
    if values is None:
        return None
    n, e, h = values
    return (COORDINATE.parse(n, "--return-from NORTH"), COORDINATE.parse(e, "--return-from EAST"),
            HEADING_DEG.parse(h, "--return-from HEADING_DEG"))


def _origin(text: str | None):
    """--origin LAT,LON as a GeoOrigin (None without it); ConfigError naming the flag."""
    if text is None:
        return None
    from lotsen.planning import GeoOrigin

    parts = text.split(",")
    if len(parts) != 2:
        raise ConfigError(f"--origin: {text[:40]!r} is not LAT,LON in degrees (e.g. 59.3293,18.0686)")
    return GeoOrigin(LATITUDE.parse(parts[0], "--origin LAT"), LONGITUDE.parse(parts[1], "--origin LON"), 0.0)


def _config(args):
    from lotsen.planning import PlannerConfig
    kw = {}
    for arg, name in (("length_ratio_max", "length_ratio_max"), ("min_turn_radius", "min_turn_radius_m"),
                      ("clearance", "clearance_m"), ("speed_max", "speed_max_mps")):
        v = getattr(args, arg, None)
        if v is not None:
            kw[name] = v
    return PlannerConfig(**kw)


def planning_budget():
    """The page's planning budget with its defaults (`extra.planning` of a launch config)."""
    from lotsen.planning.budget import PlanningBudget

    return PlanningBudget()


def plan_within_budget(route, cfg, return_from: tuple[float, float, float] | None = None):  # type: ignore[no-untyped-def]
    """The path of `route` planned with the page's budget (extra.planning defaults): size bounds
    at once, then time and memory in the planner worker, so no route file can hang a command or
    eat the machine's memory."""
    from lotsen.planning import plan_return_route, plan_route
    from lotsen.planning.budget import check_budget
    from lotsen.stack.planner_worker import PlannerWorker

    budget = planning_budget()
    check_budget(route, budget)
    worker = PlannerWorker(budget)
    try:
        if return_from is not None:
            n, e, hdg = return_from
            return worker.call(plan_return_route, route, n, e, math.radians(hdg), cfg)
        return worker.call(plan_route, route, cfg)
    finally:
        worker.close()


def run(args: argparse.Namespace) -> int:
    from lotsen.planning.io import load_route

    pose = return_pose(args.return_from)
    origin = _origin(getattr(args, "origin", None))
    check_plot_name(args.plot)
    export = getattr(args, "export", None)
    if export:
        from lotsen.planning.formats import format_of

        format_of(export)  # an unknown suffix is refused before any planning
    from lotsen.stack.stack import example_or_file

    args.route = example_or_file(args.route, "routes")  # a bare NAME: the example route, as `lotsen mission` takes it
    check_outputs((args.out, args.plot, export), (args.route,) + ((args.params,) if getattr(args, "params", None)
                                                                   else ()), ConfigError)
    predicting = None
    if getattr(args, "predict", False):
        from lotsen.cli.prediction import model_in_use, parse_speed_dir

        # the flags and the model first: a bad one is reported before the planning
        predicting = (parse_speed_dir(args.current, "current"), parse_speed_dir(args.wind, "wind"),
                      *model_in_use(args.params))
    elif any(getattr(args, k, None) for k in ("current", "wind", "params")):
        raise ConfigError("--current/--wind/--params: read only with --predict (the prediction's water, air and model)")
    route = load_route(args.route, origin=origin, default_speed_mps=getattr(args, "node_speed", None))
    route = with_survey_flags(route, args)
    cfg = _config(args)
    path = plan_within_budget(route, cfg, pose)
    for m in path.segments:
        print(f"{m.label}: {m.length_m:.2f} m (ratio {m.length_ratio:.3f}), max curvature "
              f"{m.max_curvature_1pm:.3f} 1/m, clearance {m.min_clearance_m:.2f} m, "
              f"{m.candidates_tried} candidates")
    print(f"path: {path.length_m:.2f} m, {len(path)} points, "
          f"speed {path.speed_mps.min():.2f}..{path.speed_mps.max():.2f} m/s, planned duration "
          f"{path.duration_s():.0f} s")
    if route.survey is not None and pose is None:
        on_lines = sum(ln.length_m for ln in route.survey_lines)
        p = route.survey
        print(f"survey: {len(route.survey_lines)} lines, {on_lines:.1f} m on lines at {p.speed_mps:g} m/s "
              f"({on_lines / p.speed_mps:.0f} s, {100 * on_lines / p.speed_mps / max(path.duration_s(), 1e-9):.0f} % "
              f"of the planned time), spacing {p.spacing_m:g} m, angle {p.angle_deg:g} deg, turn radius "
              f"{p.turn_radius():g} m")
    if predicting is not None and pose is None:
        from lotsen.cli.prediction import describe_prediction, predict

        current, wind, model, model_name = predicting
        print(describe_prediction(predict(route, path, model, model_name, current, wind, args.controller)))
    if args.out:
        write_output(args.out, json.dumps(path.to_dict()), (args.route,), ConfigError, "path")
        print(f"wrote {args.out}")
    if export:
        from lotsen.planning.io import save_route

        notes: list[str] = []
        with atomic_output(export, (args.route,), ConfigError, "route") as tmp:
            notes.extend(save_route(route, tmp, origin))
        for note in notes:
            print(f"note: {note}")
        print(f"wrote {export}")
    if args.plot:
        save_plot(args.plot, lambda f: plot_path(route, path, f), (args.route,))
        print(f"wrote {args.plot}")
    return 0


def plot_path(route, path, filename) -> None:
    """Area, obstacles (hatched where forbidden), nodes with heading arrows, path coloured by speed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Polygon as MplPolygon

    fig, ax = plt.subplots(figsize=(7, 7))
    # plot x = east, y = north so the map looks like a chart
    if route.area is not None:
        ax.add_patch(MplPolygon([(e, n) for n, e in route.area], closed=True, fill=False,
                                edgecolor="tab:blue", lw=1.5, label="navigable area"))
    for i, r in enumerate(route.obstacles):
        xy = [(e, n) for n, e in r.polygon]
        if r.forbidden == "inside":
            ax.add_patch(MplPolygon(xy, closed=True, facecolor="0.6", edgecolor="k", hatch="//",
                                    label="obstacle" if i == 0 else None))
        else:
            ax.add_patch(MplPolygon(xy, closed=True, fill=False, edgecolor="tab:red", ls="--"))
        c = np.mean(r.polygon, axis=0)
        ax.annotate(f"obstacles[{i}]", (c[1], c[0]), ha="center", fontsize=7)
    pts = np.column_stack([path.east_m, path.north_m])
    step = max(1, len(pts) // 4000)   # a few thousand line pieces are plenty for a picture
    p = pts[::step]
    segs = np.stack([p[:-1], p[1:]], axis=1)
    lc = LineCollection(segs, cmap="viridis", linewidths=2.5)
    lc.set_array(path.speed_mps[::step][:-1])
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label="speed reference [m/s]", shrink=0.8)
    nodes = route.all_nodes()
    L = 0.06 * max(np.ptp(path.north_m), np.ptp(path.east_m), 5.0)   # arrow length
    for k, nd in enumerate(nodes):
        ax.annotate("", xy=(nd.east_m + L * math.sin(nd.heading_rad), nd.north_m + L * math.cos(nd.heading_rad)),
                    xytext=(nd.east_m, nd.north_m),
                    arrowprops={"arrowstyle": "->", "color": "tab:red" if k == 0 else "k", "lw": 1.5})
        ax.plot(nd.east_m, nd.north_m, "s" if k == 0 else "o", color="tab:red" if k == 0 else "k", ms=5)
        ax.annotate("harbour" if k == 0 else str(k - 1), (nd.east_m, nd.north_m), xytext=(4, 4),
                    textcoords="offset points", fontsize=8)
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_title(f"planned path: {path.length_m:.1f} m, {len(path)} points")
    ax.grid(True, alpha=0.3)
    fig.savefig(filename, dpi=110, bbox_inches="tight")
    plt.close(fig)
