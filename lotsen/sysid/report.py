"""The identification report: self-contained HTML (plots embedded as base64 PNG) or PDF.

`render_report(...)` returns the HTML text; `render_pdf(...)` returns the PDF bytes (a summary
page, then the same figures, through matplotlib's PdfPages). Writing them is the CLI's job.
"""

from __future__ import annotations

import base64
import html
import io
import math
from typing import Sequence

import numpy as np

from lotsen.model import DEFAULT_PARAMETERS, VesselParameters
from lotsen.sysid.estimate import NAMES, IdentificationResult
from lotsen.sysid.validate import OutputFit, ResidualAnalysis

_UNITS = {"north": "m", "east": "m", "psi": "rad", "r": "rad/s", "u": "m/s", "v": "m/s"}


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


def _parameter_rows(result: IdentificationResult, initial: VesselParameters) -> list[tuple[list[str], bool]]:
    """[name, estimate, std, 95 % interval, relative 95 % error, initial], and whether it is poorly determined."""
    p = result.params
    rows = []
    for n in NAMES:
        v = getattr(p, n)
        if n in result.fixed:
            rows.append(([n, f"{v:.5g}", "fixed", "", "", f"{getattr(initial, n):.5g}"], False))
            continue
        if n not in result.std:  # an optional model term left off (lotsen.model.parameters.OPTIONAL_TERMS)
            rows.append(([n, f"{v:.5g}", "not estimated (off)", "", "", f"{getattr(initial, n):.5g}"], False))
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


def _summary(result: IdentificationResult, sources: Sequence[str]) -> str:
    return (f"Data: {', '.join(sources)}. Method: {result.method} shooting; {len(result.windows)} windows; "
            f"{result.n_residuals} residuals; V = {result.cost:.4g}; noise factor s^2 = {result.noise_factor:.3g} "
            f"({'model error or noise larger than assumed' if result.noise_factor > 1.5 else 'consistent with the assumed noise'}); "
            f"{result.iterations} iterations, {'converged' if result.converged else 'NOT converged'}.")


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


def render_pdf(result: IdentificationResult, sources: Sequence[str], fit_est: OutputFit | None = None,
               fit_val: OutputFit | None = None, blackbox_val: OutputFit | None = None,
               residuals: ResidualAnalysis | None = None, warnings: Sequence[str] = (),
               initial: VesselParameters = DEFAULT_PARAMETERS) -> bytes:
    """The report as PDF: a text summary page (parameters, identifiability, fit), then the figures."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    lines = ["Identification report", ""] + textwrap.wrap(_summary(result, sources), 110) + [""]
    for w in warnings:
        lines += textwrap.wrap(w if w.startswith("WARNING") else "WARNING: " + w, 110)
    widths = (8, 12, 11, 26, 18, 10)
    lines += ["", "Parameters (95 % = estimate +- 1.96 sigma from the Fisher information; * = above 5 %)",
              "".join(h.ljust(w) for h, w in zip(PARAMETER_HEADER, widths))]
    for row, bad in _parameter_rows(result, initial):
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


def render_report(result: IdentificationResult, sources: Sequence[str], fit_est: OutputFit | None = None,
                  fit_val: OutputFit | None = None, blackbox_val: OutputFit | None = None,
                  residuals: ResidualAnalysis | None = None, warnings: Sequence[str] = (),
                  initial: VesselParameters = DEFAULT_PARAMETERS) -> str:
    rows = []
    for row, bad in _parameter_rows(result, initial):
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
        f"<p>{html.escape(_summary(result, sources))}</p>",
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
