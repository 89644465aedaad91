"""`lotsen model check`: parameters, stability report (seed eq. 16) and the linearised system (eq. 15)."""

from __future__ import annotations

import argparse
from dataclasses import fields

import numpy as np

from lotsen.model import VesselModel, VesselParameters, linearise, stability_report, straight_trim
from lotsen.model.linear import linearise_straight
from lotsen.settings import Number
from lotsen.model import load_parameter_file


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("model", help="inspect the vessel model")
    msub = p.add_subparsers(dest="model_command", metavar="ACTION")
    c = msub.add_parser("check", help="print parameters, stability conditions (16a-d) and linearisation (15)")
    c.add_argument("--params", help="params.json (from `lotsen identify`); default: the documented defaults")
    c.add_argument("--speed", type=Number(0.0, 5.0, "m/s"), default=0.5,
                   help="U0 for the full linearisation, m/s (default 0.5)")
    c.add_argument("--n-max", type=Number(1.0, 200.0, "rev/s"), default=100.0,
                   help="azimuth speed limit for U_max, rev/s (default 100)")
    c.set_defaults(func=check)
    p.set_defaults(func=lambda a: (p.print_help(), 1)[1])


def check(args: argparse.Namespace) -> int:
    loaded = load_parameter_file(args.params) if args.params else None
    model = VesselModel(loaded.parameters if loaded else VesselParameters())
    np.set_printoptions(precision=4, suppress=True, linewidth=120)
    print(f"Model: {loaded.describe() if loaded else 'default coefficients'}")
    print("Vessel parameters (seed eq. 26):")
    for f in fields(VesselParameters):
        default = " (default)" if loaded and f.name in loaded.defaults_for else ""
        print(f"  {f.name:<6s} = {getattr(model.params, f.name):>10.4g}  {f.metadata['unit']:<9s} {f.metadata['doc']}"
              f"{default}")
    rep = stability_report(model, n_max_rps=args.n_max)
    print(f"\nStability (seed eq. 16), U_max = {rep.U_max:.3f} m/s at n = {args.n_max:g} rev/s:")
    print("\n".join(rep.lines()))
    for U in (0.0, rep.U_max):
        lin = linearise_straight(model, U)
        print(f"\nLinear sway-yaw model (seed eq. 15) at U0 = {U:.2f} m/s:  M [v r]' + N [v r]' = b tau")
        print(f"  M =\n{lin.M}\n  N(U0) =\n{lin.N}\n  surge pole = {lin.surge_pole:.4f} 1/s")
    x0, u0 = straight_trim(model, args.speed)
    A, B = linearise(model, x0, u0)
    print(f"\nFull linearisation x_dot = A dx + B du at U0 = {args.speed:g} m/s heading north "
          f"(n1 = n2 = {u0[2]:.2f} rev/s), x = [N E psi u v r], u = [a1 a2 n1 n2 nt]:")
    print(f"  A =\n{A}\n  B =\n{B}")
    return 0
