"""The identification report: self-contained HTML (plots embedded as base64 PNG) or PDF.

`Report.of(identification, problem, sources, warnings)` gathers what the report shows (the answer, its
verdict and the data that judged it, the held-out prediction of every model compared, the simulation
fit, the residuals, the black-box peer); `render_report(report)` returns the HTML text,
`render_pdf(report)` the PDF bytes (a summary page, then the same figures, through matplotlib's
PdfPages). Writing them is the CLI's job.
"""

from __future__ import annotations

import base64
import html
import io
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from lotsen.errors import LotsenError
from lotsen.model import DEFAULT_PARAMETERS, VesselParameters
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.sysid.estimate import NAMES, IdentificationResult
from lotsen.sysid.judge import Identification
from lotsen.sysid.problem import IdentificationProblem
from lotsen.sysid.validate import OutputFit, ResidualAnalysis

_UNITS = {"north": "m", "east": "m", "psi": "rad", "r": "rad/s", "u": "m/s", "v": "m/s"}


@dataclass
class Report:
    """What one identification report shows (module docstring)."""

    ident: Identification
    sources: list[str]
    warnings: list[str] = field(default_factory=list)
    initial: VesselParameters = DEFAULT_PARAMETERS
    fit_est: OutputFit | None = None
    fit_val: OutputFit | None = None
    blackbox_val: OutputFit | None = None
    residuals: ResidualAnalysis | None = None

    @property
    def result(self) -> IdentificationResult:
        return self.ident.result

    @classmethod
    def of(cls, ident: Identification, problem: IdentificationProblem, sources: Sequence[str],
           warnings: Sequence[str] = ()) -> "Report":
        """The report of `ident` on `problem`: the answer simulated on the estimation and held-out records
        (10-s windows), its residuals, and the black-box peer; what cannot be computed on too short data
        is said in a warning instead."""
        from lotsen.sysid.blackbox import fit_narx, narx_fit
        from lotsen.sysid.validate import inputs_at_outputs, residual_analysis, simulate_fit

        rep = cls(ident, list(sources), list(warnings), problem.start)
        window, gap, geom = problem.solver.window_s or 10.0, problem.gap_s, problem.geometry
        try:
            rep.fit_est = simulate_fit(ident.result.params, problem.records, window, gap, geom)
        except LotsenError as exc:
            rep.warnings.append(f"no fit on the estimation data: {exc}")
        try:
            rep.fit_val = simulate_fit(ident.result.params, problem.validation, window, gap, geom)
            ra = residual_analysis(rep.fit_val, inputs_at_outputs(problem.validation, window, gap))
            rep.residuals = ra if ra.autocorr else None  # no output with enough samples for a correlation
        except LotsenError as exc:
            rep.warnings.append(f"no validation: {exc} (the held-out part is too short; use --validate or a longer "
                                "record)")
        try:
            rep.blackbox_val = narx_fit(fit_narx(problem.records, gap), problem.validation, window, gap)
        except LotsenError as exc:
            rep.warnings.append(f"no black-box peer: {exc}")
        return rep


def _png(fig) -> str:  # type: ignore[no-untyped-def]
    if fig is None:
        return ""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return f'<img src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}"/>'


def _fit_plot(fit: OutputFit, other: OutputFit | None, title: str):  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(fit.output_names)
    fig, axes = plt.subplots(n, 1, figsize=(10, 1.9 * n), sharex=True)
    axes = np.atleast_1d(axes)
    for j, name in enumerate(fit.output_names):
        ax = axes[j]
        ok = np.isfinite(fit.y[:, j])
        ax.plot(fit.t[ok], fit.y[ok, j], ".", ms=2, color="0.4", label="measured")
        ax.plot(fit.t, fit.yhat[:, j], "-", lw=1, color="C0", label=f"grey-box ({fit.fit_percent[name]:.1f} %)")
        if other is not None and name in other.output_names:
            jj = other.output_names.index(name)
            ax.plot(other.t, other.yhat[:, jj], "-", lw=0.8, color="C3",
                    label=f"black-box ({other.fit_percent[name]:.1f} %)")
        for ts in fit.window_starts:
            ax.axvline(ts, color="0.85", lw=0.5)
        ax.set_ylabel(f"{name} [{_UNITS.get(name, '')}]")
        ax.legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("t [s] (vertical lines: window starts)")
    axes[0].set_title(title)
    return fig


def _track_plot(fit: OutputFit):  # type: ignore[no-untyped-def]
    import matplotlib.pyplot as plt

    names = fit.output_names
    if "north" not in names or "east" not in names:
        return None
    i, j = names.index("north"), names.index("east")
    fig, ax = plt.subplots(figsize=(5, 5))
    ok = np.isfinite(fit.y[:, i])
    ax.plot(fit.y[ok, j], fit.y[ok, i], ".", ms=2, color="0.4", label="measured")
    ax.plot(fit.yhat[:, j], fit.yhat[:, i], "-", lw=1, label="grey-box")
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend(fontsize=7)
    return fig


def _residual_plot(ra: ResidualAnalysis):  # type: ignore[no-untyped-def]
    import matplotlib.pyplot as plt

    names = list(ra.autocorr)
    fig, axes = plt.subplots(2, len(names), figsize=(3 * len(names), 4.5), squeeze=False)
    for j, name in enumerate(names):
        ax = axes[0, j]
        ax.bar(ra.lags, ra.autocorr[name], width=0.6)
        ax.axhspan(-ra.bound, ra.bound, color="C2", alpha=0.2)
        ax.set_title(f"autocorr. {name}", fontsize=9)
        ax.set_ylim(-1, 1)
        ax = axes[1, j]
        L = (len(next(iter(ra.crosscorr[name].values()))) - 1) // 2 if ra.crosscorr.get(name) else 0
        for inp, c in ra.crosscorr.get(name, {}).items():
            ax.plot(np.arange(-L, L + 1), c, lw=0.8, label=inp)
        ax.axhspan(-ra.bound, ra.bound, color="C2", alpha=0.2)
        ax.set_title(f"cross-corr. {name} / inputs", fontsize=9)
        ax.set_ylim(-1, 1)
        ax.set_xlabel("lag [samples]")
        if j == 0:
            ax.legend(fontsize=6)
    fig.tight_layout()
    return fig


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    h = "".join(f"<th>{html.escape(c)}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _parameter_rows(result: IdentificationResult, initial: VesselParameters,
                    undetermined: dict[str, str] | None = None) -> list[tuple[list[str], bool]]:
    """[name, estimate, std, 95 % interval, relative 95 % error, initial], and whether it is poorly determined."""
    undetermined = undetermined or {}
    p = result.params
    rows = []
    for n in NAMES:
        v = getattr(p, n)
        if n not in result.std and n in OPTIONAL_TERMS and v == 0:  # an optional model term left off
            rows.append(([n, f"{v:.5g}", "not estimated (off)", "", "", f"{getattr(initial, n):.5g}"], False))
            continue
        if n in result.fixed:
            rows.append(([n, f"{v:.5g}", "fixed", "", "", f"{getattr(initial, n):.5g}"], False))
            continue
        if n in undetermined:  # the data do not determine it: no number for its interval
            rows.append(([n, f"{v:.5g}", "undetermined", undetermined[n], "", f"{getattr(initial, n):.5g}"], True))
            continue
        s = result.std[n]
        rel = 196 * s / abs(v) if v != 0 else math.inf
        rows.append(([n, f"{v:.5g}", f"{s:.3g}", f"[{v - 1.96 * s:.4g}, {v + 1.96 * s:.4g}]", f"{rel:.1f} %",
                      f"{getattr(initial, n):.5g}"], n in result.identifiability.poorly_determined))
    return rows


PARAMETER_HEADER = ["parameter", "estimate", "std", "95 % interval", "1.96 std / |value|", "initial"]


def _fit_rows(fit_est: OutputFit | None, fit_val: OutputFit | None,
              blackbox_val: OutputFit | None) -> tuple[list[str], list[list[str]]]:
    rows = []
    for label, f in (("grey-box, estimation data", fit_est), ("grey-box, validation data", fit_val),
                     ("black-box NARX, validation data", blackbox_val)):
        if f is not None:
            rows.append([label] + [f"{f.fit_percent.get(n, float('nan')):.1f} %" for n in f.output_names])
    names = list((fit_val or fit_est or blackbox_val).output_names) if rows else []  # type: ignore[union-attr]
    return names, rows


def _summary(rep: Report) -> str:
    ident, result = rep.ident, rep.result
    held = ident.held_out_score
    judged = (f" Judged on {ident.judged_on}" + (f": the answer's {held.horizon_s:g}-s prediction misses by "
                                                 f"{held.position_at_horizon_m:.2f} m (RMS over {held.n_windows} "
                                                 "windows)" if held is not None and held.n_windows else "") + ".")
    how = ("the equations of motion fitted to the record" if ident.estimator == "equation error" else
           f"{result.n_residuals} residuals; V = {result.cost:.4g}; noise factor s^2 = {result.noise_factor:.3g} "
           f"({'model error or noise larger than assumed' if result.noise_factor > 1.5 else 'consistent with the assumed noise'}); "
           f"{result.iterations} iterations, {'converged' if result.converged else 'NOT converged'}")
    from lotsen.sysid.waves import describe

    sea = f" Sea: {describe(ident.sea)}." if ident.sea is not None else ""
    return (f"Verdict: {ident.verdict.verdict}. Data: {', '.join(rep.sources)}.{sea} The answer: the {ident.estimator} "
            f"estimate ({how}).{judged}")


def _verdict_lines(rep: Report) -> list[str]:
    """The verdict's reasons, the advice and the held-out prediction of every model, as lines."""
    ident = rep.ident
    lines = [f"verdict {ident.verdict.verdict}: {r}" for r in ident.verdict.reasons]
    lines += [f"advice: {a}" for a in ident.advice]
    for name, sc in ident.prediction.items():
        if sc.n_windows:
            lines.append(f"{name}: " + ", ".join(f"{sc.position_m[h]:.2f} m / {sc.heading_deg[h]:.1f} deg after {h:g} s"
                                                 for h in sc.horizons_s) + (" <- the answer" if name == ident.chosen else ""))
    return lines


def _figures(fit_est: OutputFit | None, fit_val: OutputFit | None, blackbox_val: OutputFit | None,
             residuals: ResidualAnalysis | None) -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    if residuals is not None:
        out.append(("Residual analysis (validation data)", _residual_plot(residuals)))
    if fit_val is not None:
        out.append(("Validation data", _fit_plot(fit_val, blackbox_val, "validation: measured vs simulated")))
        out.append(("Validation track", _track_plot(fit_val)))
    if fit_est is not None:
        out.append(("Estimation data", _fit_plot(fit_est, None, "estimation: measured vs simulated")))
    return [(t, f) for t, f in out if f is not None]


def render_pdf(rep: Report) -> bytes:
    """The report as PDF: a text summary page (verdict, parameters, identifiability, fit), then the figures."""
    result, fit_est, fit_val, blackbox_val = rep.result, rep.fit_est, rep.fit_val, rep.blackbox_val
    residuals, warnings, initial = rep.residuals, rep.warnings, rep.initial
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    lines = ["Identification report", ""] + textwrap.wrap(_summary(rep), 110) + [""]
    for ln in _verdict_lines(rep):
        lines += textwrap.wrap(ln, 110)
    lines.append("")
    for w in warnings:
        lines += textwrap.wrap(w if w.startswith("WARNING") else "WARNING: " + w, 110)
    widths = (8, 12, 11, 26, 18, 10)
    lines += ["", "Parameters (95 % = estimate +- 1.96 sigma from the Fisher information; * = above 5 %)",
              "".join(h.ljust(w) for h, w in zip(PARAMETER_HEADER, widths))]
    for row, bad in _parameter_rows(result, initial, rep.ident.undetermined):
        lines.append("".join(c.ljust(w) for c, w in zip(row, widths)) + (" *" if bad else ""))
    lines += ["", f"Identifiability: condition number of the relative Fisher information "
                  f"{result.identifiability.condition_number:.3g}"]
    for d in result.identifiability.directions or ["no poorly determined direction"]:
        lines += textwrap.wrap("  - " + d, 110)
    names, rows = _fit_rows(fit_est, fit_val, blackbox_val)
    if rows:
        lines += ["", "Fit (NRMSE, 100 (1 - |y - yhat| / |y - mean y|)):  " + "  ".join(names)]
        lines += ["  " + r[0].ljust(34) + "  ".join(c.rjust(7) for c in r[1:]) for r in rows]
    buf = io.BytesIO()
    with PdfPages(buf) as pdf:
        fig = plt.figure(figsize=(8.27, 11.69))  # A4
        fig.text(0.05, 0.97, "\n".join(lines), va="top", family="monospace", fontsize=6.5)
        pdf.savefig(fig)
        plt.close(fig)
        for title, f in _figures(fit_est, fit_val, blackbox_val, residuals):
            f.suptitle(title)  # type: ignore[attr-defined]
            pdf.savefig(f)
            plt.close(f)  # type: ignore[arg-type]
    return buf.getvalue()


def render_report(rep: Report) -> str:
    """The report as one self-contained HTML page."""
    result, fit_est, fit_val, blackbox_val = rep.result, rep.fit_est, rep.fit_val, rep.blackbox_val
    residuals, warnings, initial = rep.residuals, rep.warnings, rep.initial
    rows = []
    for row, bad in _parameter_rows(result, initial, rep.ident.undetermined):
        if row[4]:
            css = " class='bad'" if bad else ""
            row[4] = f"<span{css}>{row[4]}</span>"
        rows.append(row)
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>lotsen identification report</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
        "td,th{border:1px solid #bbb;padding:2px 8px;text-align:right}.bad{color:#b00;font-weight:bold}"
        ".warn{background:#fee;border:1px solid #b00;padding:6px}</style></head><body>",
        "<h1>Identification report</h1>",
        f"<p>{html.escape(_summary(rep))}</p>",
        "<ul>" + "".join(f"<li>{html.escape(ln)}</li>" for ln in _verdict_lines(rep)) + "</ul>",
    ]
    for w in warnings:
        parts.append(f"<p class='warn'>{html.escape(w)}</p>")
    parts += ["<h2>Parameters</h2>",
              "<p>95 % intervals = estimate &plusmn; 1.96 &sigma; from the Fisher information (initial states "
              "marginalised, scaled by max(1, s<sup>2</sup>)). Red: relative 95 % error above 5 %.</p>",
              _table(PARAMETER_HEADER, rows),
              "<h2>Identifiability</h2>",
              f"<p>Condition number of the relative Fisher information: {result.identifiability.condition_number:.3g}.</p>"]
    if result.identifiability.directions:
        parts.append("<ul>" + "".join(f"<li>{html.escape(d)}</li>" for d in result.identifiability.directions) + "</ul>")
    else:
        parts.append("<p>No poorly determined direction.</p>")
    names, fit_rows = _fit_rows(fit_est, fit_val, blackbox_val)
    if fit_rows:
        parts += ["<h2>Fit (NRMSE, 100 (1 - |y - yhat| / |y - mean y|))</h2>", _table(["model"] + names, fit_rows)]
    if residuals is not None:
        rr = [[n, f"{100 * residuals.whiteness_fraction_outside[n]:.0f} %",
               f"{100 * residuals.independence_fraction_outside.get(n, 0):.0f} %"] for n in residuals.autocorr]
        parts += [f"<p>Residuals: share of lags outside &plusmn;{residuals.bound:.3f} (95 % band; about 5 % "
                  "expected for white, input-independent residuals).</p>",
                  _table(["output", "autocorrelation", "cross-correlation with inputs"], rr)]
    for title, fig in _figures(fit_est, fit_val, blackbox_val, residuals):
        parts += [f"<h2>{html.escape(title)}</h2>", _png(fig)]
    parts.append("</body></html>")
    return "\n".join(parts)
