"""Figures of where the model has a solution: the phase plane (figure 12), regime maps over a
2-D slice of a sweep, and the traced edge ``eta_max(A, N)``.

The data come from :mod:`cosserat_channel.regimes` and from sweep Datasets, computed by the caller:
nothing here solves (the traced edge of a regime map is passed in as a boundary Dataset;
:func:`regime_trace_grid` says on which ``(A, N)`` to trace it). Every figure has axis
labels in the paper's symbols, a title naming the fixed parameters, and one legend entry per
status, region or boundary drawn (contour lines get proxy handles so that they appear there).
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from .. import outputs
from ..physics import analytic
from .. import regime_codes as rc
from .. import status as st
from ..parameters import DIMS
from . import HANDLE_LENGTH, axis_label, new_figure, parameter_title, save_figure
# The traced edges are opaque lines twice as wide as the analytic lines and drawn under them:
# where the traced edge is the axis condition (or the wall line) both stay visible, the analytic
# line inside the traced one. Opaque, so that their colour does not mix with the region's
# beneath; not wider, so that a line lies on the edge of the region it bounds.
BOUNDARY_STYLES = {
    "wall": dict(color="k", ls="-", lw=1.8, alpha=1.0, zorder=4),
    "axis": dict(color="#0033cc", ls="--", lw=1.8, alpha=1.0, zorder=4),
    "A=-1": dict(color="#8b4513", ls=":", lw=2.5, alpha=1.0, zorder=4),
    "traced": dict(color="#00bfff", ls="-", lw=3.6, alpha=1.0, zorder=3),
    "traced_min": dict(color="#e7298a", ls="-", lw=3.6, alpha=1.0, zorder=3),
    "switch": dict(color="#d95f02", ls="-.", lw=1.5, alpha=1.0, zorder=4),
}
BOUNDARY_LABELS = {
    "wall": r"$A = 1 - 2N^2$ (wall inadmissible below)",
    "axis": r"$(A-1)\,\varepsilon L + 2(A+1)N = 0$ (axis condition)",
    "A=-1": r"$A = -1$",
    "traced": r"traced edge $\varepsilon L = \eta_{\max}(A, N)$",
    "traced_min": r"traced lower edge $\varepsilon L = \eta_{\min}(A, N)$",
    "switch": r"$N^2 = (5 + 3A)/2$ (node/focus switch: above, $\eta_{\max}$ is the node's)",
}
# The analytic lines and the traced edges of a regime map are contoured on this many values per
# axis, evenly spaced over the plotted range (regime_trace_grid(..., n=MAP_GRID) gives them).
MAP_GRID = 400
# A regime map marks its computed points when it has at most this many (a coarse grid, where a
# cell is large enough that its colour could be mistaken for a region's exact extent).
MAP_NODES_SHOWN = 400
# A panel of the solvable region has a logarithmic colour scale when its values span more than
# this ratio (a decade); over less a linear scale separates them better.
LOG_SCALE_RATIO = 10.0
REGION_COLORS = {
    rc.REGION_D_NEGATIVE: "#d9d9d9",
    rc.REGION_EP_POS_EM_NEG: "#fff2b3",
    rc.REGION_EM_POS: "#c6e2ff",
    rc.REGION_EP_NEG: "#f4c2c2",
}


# ---------------------------------------------------------------------------------------------
# Phase plane (figure 12)
# ---------------------------------------------------------------------------------------------
def phase_plane_figure(pp, nu=None, path=None, *, fig=None):
    """Figure 12 for any ``(eps, L, A, N)``: sign regions, ``D = 0``, nullcline, trajectories.

    Parameters
    ----------
    pp : regimes.PhasePlane
        From :func:`cosserat_channel.regimes.phase_plane`.
    nu : float, optional
        Solids fraction: plot the paper's ``m_bar = nu m`` (figure 12 uses nu = 0.603) instead
        of ``m_bar / nu``.
    path : path-like, optional
        Where to save the figure.
    fig : matplotlib.figure.Figure or SubFigure, optional
        Draw into this (a panel of a larger figure) instead of a new figure.
    """
    scale = 1.0 if nu is None else float(nu)
    fig = new_figure() if fig is None else fig
    ax = fig.subplots()
    codes = sorted(REGION_COLORS)
    cmap = ListedColormap([REGION_COLORS[c] for c in codes])
    norm = BoundaryNorm(np.arange(len(codes) + 1) - 0.5, cmap.N)
    ax.pcolormesh(pp.xi, scale * pp.m, pp.region, cmap=cmap, norm=norm, shading="nearest",
                  rasterized=True)
    handles = [Patch(facecolor=REGION_COLORS[c], edgecolor="0.5", label=rc.REGION_LABELS[c])
               for c in codes if np.any(pp.region == c)]
    for sgn, lab in ((1, r"$D = 0$"), (-1, None)):
        (ln,) = ax.plot(pp.xi, sgn * scale * pp.D_zero, color="k", lw=2.0, label=lab)
    handles.append(ln)
    ln.set_label(r"$D = 0$")
    null_name = r"$E_{-} = 0$" if pp.A > -1.0 else r"$E_{+} = 0$"
    for sgn in (1, -1):
        (nl,) = ax.plot(pp.xi, sgn * scale * pp.nullcline, color="0.3", lw=1.2, ls="--")
    nl.set_label(null_name + r" ($\xi^2 + \bar m^2/(\nu L)^2 = N^2$)")
    handles.append(nl)
    styles = {("+", -1): dict(color="C3", ls="-."), ("-", -1): dict(color="C0", ls=":"),
              ("+", 1): dict(color="C1", ls="-."), ("-", 1): dict(color="C2", ls=":")}
    for tr in pp.trajectories:
        style = styles[(tr.root, -1 if tr.start < 0 else 1)]
        if tr.xi.size > 1:
            (h,) = ax.plot(tr.xi, scale * tr.m, lw=2.5, label=tr.label, **style)
            if tr.end == "D=0":
                ax.plot(tr.xi[-1], scale * tr.m[-1], "x", color=style["color"], ms=9, mew=2)
        else:
            (h,) = ax.plot(tr.xi, scale * tr.m, "o", mfc="none", ms=9, mew=2,
                           color=style["color"], label=tr.label)
        handles.append(h)
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(scale * pp.m[0], scale * pp.m[-1])
    ax.set_xlabel(axis_label("xi"))
    m = outputs.PROFILES["m"]
    ax.set_ylabel(rf"{m.long_name} $\bar m$ ({m.unit_label})" if nu is not None else m.label)
    # Below the plane, in two columns: beside it the long trajectory labels took 40 % of the width.
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.09), ncols=2,
              fontsize="small", frameon=False, handlelength=HANDLE_LENGTH)
    title = (r"Phase plane (paper figure 12): $E_{+}$ of eq:a1, $E_{-}$ of eq:a2; "
             + parameter_title(pp.eps, pp.L, None, pp.A, pp.N))
    if nu is not None:
        title += rf", $\nu$ = {nu:.4g}"
    ax.set_title(title)
    if path is not None:
        save_figure(fig, path)
    return fig


# ---------------------------------------------------------------------------------------------
# Slices of a sweep
# ---------------------------------------------------------------------------------------------
def select_slice(ds, keep, at=None):
    """``ds`` reduced to the dimensions ``keep``: size-1 dims squeezed, others picked by ``at``.

    ``at`` maps a dimension to a value (nearest coordinate). Returns ``(slice, fixed)`` with
    ``fixed`` the values of every dimension not kept. Raises ValueError naming the dimensions
    that still vary.
    """
    at = dict(at or {})
    for k in at:
        if k not in ds.dims:
            raise ValueError(f"--at {k}: not a dimension of the result (have {', '.join(ds.dims)})")
        if k in keep:
            raise ValueError(f"--at {k}: {k} is plotted, it cannot also be fixed")
    sub = ds.sel({k: v for k, v in at.items()}, method="nearest") if at else ds
    loose = [d for d in DIMS if d in sub.dims and d not in keep and sub.sizes[d] > 1]
    if loose:
        raise ValueError(
            f"dimension(s) {', '.join(loose)} vary in the result: fix them with --at "
            + ",".join(f"{d}=VALUE" for d in loose)
        )
    fixed = {d: float(sub[d].values.reshape(-1)[0]) for d in DIMS
             if d in sub.coords and d not in keep}
    sub = sub.squeeze([d for d in DIMS if d in sub.dims and d not in keep], drop=False)
    return sub, fixed


def _cell_edges(v):
    """Edges of the cells around the grid values ``v``, clipped to the computed range.

    Inner edges lie halfway between neighbours, the outer two on the first and last value, so
    that no cell reaches past what was computed (the end cells are half cells). A single value
    gets a unit-wide cell around it.
    """
    v = np.asarray(v, dtype=float)
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    return np.r_[v[0], 0.5 * (v[1:] + v[:-1]), v[-1]]


def _boundary_fields(x, y, X, Y, fixed, traced):
    """Implicit functions of the boundaries on the grid ``(X, Y)`` (zero on each line)."""
    p = {d: fixed.get(d) for d in DIMS}
    p[x], p[y] = X, Y
    if any(p[d] is None for d in ("eps", "L", "A", "N")):
        return {}
    eps, L, A, N = (np.broadcast_to(np.asarray(p[d], float), X.shape) for d in ("eps", "L", "A", "N"))
    eta = eps * L
    out = {
        "wall": A - (1.0 - 2.0 * N**2),
        "axis": np.where(A > -1.0, (A - 1.0) * eta + 2.0 * (A + 1.0) * N, np.nan),
        "A=-1": A + 1.0,
    }
    if traced is not None:
        out["traced"] = traced["eta_max"] - eta
        out["traced_min"] = traced["eta_min"] - eta
    return out


def regime_trace_grid(ds, x="A", y="N", at=None, n=12):
    """The ``(A, N)`` values on which :func:`regime_map` wants the traced edge of this slice.

    ``n`` evenly spaced values over the range of each of A and N that is plotted, the fixed value
    of the other. The edge is smooth in A and N and is interpolated onto the figure's grid, so a
    coarse trace is enough (tracing is ~1 s per (A, N)). Nothing is traced here: pass the values
    to :func:`cosserat_channel.regimes.trace_boundary` and its Dataset to :func:`regime_map`.

    Returns
    -------
    (ndarray, ndarray) or None
        ``(A, N)``; None when neither A nor N is plotted or the slice is a single row or column
        (the map then draws no boundary lines). Raises ValueError as :func:`regime_map` does.
    """
    sub, fixed = _map_slice(ds, x, y, at)
    if not {"A", "N"} & {x, y} or sub.sizes[x] < 2 or sub.sizes[y] < 2:
        return None
    values = {}
    for d in ("A", "N"):
        if d in (x, y):
            v = np.asarray(sub[d].values, float)
            values[d] = np.linspace(v.min(), v.max(), n)
        else:
            values[d] = np.array([fixed[d]])
    return values["A"], values["N"]


def _map_slice(ds, x, y, at):
    """The checked 2-D slice of a regime map and its fixed values (see :func:`select_slice`)."""
    if x == y or x not in DIMS or y not in DIMS:
        raise ValueError(f"--x and --y must be two different dimensions of {DIMS}; got {x!r}, {y!r}")
    if "status" not in ds:
        raise ValueError("the result has no 'status' variable")
    return select_slice(ds, (x, y), at)


def _traced_on_grid(x, y, xv, yv, fixed, boundary):
    """``eta_max`` and ``eta_min`` (where bounded) of ``boundary`` interpolated on the plot grid."""
    if not [d for d in (x, y) if d in ("A", "N")]:
        return None
    kind = boundary["edge_kind"]
    eta_max = boundary["eta_max"].where(kind == rc.EDGE_BOUNDED)
    first_ok = boundary["eta_min"] > boundary.attrs.get("eta_search_min", rc.ETA_SEARCH_MIN)
    eta_min = boundary["eta_min"].where((kind != rc.EDGE_NONE) & first_ok)
    X, Y = np.meshgrid(xv, yv)
    axes = {x: np.asarray(xv, float), y: np.asarray(yv, float)}
    out = {}
    for name, field in (("eta_max", eta_max), ("eta_min", eta_min)):
        f = field
        for d in ("A", "N"):
            if f.sizes[d] == 1:
                f = f.isel({d: 0}, drop=True)
        if all(d in axes and np.array_equal(f[d].values, axes[d]) for d in f.dims):
            # Evaluated on the figure's own grid (an atlas can be): taken as it is, no
            # interpolation (and no scipy import in a fresh process).
            v = np.asarray(f.transpose(*(d for d in (y, x) if d in f.dims)).values, float)
            v = v if y in f.dims else v[None, ...]
            v = v if x in f.dims else v[..., None]
            out[name] = np.broadcast_to(v, X.shape).copy()
            continue
        sel = {}
        for d, G in ((x, X), (y, Y)):
            if d in ("A", "N"):
                sel[d] = G
        for d in ("A", "N"):
            if d not in sel:
                sel[d] = np.full(X.shape, fixed[d])
        coords = {d: (("r", "c"), sel[d]) for d in ("A", "N") if d in f.dims}
        import xarray as xr

        vals = f.interp({d: xr.DataArray(sel[d], dims=("r", "c")) for d in coords})
        out[name] = np.asarray(vals.values, float)
    return out


def regime_map(ds, x="A", y="N", at=None, *, boundary=None, path=None):
    """Status over a 2-D slice of a sweep, one colour and legend entry per status present.

    Overlays, where the other parameters are fixed: ``A = 1 - 2N^2``, the axis condition
    ``(A-1) eps L + 2(A+1) N = 0`` (for ``A > -1``), ``A = -1`` and, when ``boundary`` is given,
    the traced edge ``eps L = eta_max(A, N)`` (and the lower edge ``eta_min`` where one exists),
    each in the legend when it crosses the plotted range.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep result (dims eps, L, K, A, N) with ``status``.
    x, y : str
        The two dimensions to map.
    at : dict, optional
        Values (nearest) of the other dimensions that have more than one value.
    boundary : xarray.Dataset, optional
        From :func:`cosserat_channel.regimes.trace_boundary`, e.g. on the values
        :func:`regime_trace_grid` gives; interpolated onto the plot. Without it no traced edge is
        drawn (this function never solves).
    path : path-like, optional
        Where to save the figure.
    """
    sub, fixed = _map_slice(ds, x, y, at)
    status = sub["status"].transpose(y, x).values.astype(int)
    xv, yv = sub[x].values.astype(float), sub[y].values.astype(float)
    fig = new_figure()
    ax = fig.subplots()
    codes = [s.value for s in st.Status]
    cmap = ListedColormap([st.Status(c).color for c in codes])
    norm = BoundaryNorm(np.arange(len(codes) + 1) - 0.5, cmap.N)
    xe, ye = _cell_edges(xv), _cell_edges(yv)
    ax.pcolormesh(xe, ye, status, cmap=cmap, norm=norm, shading="flat", rasterized=True)
    handles = [Patch(facecolor=st.Status(c).color, edgecolor="0.3",
                     label=st.Status(c).name) for c in codes if np.any(status == c)]

    xf = np.linspace(xv.min(), xv.max(), MAP_GRID) if xv.size > 1 else xv
    yf = np.linspace(yv.min(), yv.max(), MAP_GRID) if yv.size > 1 else yv
    if xv.size > 1 and yv.size > 1:
        traced = None if boundary is None else _traced_on_grid(x, y, xf, yf, fixed, boundary)
        X, Y = np.meshgrid(xf, yf)
        for name, F in _boundary_fields(x, y, X, Y, fixed, traced).items():
            F = np.asarray(F, float)
            if not (np.nanmin(F, initial=np.inf) < 0.0 < np.nanmax(F, initial=-np.inf)):
                continue
            style = BOUNDARY_STYLES[name]
            cs = ax.contour(X, Y, F, levels=[0.0], colors=[style["color"]],
                            linestyles=[style["ls"]], linewidths=[style["lw"]],
                            alpha=style["alpha"], zorder=style["zorder"])
            if not any(len(seg) for seg in cs.allsegs[0]):
                continue
            handles.append(Line2D([], [], label=BOUNDARY_LABELS[name],
                                  **{k: v for k, v in style.items() if k != "zorder"}))
    if xv.size * yv.size <= MAP_NODES_SHOWN:
        # Each cell is the status at its centre: on a coarse grid the dots show where that was
        # computed, and the analytic lines run between dots of different colour.
        X0, Y0 = np.meshgrid(xv, yv)
        handles.append(ax.plot(X0.ravel(), Y0.ravel(), ls="none", marker=".", ms=3, color="k",
                               alpha=0.6, zorder=5, clip_on=False,
                               label="computed point (colours its cell)")[0])
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(axis_label(x))
    ax.set_ylabel(axis_label(y))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
              title="status / boundary", handlelength=HANDLE_LENGTH)
    ax.set_title("Solution status: " + parameter_title(**fixed))
    if path is not None:
        save_figure(fig, path)
    return fig


def boundary_figure(bds, path=None):
    """``eta_max(A)`` with one line per ``N`` (log scale), the axis edge of each ``N`` dashed."""
    fig = new_figure()
    ax = fig.subplots()
    A = bds["A"].values
    top = bds.attrs.get("eta_search_max", rc.ETA_SEARCH_MAX)
    flagged = False
    for j, n in enumerate(bds["N"].values):
        color = f"C{j % 10}"
        kind = bds["edge_kind"].values[:, j]
        em = bds["eta_max"].values[:, j]
        bounded = np.where(kind == rc.EDGE_BOUNDED, em, np.nan)
        ax.plot(A, bounded, "-o", ms=3, color=color, label=rf"$\eta_{{\max}}$, $N$ = {n:.4g}")
        ax.plot(A, bds["axis_edge_eta"].values[:, j], "--", lw=1, color=color)
        unb = kind == rc.EDGE_UNBOUNDED
        if unb.any():
            ax.plot(A[unb], np.full(unb.sum(), top), "^", mfc="none", color=color,
                    label=None if flagged else rf"ok up to $\eta$ = {top:g} (no edge found)")
            flagged = True
    ax.plot([], [], "--", color="0.4", lw=1, label=r"axis condition $\eta = 2(A+1)N/(1-A)$")
    ax.set_yscale("log")
    ax.set_xlabel(axis_label("A"))
    ax.set_ylabel(r"$\eta_{\max} = (\varepsilon L)_{\max}$ (-)")
    ax.set_title(r"Edge of solvability: largest $\eta = \varepsilon L$ with a solution "
                 rf"(searched in [{bds.attrs.get('eta_search_min', 0):g}, {top:g}])")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small", loc="best")
    if path is not None:
        save_figure(fig, path)
    return fig


def _fitted_norm(values):
    """A colour norm spanning the finite ``values``: logarithmic when they span more than
    :data:`LOG_SCALE_RATIO`, else linear; None when no value is finite."""
    from matplotlib.colors import LogNorm, Normalize

    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    lo, hi = float(v.min()), float(v.max())
    if lo > 0.0 and hi > LOG_SCALE_RATIO * lo:
        return LogNorm(lo, hi)
    return Normalize(lo, hi)


def _crosses_box(x, y, xlim, ylim):
    """Whether the sampled curve ``(x, y)`` has a point strictly inside the box ``xlim x ylim``
    (a line on the box's edge, or outside it, is not drawn and not in the legend)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    return bool(np.any((x > xlim[0]) & (x < xlim[1]) & (y > ylim[0]) & (y < ylim[1])))


def solvable_region_figure(bds, path=None):
    """Where the model has a solution in ``(A, N)``: ``eta_max`` shaded, ``eta_min`` beside it.

    Left, the largest ``eta = eps L`` with a solution (hatched where every searched ``eta`` is ok,
    so ``eta_max`` is beyond the range), with the node/focus switch
    (:func:`cosserat_channel.physics.analytic.node_focus_switch_N`) across which it is not analytic;
    right, the smallest, where small ``eta`` fails too (hatched where the lowest searched ``eta``
    is ok). Each panel has its own colour scale fitted to the values it shows (logarithmic when
    they span more than a decade), so that a narrow range of ``eta`` is not one flat colour. The
    analytic lines ``A = 1 - 2N^2``, ``A = -1`` and ``A = 1`` (above which the axis condition
    never binds) are drawn where they cross the box; grey where there is no solution for any
    ``eta``, white where the data do not decide (an unresolved atlas cell), dotted where the data
    state an error above their tolerance (an atlas cell that could not reach it: ``eta_error``).
    One legend below both panels lists each thing drawn once.

    Parameters
    ----------
    bds : xarray.Dataset
        A boundary Dataset on a fine ``(A, N)`` grid, e.g. from
        :meth:`cosserat_channel.atlas.Atlas.boundary` (this function never solves).
    path : path-like, optional
        Where to save the figure.
    """
    A = bds["A"].values.astype(float)
    N = bds["N"].values.astype(float)
    kind = bds["edge_kind"].values.T
    resolved = bds["resolved"].values.T if "resolved" in bds else np.ones(kind.shape, bool)
    lo = float(bds.attrs.get("eta_search_min", rc.ETA_SEARCH_MIN))
    hi = float(bds.attrs.get("eta_search_max", rc.ETA_SEARCH_MAX))
    eta_max = np.where(kind == rc.EDGE_BOUNDED, bds["eta_max"].values.T, np.nan)
    eta_min_all = bds["eta_min"].values.T
    eta_min = np.where((kind != rc.EDGE_NONE) & (eta_min_all > lo), eta_min_all, np.nan)
    fig = new_figure(figsize=(13.0, 7.5))
    axes = fig.subplots(1, 2, sharey=True)
    A_lim, N_lim = (A.min(), A.max()), (N.min(), N.max())
    A_edges, N_edges = _cell_edges(A), _cell_edges(N)
    AA, NN = np.meshgrid(A, N)
    none = resolved & (kind == rc.EDGE_NONE)
    N_wall = np.linspace(*N_lim, MAP_GRID)
    A_wall = 1.0 - 2.0 * N_wall**2
    A_sw = np.linspace(max(A_lim[0], -1.0), min(A_lim[1], 1.0), MAP_GRID)
    N_sw = analytic.node_focus_switch_N(A_sw) if A_sw[0] < A_sw[-1] else np.full(A_sw.shape, np.nan)
    # Where the source states an error above its tolerance (an atlas's envelope cells).
    err = bds["eta_error"].values.T if "eta_error" in bds else None
    tol = float(bds.attrs.get("atlas_tol", np.nan))
    rough = None
    if err is not None and np.isfinite(tol):
        with np.errstate(invalid="ignore"):
            mask = resolved & (err > tol * (1.0 + 1e-9))
        rough = np.where(mask, 1.0, np.nan) if mask.any() else None
    # One legend for the figure: the panels share the lines, each is listed once.
    handles = {}

    def keep(handle):
        handles.setdefault(handle.get_label(), handle)

    # Beyond the searched range: a pale tint past the colour scale's end, and hatched.
    panels = (
        (axes[0], eta_max, r"$\eta_{\max}$", kind == rc.EDGE_UNBOUNDED, "//", "#fff7c2",
         rf"ok up to $\eta$ = {hi:g}", r": largest $\varepsilon L$ with a solution"),
        (axes[1], eta_min, r"$\eta_{\min}$", (kind != rc.EDGE_NONE) & (eta_min_all <= lo), "\\\\",
         "#ece4f4", rf"ok down to $\eta$ = {lo:g}",
         rf": smallest $\varepsilon L$ with a solution (where > {lo:g})"),
    )
    for ax, field, name, beyond, hatch, tint, text, title in panels:
        if none.any():
            ax.pcolormesh(A_edges, N_edges, np.where(none, 1.0, np.nan),
                          cmap=ListedColormap(["#d9d9d9"]), shading="flat", rasterized=True)
            keep(Patch(facecolor="#d9d9d9", edgecolor="0.5",
                       label=r"no solution for any $\eta$ in range"))
        norm = _fitted_norm(field)
        if norm is not None:
            mesh = ax.pcolormesh(A_edges, N_edges, field, norm=norm, cmap="viridis",
                                 shading="flat", rasterized=True)
            fig.colorbar(mesh, ax=ax, label=name + r" (-)", shrink=0.9)
        # Beyond the searched range: hatched, so that it is not mistaken for undecided (white).
        beyond = np.where(resolved & beyond, 1.0, np.nan)
        if np.isfinite(beyond).any():
            ax.pcolormesh(A_edges, N_edges, beyond, cmap=ListedColormap([tint]), shading="flat",
                          rasterized=True)
            ax.contourf(AA, NN, beyond, levels=[0.5, 1.5], colors="none", hatches=[hatch])
            keep(Patch(facecolor=tint, edgecolor="0.3", hatch=hatch, label=text))
        if (~resolved).any():
            keep(Patch(facecolor="white", edgecolor="0.5", label="undecided (atlas)"))
        if rough is not None:
            # Cells that could not reach the tolerance: drawn with the error they state.
            ax.contourf(AA, NN, rough, levels=[0.5, 1.5], colors="none", hatches=["...."])
            keep(Patch(facecolor="none", edgecolor="0.3", hatch="....",
                       label=f"error above the atlas's tolerance (up to {np.nanmax(err):.2g}, "
                             "relative)"))
        if _crosses_box(A_wall, N_wall, A_lim, N_lim):
            keep(ax.plot(A_wall, N_wall, label=BOUNDARY_LABELS["wall"], **BOUNDARY_STYLES["wall"])[0])
        if ax is axes[0] and _crosses_box(A_sw, N_sw, A_lim, N_lim):
            # eta_max is not analytic across this curve (a kink in its contours)
            keep(ax.plot(A_sw, N_sw, label=BOUNDARY_LABELS["switch"], **BOUNDARY_STYLES["switch"])[0])
        for value, label, style in ((-1.0, BOUNDARY_LABELS["A=-1"], BOUNDARY_STYLES["A=-1"]),
                                    (1.0, r"$A = 1$ (axis condition binds only for $A < 1$)",
                                     dict(color="#0033cc", ls="--", lw=1.5, zorder=4))):
            if A_lim[0] < value < A_lim[1]:
                keep(ax.axvline(value, label=label, **style))
        ax.set_xlim(*A_lim)
        ax.set_ylim(*N_lim)
        ax.set_xlabel(axis_label("A"))
        ax.set_title(name + title)
    axes[0].set_ylabel(axis_label("N"))
    # Below the panels, inside the figure: constrained layout makes room for an "outside" legend.
    # Areas first, then lines, each in the order drawn.
    if handles:
        fig.legend(handles=sorted(handles.values(), key=lambda h: not isinstance(h, Patch)),
                   loc="outside lower center", ncols=2, fontsize="small", frameon=False)
    fig.suptitle("Solvable region in (A, N)" + (f" (atlas, tolerance {tol:g})"
                                                 if np.isfinite(tol) else ""))
    if path is not None:
        save_figure(fig, path)
    return fig
