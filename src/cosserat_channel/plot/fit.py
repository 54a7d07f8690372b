"""The residual figure of a calibration (:class:`cosserat_channel.calibrate.FitResult`).

Takes the finished fit's numbers (measurements, predictions, residuals) and never solves.
"""

from __future__ import annotations

import numpy as np

from . import axis_label, new_figure, save_figure

__all__ = ["residuals_figure"]


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
        as a line) when the data hold a profile, else measured against fitted values with the
        line of equality.
    """
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
        for q in quantities:
            sel = data.quantity == q
            ax_m.errorbar(result.predictions[sel], data.value[sel], yerr=data.std_error[sel],
                          fmt="o", ms=4, color=colour[q], label=q)
        finite = np.isfinite(result.predictions)
        both = np.concatenate([result.predictions[finite], data.value])
        lo, hi = float(both.min()), float(both.max())
        ax_m.plot([lo, hi], [lo, hi], color="0.3", lw=0.8, ls="--")
        ax_m.set_xlabel("fitted")
        ax_m.set_ylabel("measured")
    ax_m.legend(loc="best", fontsize="small")
    ax_m.grid(alpha=0.3)
    fit_text = ", ".join(f"{n} = {v:.4g} ± {e:.2g}" for n, v, e in
                         zip(result.names, result.estimates, result.std_errors))
    fig.suptitle(f"{fit_text};  $\\chi^2$/dof = {result.chi2_dof:.3g}")
    if path is not None:
        save_figure(fig, path)
    return fig
