"""The paper's figures 2-12 and table 1, drawn one for one from :mod:`cosserat_channel.paper`'s
data, each in the paper's single-panel layout with the paper's stated numbers beside ours below.

:func:`draw` takes a :class:`cosserat_channel.paper.PaperFigure` and returns a Figure; nothing
here solves. Line styles follow the captions: solid for the numerical solution, open circles (and
squares for a second ``eps``) for the asymptotic one, dashes and dots where the paper uses them.
"""

from __future__ import annotations

import dataclasses
import textwrap

import numpy as np

from .. import outputs
from .. import status as st
from . import HANDLE_LENGTH, axis_label, new_figure, shear_stress_label

FIGSIZE = (7.5, 6.6)
TABLE_FIGSIZE = (7.5, 3.9)
CAPTION_WIDTH = 110  # characters per line of the comparison under the panel
N_MARKERS = 21
# The paper's line kinds (its \linezero, \lineone, \linetwo, \linedotted, \linedotdash).
SOLID, DASHED, LONG_DASHED, DOTTED, DOT_DASH = "-", (0, (4, 3)), (0, (9, 3)), (0, (1, 2)), "-."
CIRCLE = dict(ls="none", marker="o", mfc="none", color="k", ms=6)
SQUARE = dict(ls="none", marker="s", mfc="none", color="k", ms=6)


def draw(pf):
    """The Figure of one :class:`~cosserat_channel.paper.PaperFigure` (by its ``key``)."""
    try:
        drawer = DRAWERS[pf.key]
    except KeyError:
        raise ValueError(f"no drawing for {pf.key!r}; have {', '.join(DRAWERS)}") from None
    width, height = TABLE_FIGSIZE if pf.key == "table1" else FIGSIZE
    lines = _caption_lines(pf)
    # The comparison's lines get their own inches below the drawing (7.5 pt monospace, about
    # 0.13 in a line), so a long comparison never clips at the figure's edge.
    footer = 0.25 + 0.13 * len(lines)
    fig = new_figure((width, height + footer))
    top, bottom = fig.subfigures(2, 1, height_ratios=[height, footer])
    drawer(pf, top)
    bottom.text(0.02, 0.97, "\n".join(lines), va="top", ha="left", fontsize=7.5,
                family="monospace")
    return fig


def _caption_lines(pf):
    """The paper's numbers beside ours, one entry per row, wrapped to the width of the figure."""
    lines = []
    for r in pf.rows:
        text = f"{r.what}: paper {r.paper}; ours {r.ours}" + (f" \u2014 {r.note}" if r.note else "")
        lines += textwrap.wrap(text, CAPTION_WIDTH, initial_indent="- ", subsequent_indent="  ")
    return lines


def _axes(sub, pf, xlabel, ylabel):
    ax = sub.subplots()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title("\n".join(textwrap.wrap(pf.title, 80)), fontsize="medium")
    ax.grid(alpha=0.25)
    return ax


def _markers(x, y, n=N_MARKERS):
    x, y = np.asarray(x), np.asarray(y)
    i = np.unique(np.linspace(0, x.size - 1, min(n, x.size)).round().astype(int))
    return x[i], y[i]


def _xi_axes(sub, pf, name):
    ax = _axes(sub, pf, axis_label("xi"), axis_label(name))
    ax.set_xlim(0.0, 1.0)
    return ax


ASYMPTOTIC = "asymptotic (Appendix C)"


# ---------------------------------------------------------------------------------------------
# Figures 2-6
# ---------------------------------------------------------------------------------------------
def figure2(pf, sub):
    d = pf.data
    ax = _xi_axes(sub, pf, "u_over_u0")
    for L, ls in zip(sorted(d["u"]), (LONG_DASHED, SOLID, DASHED)):
        ax.plot(d["xi"], d["u"][L], color="k", ls=ls, lw=1.6, label=f"numerical, $L$ = {L:g}")
    ax.plot(*_markers(d["xi"], d["asymptotic"]), label=ASYMPTOTIC + ", $L$ = 10", **CIRCLE)
    ax.legend(handlelength=HANDLE_LENGTH, loc="lower left")


def _u_numerical_and_asymptotic(pf, sub):
    d = pf.data
    ax = _xi_axes(sub, pf, "u_over_u0")
    ax.plot(d["xi"], d["u"], color="k", lw=1.6, label="numerical")
    ax.plot(*_markers(d["xi"], d["asymptotic"]), label=ASYMPTOTIC, **CIRCLE)
    ax.legend(handlelength=HANDLE_LENGTH, loc="lower left")


figure3 = figure4 = _u_numerical_and_asymptotic

OMEGA_BAR = r"angular velocity $\bar\omega$"


def figure5(pf, sub):
    d = pf.data
    ax = _axes(sub, pf, axis_label("xi"), OMEGA_BAR + r", $-\frac{1}{2}\,du/d\xi$")
    ax.set_xlim(0.0, 1.0)
    ax.plot(d["xi"], d["omega"], color="k", lw=1.6, label=r"$\bar\omega$")
    ax.plot(d["xi"], d["half_vorticity"], color="k", ls=DASHED, lw=1.6,
            label=r"half the vorticity, $-\frac{1}{2}\,du/d\xi$")
    ax.plot(*_markers(d["xi"], d["asymptotic"]), label=ASYMPTOTIC + r", $\bar\omega$", **CIRCLE)
    ax.legend(handlelength=HANDLE_LENGTH, loc="upper left")


def figure6(pf, sub):
    d = pf.data
    ax = _axes(sub, pf, axis_label("xi"), OMEGA_BAR)
    ax.set_xlim(0.0, 1.0)
    ax.plot(d["xi"], d["omega"], color="k", lw=1.6, label=r"numerical $\bar\omega$")
    ax.plot(*_markers(d["xi"], d["asymptotic"]), label=ASYMPTOTIC, **CIRCLE)
    ax.legend(handlelength=HANDLE_LENGTH, loc="upper left")


# ---------------------------------------------------------------------------------------------
# Figures 7-9
# ---------------------------------------------------------------------------------------------
def _Delta_against(pf, sub, x):
    """Delta against the data's ``x`` with the asymptote's markers (figures 7 and 8)."""
    d = pf.data
    ax = _axes(sub, pf, axis_label(x), axis_label("Delta"))
    ax.plot(d[x], d["Delta"], color="k", lw=1.6, label="numerical")
    ax.plot(*_markers(d[x], d["asymptotic"], 15), label=ASYMPTOTIC, **CIRCLE)
    ax.legend(handlelength=HANDLE_LENGTH, loc="upper left")
    return ax


def figure7(pf, sub):
    _Delta_against(pf, sub, "W_over_d_p").set_xscale("log")


def figure8(pf, sub):
    _Delta_against(pf, sub, "L").set_xlim(0.0, float(np.max(pf.data["L"])))


def figure9(pf, sub):
    d = pf.data
    ax = _axes(sub, pf, axis_label("K"), axis_label("Delta"))
    ax.plot(d["K"], d["Delta"], color="k", lw=1.6, label="numerical")
    if np.isfinite(d["K_star"]):
        ax.axvline(d["K_star"], color="0.5", ls=DOTTED, lw=1.2,
                   label=rf"$K$ = {d['K_star']:.1f}: $u(1) \geq 0.95\,u(0)$, $\Delta$ = 0")
    ax.set_xlim(0.0, float(np.max(d["K"])))
    ax.set_ylim(bottom=0.0)
    ax.legend(handlelength=HANDLE_LENGTH, loc="upper right")


# ---------------------------------------------------------------------------------------------
# Figures 10-12
# ---------------------------------------------------------------------------------------------
def _eps_label(eps):
    return rf"$\varepsilon$ = 1/{1.0 / eps:.0f}"


def figure10(pf, sub):
    d = pf.data
    ax = _axes(sub, pf, axis_label("xi"), shear_stress_label())
    ax.set_xlim(0.0, 1.0)
    xy, yx = outputs.PROFILES["sigma_xy"].symbol, outputs.PROFILES["sigma_yx"].symbol
    ax.plot(d["xi"], d["sigma_xy"], color="k", lw=1.6, label=xy + r" $= -\xi$ (both $\varepsilon$)")
    _per_eps(ax, d, "sigma_yx", (DOTTED, LONG_DASHED), yx)
    ax.legend(handlelength=HANDLE_LENGTH, loc="lower left")


def _per_eps(ax, d, name, dashes, label):
    """``d[name][eps]`` against xi for each eps (largest first) with its asymptote's markers."""
    for e, ls, marks in zip(sorted(d[name], reverse=True), dashes, (CIRCLE, SQUARE)):
        ax.plot(d["xi"], d[name][e], color="k", ls=ls, lw=1.8, label=f"{label}, {_eps_label(e)}")
        ax.plot(*_markers(d["xi"], d["asymptotic"][e]), label=f"{ASYMPTOTIC}, {_eps_label(e)}",
                **marks)


def figure11(pf, sub):
    d = pf.data
    ax = _xi_axes(sub, pf, "m")
    _per_eps(ax, d, "m", (DOTTED, DASHED), "numerical")
    ax.legend(handlelength=HANDLE_LENGTH, loc="upper left")


def figure12(pf, sub):
    from .regimes import phase_plane_figure

    pp = pf.data["phase_plane"]
    # The paper draws the two trajectories from m(0) = -N L nu only.
    pp = dataclasses.replace(pp, trajectories=[t for t in pp.trajectories if t.start < 0])
    phase_plane_figure(pp, nu=pf.data["nu"], fig=sub)
    sub.axes[0].set_title("\n".join(textwrap.wrap(pf.title, 80)), fontsize="medium")


# ---------------------------------------------------------------------------------------------
# Table 1 and Appendix A
# ---------------------------------------------------------------------------------------------
def table1(pf, sub):
    d = pf.data
    ax = sub.subplots()
    ax.axis("off")
    ax.set_title("\n".join(textwrap.wrap(pf.title, 80)), fontsize="medium")
    table = ax.table(cellText=[list(r) for r in d["rows"]], colLabels=list(d["header"]),
                     loc="center", cellLoc="center")
    table.auto_set_font_size(False)
    table.set_fontsize(8.5)
    table.scale(1.0, 1.9)
    for (row, col), cell in table.get_celld().items():
        if row > 0 and "ours" in d["rows"][row - 1][0]:
            cell.set_facecolor("#e8f0fe")
        if col == 0:
            cell.set_width(0.27)


def appendix_a(pf, sub):
    """Where the printed formulation's march reaches the wall, per eps (columns) and rtol (rows)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    d = pf.data
    eps, rtol, reached = d["eps"], d["rtol"], d["reached"]
    ax = _axes(sub, pf, r"relative particle size $\varepsilon$ (columns: the values tried)",
               "LSODA rtol of the printed march")
    colours = [st.Status.eps_too_large_path.color, st.Status.ok.color]
    ax.pcolormesh(np.arange(eps.size + 1) - 0.5, np.arange(rtol.size + 1) - 0.5,
                  reached.astype(int), cmap=ListedColormap(colours), vmin=0, vmax=1,
                  edgecolors="w", linewidth=0.5)
    step = max(1, eps.size // 20)
    ticks = sorted(set(range(0, eps.size, step)) | {int(i) for i in np.flatnonzero(eps >= 0.3)})
    ax.set_xticks(ticks, [f"{eps[i]:.4g}" for i in ticks], rotation=90, fontsize=7)
    ax.set_yticks(range(rtol.size), [f"{r:.0e}" for r in rtol])
    ax.grid(False)
    edge = np.interp(d["eps_max"], eps, np.arange(eps.size))
    ax.axvline(edge, color="k", lw=2.0)
    at = np.interp(d["eps_paper"], eps, np.arange(eps.size))
    ax.axvline(at, color="k", ls=DASHED, lw=1.2)
    ax.legend(handles=[Patch(color=colours[1], label="reaches the wall"),
                       Patch(color=colours[0], label=r"meets $D < 0$ (no solution)"),
                       Line2D([], [], color="k", lw=2.0,
                              label=rf"true edge $\varepsilon$ = {d['eps_max']:.6f}"),
                       Line2D([], [], color="k", ls=DASHED, lw=1.2,
                              label=r"the paper's $\varepsilon$ = 0.33")],
              loc="upper center", bbox_to_anchor=(0.5, -0.2), ncols=2, fontsize="small",
              frameon=False)


DRAWERS = {f"figure{n}": globals()[f"figure{n}"] for n in range(2, 13)}
DRAWERS.update(table1=table1, appendix_a=appendix_a)
