"""The figure of the stability report: work and error of one point against eps L."""

from __future__ import annotations

import math

from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from . import new_figure, parameter_title, save_figure

PATH_COLOURS = {"explicit": "C0", "stiff": "C3", "none": "C2"}
PATH_LABELS = {"explicit": "explicit path (Dormand-Prince 5(4))", "stiff": "stiff path (RODAS4P2)",
               "none": "no stage-1 integration (A = -1)"}
SERIES_STYLES = ("-", "--", ":", "-.")
ETA_LABEL = r"$\eta = \varepsilon L$"
ERROR_LABEL = r"relative error, the larger of $\Delta$'s and $\bar m_w$'s"
ERROR_TITLE = r"vs reference: scipy Radau at rtol 1e-12 ($A = -1$: closed form)"
ZERO_STEPS_LABEL = "0 stage-1 steps (drawn on the bottom edge)"


def stability_figure(report, path=None) -> Figure:
    """Three log-log panels against ``eta = eps L``: steps, time per point, relative error.

    One line per ``(A, N)`` series (rows of case ``sweep``); every point, including those next to
    the regime boundaries, is a marker coloured by the path stage 1 took. The error panel shows
    ``rtol`` as a horizontal line.

    Parameters
    ----------
    report : cosserat_channel.measure.stability.Report
        Its rows, ``rtol`` and the fixed ``L``, ``K`` of the title.
    path : str or path-like, optional
        Where to save the figure.
    """
    rows = report.rows
    fig = new_figure((13.0, 4.8))
    ax_s, ax_t, ax_e = fig.subplots(1, 3, sharex=True)
    series = sorted({(r["A"], r["N"]) for r in rows if r["case"] == "sweep"})
    handles = []
    for k, (A, N) in enumerate(series):
        pts = sorted((r for r in rows if r["case"] == "sweep" and r["A"] == A and r["N"] == N),
                     key=lambda r: r["eta"])
        eta = [r["eta"] for r in pts]
        ls = SERIES_STYLES[k % len(SERIES_STYLES)]
        name = f"$A$ = {A:.3g}, $N$ = {N:.3g}"
        ax_s.plot(eta, [r["s1_acc"] for r in pts], color="0.3", ls=ls, lw=1.2,
                  label=f"stage 1 steps, {name}")
        ax_s.plot(eta, [r["s2_acc"] for r in pts], color="0.65", ls=ls, lw=1.2,
                  label=f"stage 2 steps, {name}")
        ax_t.plot(eta, [r["us"] for r in pts], color="0.3", ls=ls, lw=1.2, label=name)
        err = [max(r["err_Delta"], r["err_m_wall"]) for r in pts]
        ax_e.plot(eta, [e if math.isfinite(e) and e > 0 else math.nan for e in err], color="0.3",
                  ls=ls, lw=1.2, label=name)
    # A log axis has no 0: a point with no stage-1 step (A = -1) is a triangle on the bottom edge
    # (x in data, y in axes coordinates), not a made-up value.
    bottom = ax_s.get_xaxis_transform()
    zero_steps = False
    for r in rows:
        colour = PATH_COLOURS.get(r["path"], "k")
        marker = "o" if r["case"] == "sweep" else "D"
        if r["s1_acc"] > 0:
            ax_s.scatter([r["eta"]], [r["s1_acc"]], color=colour, marker=marker, s=22, zorder=3)
        else:
            ax_s.scatter([r["eta"]], [0.0], color=colour, marker="v", s=40, zorder=3,
                         transform=bottom, clip_on=False)
            zero_steps = True
        ax_t.scatter([r["eta"]], [r["us"]], color=colour, marker=marker, s=22, zorder=3)
        e = max(r["err_Delta"], r["err_m_wall"])
        if math.isfinite(e) and e > 0:
            ax_e.scatter([r["eta"]], [e], color=colour, marker=marker, s=22, zorder=3)
    ax_e.axhline(report.rtol, color="k", lw=0.8, ls="--", label=f"rtol = {report.rtol:g}")
    for p in sorted({r["path"] for r in rows}):
        handles.append(Line2D([], [], color=PATH_COLOURS.get(p, "k"), marker="o", ls="",
                              label=PATH_LABELS.get(p, p)))
    handles.append(Line2D([], [], color="0.5", marker="D", ls="", label="next to a regime boundary"))
    if zero_steps:
        ax_s.scatter([], [], color="0.5", marker="v", s=40, label=ZERO_STEPS_LABEL)
    ax_s.set_ylabel("accepted steps per point")
    ax_t.set_ylabel(r"time per point ($\mu$s, best of repeats)")
    ax_e.set_ylabel(ERROR_LABEL)
    ax_e.set_title(ERROR_TITLE, fontsize="small")
    for ax in (ax_s, ax_t, ax_e):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(ETA_LABEL)
        ax.grid(alpha=0.3, which="both")
    # Legends below the panels: inside they covered points.
    below = dict(loc="upper center", bbox_to_anchor=(0.5, -0.16), fontsize=7, frameon=False)
    ax_s.legend(**below)
    ax_t.legend(handles=handles + ax_t.get_legend_handles_labels()[0], **below)
    ax_e.legend(**below)
    fig.suptitle("Stability of one point across " + ETA_LABEL + ": "
                 + parameter_title(L=report.L, K=report.K) + f", rtol = {report.rtol:g}")
    if path is not None:
        save_figure(fig, path)
    return fig
