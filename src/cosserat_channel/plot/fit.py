"""The figures of a calibration (:class:`cosserat_channel.calibrate.FitResult`): its residuals,
and its confidence region over the map of where the model has a solution.

Takes the finished fit's numbers (measurements, predictions, residuals, covariance) and the
statuses of a grid, and never solves.
"""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D

from .. import status as st
from . import axis_label, new_figure, save_figure

__all__ = ["residuals_figure", "confidence_region_figure"]


def residuals_figure(result, path=None):
    """Two panels: each row's normalised residual, and the measurements against the fit.

    Parameters
    ----------
    result : FitResult
        A finished fit (its ``data``, ``predictions``, ``residuals``, ``params``, ``errors``).
    path : str or path-like, optional
        Where to save the figure (format from the suffix).

    Returns
    -------
    matplotlib.figure.Figure
        Left: ``(prediction - value)/std_error`` per row, one colour per quantity, with the
        bands +-1 and +-2. Right: profile rows against ``xi`` (measured with error bars, fitted
        as a line) when the data hold a profile, else each row's measured value over its fitted
        one (quantities of any units side by side) with its error bar and the line of equality.
    """
    from matplotlib.ticker import MaxNLocator

    data = result.data
    quantities = list(dict.fromkeys(data.quantity.tolist()))
    colour = {q: f"C{k % 10}" for k, q in enumerate(quantities)}
    fig = new_figure((11.0, 4.8))
    ax_r, ax_m = fig.subplots(1, 2)
    rows = np.arange(1, len(data) + 1)
    for lim, alpha in ((2.0, 0.08), (1.0, 0.15)):
        ax_r.axhspan(-lim, lim, color="0.5", alpha=alpha, lw=0)
    ax_r.axhline(0.0, color="0.3", lw=0.8)
    for q in quantities:
        sel = data.quantity == q
        ax_r.plot(rows[sel], result.residuals[sel], "o", color=colour[q], label=q)
    ax_r.set_xlabel("measurement (row)")
    ax_r.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_r.set_ylabel("residual (fit - measured) / standard error")
    ax_r.legend(loc="best", fontsize="small")
    ax_r.grid(alpha=0.3)
    profile = data.is_profile
    if profile.any():
        drawn = [q for q in quantities if profile[data.quantity == q].all()]
        for q in drawn:
            sel = (data.quantity == q) & profile
            order = np.argsort(data.xi[sel])
            x = data.xi[sel][order]
            ax_m.errorbar(x, data.value[sel][order], yerr=data.std_error[sel][order], fmt="o",
                          ms=4, color=colour[q], label=f"{q} measured")
            ax_m.plot(x, result.predictions[sel][order], "-", color=colour[q], label=f"{q} fit")
        ax_m.set_xlabel(axis_label("xi"))
        ax_m.set_ylabel(axis_label(drawn[0]) if len(drawn) == 1 else "profile")
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = data.value / result.predictions
            spread = data.std_error / np.abs(result.predictions)
        for q in quantities:
            sel = data.quantity == q
            ax_m.errorbar(rows[sel], ratio[sel], yerr=spread[sel], fmt="o", ms=5,
                          color=colour[q], label=q)
        ax_m.axhline(1.0, color="0.3", lw=0.8, ls="--")
        ax_m.set_xlabel("measurement (row)")
        ax_m.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax_m.set_ylabel("measured / fitted")
    ax_m.legend(loc="best", fontsize="small")
    ax_m.grid(alpha=0.3)
    fit_text = ", ".join(f"{n} = {v:.4g} ± {e:.2g}" for n, v, e in
                         zip(result.names, result.estimates, result.std_errors))
    fig.suptitle(f"{fit_text};  $\\chi^2$/dof = {result.chi2_dof:.3g}")
    if path is not None:
        save_figure(fig, path)
    return fig


def confidence_region_figure(result, x, y, region, *, levels=(0.68, 0.95), truth=None,
                             title=None, path=None):
    """A fit's joint confidence regions of two parameters over the statuses of a grid.

    Parameters
    ----------
    result : FitResult
        A finished fit with ``x`` and ``y`` free (its estimates and covariance).
    x, y : str
        The two parameters (e.g. ``"A"``, ``"N"``): the horizontal and vertical axes.
    region : tuple
        ``(x_values, y_values, codes)``: the grid's values along each axis and the status code
        at each node, shape ``(x_values.size, y_values.size)``, as
        :func:`cosserat_channel.atlas.classify` gives them on ``numpy.meshgrid(..., indexing="ij")``
        (:class:`~cosserat_channel.status.Status` codes; negative where the grid does not decide).
        The other inputs of the grid (e.g. ``eps L``) are the caller's: say them in ``title``.
    levels : sequence of float
        Confidence levels whose regions (:meth:`FitResult.ellipse`) are drawn.
    truth : (float, float), optional
        The true values of a synthetic test, marked.
    title : str, optional
        Added to the figure's title.
    path : str or path-like, optional
        Where to save the figure.

    Returns
    -------
    matplotlib.figure.Figure
        Each status without a solution shaded in its colour, the undecided nodes hatched, the
        edge of the solvable region as a line, the regions as ellipses around the estimate.
        The title gives the distance from the estimate to the nearest node without a solution
        in standard deviations of the pair (:meth:`FitResult.mahalanobis`), beside the radius
        of the largest region drawn.
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from .regimes import _cell_edges

    xv = np.asarray(region[0], dtype=float)
    yv = np.asarray(region[1], dtype=float)
    codes = np.asarray(region[2])
    if codes.shape != (xv.size, yv.size):
        raise ValueError(f"region: codes have shape {codes.shape}; expected "
                         f"({xv.size}, {yv.size}) for the grid's values of {x} and {y}")
    fig = new_figure((9.0, 7.0))
    ax = fig.subplots()
    edges_x, edges_y = _cell_edges(xv), _cell_edges(yv)
    handles = []
    for status in st.Status:
        if status == st.Status.ok or not (codes == status.value).any():
            continue
        ax.pcolormesh(edges_x, edges_y, np.where(codes == status.value, 1.0, np.nan).T,
                      cmap=ListedColormap([status.color]), alpha=0.45, shading="flat",
                      rasterized=True)
        handles.append(Patch(facecolor=status.color, alpha=0.45,
                             label=f"no solution: {status.name}"))
    undecided = codes < 0
    if undecided.any():
        XX, YY = np.meshgrid(xv, yv, indexing="ij")
        ax.contourf(XX, YY, undecided.astype(float), levels=[0.5, 1.5], colors="none",
                    hatches=["xx"])
        handles.append(Patch(facecolor="none", edgecolor="0.3", hatch="xx",
                             label="undecided (a solve would decide)"))
    ok = codes == st.OK
    if ok.any() and (codes > 0).any():
        XX, YY = np.meshgrid(xv, yv, indexing="ij")
        # between the nodes with and without a solution only, not around the undecided ones
        side = np.ma.masked_where(undecided, ok.astype(float))
        ax.contour(XX, YY, side, levels=[0.5], colors="k", linewidths=1.5)
        handles.append(Line2D([], [], color="k", lw=1.5, label="edge of the solvable region"))
    for k, level in enumerate(sorted(levels)):
        ex, ey = result.ellipse(x, y, level)
        handles.append(ax.plot(ex, ey, color="C0", lw=2.2 if k == len(levels) - 1 else 1.2,
                               ls="-" if k == len(levels) - 1 else "--",
                               label=f"{level:.0%} confidence region")[0])
    i, j = result.names.index(x), result.names.index(y)
    handles.append(ax.plot(result.estimates[i], result.estimates[j], "o", color="C0",
                           label="estimate")[0])
    if truth is not None:
        handles.append(ax.plot(*truth, "*", color="C3", ms=12, label="truth")[0])
    ax.set_xlim(edges_x[0], edges_x[-1])
    ax.set_ylim(edges_y[0], edges_y[-1])
    ax.set_xlabel(axis_label(x))
    ax.set_ylabel(axis_label(y))
    ax.grid(alpha=0.3)
    ax.legend(handles=handles, loc="best", fontsize="small")
    text = f"{x} = {result.estimates[i]:.4g} ± {result.std_errors[i]:.2g}, " \
           f"{y} = {result.estimates[j]:.4g} ± {result.std_errors[j]:.2g}"
    bad = codes > 0
    if bad.any():
        XX, YY = np.meshgrid(xv, yv, indexing="ij")
        d = float(np.nanmin(result.mahalanobis(x, y, XX[bad], YY[bad])))
        radius = float(np.sqrt(-2.0 * np.log1p(-max(levels))))
        text += (f"\nnearest node without a solution: {d:.3g} standard deviations "
                 f"(the {max(levels):.0%} region's: {radius:.3g})")
    fig.suptitle((title + "\n" if title else "") + text)
    if path is not None:
        save_figure(fig, path)
    return fig

