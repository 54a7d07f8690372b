"""Figures of the work-precision report (:mod:`cosserat_channel.measure.workprecision`).

Both take :class:`cosserat_channel.measure.report.Curve` objects (method, stages, points,
rtol, time_us, median/max per quantity) and return a Figure; saving is :func:`save_figure`'s.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..outputs import OUTPUTS
from . import new_figure, save_figure  # noqa: F401  (save_figure re-exported for the report)

TIME_LABEL = r"time per point [$\mu$s] (one core)"
ERROR_LABEL = "median relative error against the reference"
RTOL_LABEL = "requested rtol"
ACHIEVED_LABEL = "achieved relative error against the reference"

# (colour, marker, line style) per method; ours solid, scipy dashed, numbalsoda dash-dot.
STYLES = {
    "ours": ("C0", "o", "-"),
    "scipy-RK45": ("C1", "s", "--"),
    "scipy-DOP853": ("C2", "^", "--"),
    "scipy-LSODA": ("C3", "v", "--"),
    "scipy-Radau": ("C4", "D", "--"),
    "numbalsoda-LSODA": ("C5", "P", "-."),
    "numbalsoda-DOP853": ("C6", "X", "-."),
}
QUANTITY_STYLES = {"Delta": ("C0", "o"), "m_wall": ("C1", "s"), "slip": ("C2", "^")}


def _symbol(q: str) -> str:
    """A measured quantity's symbol: its output's, else its name."""
    return OUTPUTS[q].symbol if q in OUTPUTS and OUTPUTS[q].symbol else q


def _finite(x, y):
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    return x[ok], y[ok]


def _unanswered(c, solved_every=None) -> str:
    """The points a curve left unanswered, in the words the right panel uses for the same count.

    ``solved_every``: how many points it solved at every rtol (from its comparison), else only
    the worst single rtol is known.
    """
    if solved_every is not None and solved_every < c.n_attempted:
        return f" ({solved_every} of {c.n_attempted} solved at every rtol)"
    k = max(c.failed, default=0)
    return f" (at most {k} of {c.n_attempted} unanswered at one rtol)" if k else ""


# Legends go below the panels: inside they covered curves.
LEGEND_BELOW = dict(loc="upper center", bbox_to_anchor=(0.5, -0.09), fontsize="x-small",
                    ncols=1, frameon=False)


def _style_axes(ax, title):
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(TIME_LABEL)
    ax.set_ylabel(ERROR_LABEL)
    ax.grid(True, which="major", alpha=0.3)
    ax.grid(True, which="minor", alpha=0.1)
    ax.legend(**LEGEND_BELOW)
    ax.set_title(title, fontsize="medium")


def work_precision_figure(ours_both, stage1_curves, comparisons=(), *, title: str = "") -> Figure:
    """Median relative error against time per point, log-log, one curve per method.

    Left panel: ``ours_both`` with the worst of its quantities' medians (thick black) and each
    stage-1 curve with its ``m_wall`` median, every method on its own points (a peer's points it
    gave up on count with the time spent up to its work cap). Right panel (when ``comparisons``
    are given): each stage-1 peer on the points it solved at every rtol, dashed, next to ours
    re-timed on exactly those points, solid in our colour with the peer's (hollow) marker. Both
    panels count a peer's points the same way: solved at every rtol.
    """
    pairs = [c for c in comparisons if c.ours.stages == "stage1"]
    solved_every = {c.peer.method: c.peer_solved.n_attempted for c in pairs}
    fig = new_figure((16.0, 9.5) if pairs else (10.0, 8.5))
    axes = fig.subplots(1, 2 if pairs else 1, squeeze=False)[0]
    ax = axes[0]
    x, y = _finite(ours_both.time_us, ours_both.worst_median())
    ax.plot(x, y, color="k", marker="o", lw=2.2, ls="-",
            label="ours, both stages (worst of " + ", ".join(_symbol(q) for q in ("Delta", "m_wall", "slip"))
            + ")" + _unanswered(ours_both))
    for c in stage1_curves:
        colour, marker, ls = STYLES.get(c.method, ("0.5", ".", ":"))
        label = f"{c.method}, stage 1 ({_symbol('m_wall')})"
        if c.method == "ours" and c.points == "subsample":
            label = f"ours, stage 1 ({_symbol('m_wall')}), on the scipy subsample ({c.n_attempted} points)"
            ls = ":"
        elif c.method.startswith("scipy"):
            label += f", Python loop, {c.n_attempted} points"
        label += _unanswered(c, solved_every.get(c.method) if c.method != "ours" else None)
        x, y = _finite(c.time_us, c.median["m_wall"])
        ax.plot(x, y, color=colour, marker=marker, ls=ls, lw=1.5, ms=5,
                mfc="none" if c.points == "subsample" and c.method == "ours" else colour,
                label=label)
    _style_axes(ax, "each method on its own points (unanswered points: time up to the work cap)")
    if pairs:
        ax2 = axes[1]
        for c in pairs:
            colour, marker, _ = STYLES.get(c.peer.method, ("0.5", ".", ":"))
            x, y = _finite(c.peer_solved.time_us, c.peer_solved.median["m_wall"])
            ax2.plot(x, y, color=colour, marker=marker, ls="--", lw=1.5, ms=5,
                     label=f"{c.peer.method} ({c.peer_solved.n_attempted} points it solved)")
            x, y = _finite(c.ours_solved.time_us, c.ours_solved.median["m_wall"])
            ax2.plot(x, y, color=STYLES["ours"][0], marker=marker, ls="-", lw=1.5, ms=6,
                     mfc="none", label=f"ours on the same {c.ours_solved.n_attempted} points "
                     f"(marker of {c.peer.method})")
        _style_axes(ax2, f"stage 1 ({_symbol('m_wall')}): each peer on the points it solved at every "
                    "rtol, ours on the same points")
    if title:
        fig.suptitle(title)
    return fig


def tolerance_figure(ours_both, *, factor: float = 100.0, title: str = "") -> Figure:
    """Achieved median (filled) and max (hollow) relative error against the requested rtol, with
    the ideal ``y = x`` line and the band from ``rtol / factor`` to ``rtol * factor``."""
    fig = new_figure((8.0, 7.0))
    ax = fig.subplots()
    rtol = np.asarray(ours_both.rtol, float)
    lo, hi = rtol.min() / 3.0, rtol.max() * 3.0
    xs = np.array([lo, hi])
    ax.fill_between(xs, xs / factor, xs * factor, color="0.85", alpha=0.6,
                    label=f"within a factor {factor:g} of rtol")
    ax.plot(xs, xs, color="k", ls="--", lw=1.2, label="ideal: error = rtol")
    for q in ours_both.median:
        colour, marker = QUANTITY_STYLES.get(q, ("0.5", "."))
        x, y = _finite(rtol, ours_both.median[q])
        ax.plot(x, y, color=colour, marker=marker, ls="-", label=f"{_symbol(q)}, median")
        x, y = _finite(rtol, ours_both.max[q])
        ax.plot(x, y, color=colour, marker=marker, ls=":", mfc="none",
                label=f"{_symbol(q)}, max")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(lo, hi)
    ax.set_xlabel(RTOL_LABEL)
    ax.set_ylabel(ACHIEVED_LABEL)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)
    return fig


def quantity_panels_figure(rows, quantities=("Delta", "m_wall", "slip"), *, title="") -> Figure:
    """Time per point against median relative error, one panel per quantity, from the rows of
    ``work_precision.csv`` (mappings with ``method``, ``stages``, ``rtol``, ``quantity``,
    ``time_per_point_us`` and ``median_rel_err``; strings or numbers).

    One line per (method, stages) in the method's colour and marker, solid for both stages and
    dashed for stage 1 alone. Every panel has a legend of the lines it draws: the stage-1 peers
    answer ``m_wall`` only, so its panel names them and the others do not.
    """
    fig = new_figure((16.0, 6.5))
    axes = fig.subplots(1, len(quantities), sharey=True, squeeze=False)[0]
    curves = sorted({(r["method"], r["stages"]) for r in rows})
    for ax, q in zip(axes, quantities):
        for method, stages in curves:
            sel = sorted((r for r in rows if r["quantity"] == q and r["method"] == method
                          and r["stages"] == stages), key=lambda r: float(r["rtol"]))
            err, t = _finite([float(r["median_rel_err"]) for r in sel],
                             [float(r["time_per_point_us"]) for r in sel])
            if not err.size:
                continue
            colour, marker, _ = STYLES.get(method, ("0.5", ".", ":"))
            ax.plot(err, t, color=colour, marker=marker, ls="-" if stages == "both" else "--",
                    label=f"{method} ({stages})")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{OUTPUTS[q].long_name} {_symbol(q)}" if q in OUTPUTS else q)
        ax.set_xlabel("median relative error against the reference")
        ax.grid(alpha=0.3, which="both")
        if ax.lines:
            ax.legend(fontsize="small", loc="best")
    axes[0].set_ylabel(TIME_LABEL)
    if title:
        fig.suptitle(title)
    return fig
