"""Line and profile figures of the paper: Delta against a parameter (figures 7-9) and profiles of
u/u(0), omega_hat, sigma_xy, sigma_yx and m (figures 2-6, 10, 11), with the Appendix C
asymptotics overlaid as open circles wherever they apply (N = 1).
"""

from __future__ import annotations

import numpy as np

from matplotlib import colormaps

from .. import outputs
from ..parameters import PARAMETERS
from ..physics import asymptotics
from . import HANDLE_LENGTH, axis_label, new_figure, parameter_title, save_figure, shear_stress_label
from .regimes import DIMS, select_slice

# The profiles a sweep writes (sigma_xy = -xi is solve_point's alone).
PROFILE_VARIABLES = ("u_over_u0", "omega_hat", "m", "sigma_yx")
ASYMPTOTIC_LABEL = r"asymptotic, $N = 1$ (Appendix C)"
# With several lines, one legend entry stands for the circles of every line: drawn in a neutral
# colour and saying that each line's circles share its colour (not the first line's alone).
ASYMPTOTIC_EACH_LABEL = r"asymptotic, $N = 1$ (Appendix C): circles in each line's colour"
ASYMPTOTIC_PROXY = dict(ls="none", marker="o", mfc="none", color="0.35", ms=6)
N_MARKERS = 25
MAX_LEGEND_HUES = 12


def line_plot(ds, x, y="Delta", hue=None, at=None, *, asymptote=True, path=None):
    """``y`` against the coordinate ``x`` of a sweep, one line per value of ``hue``.

    ``x`` is a dimension (``eps``, ``L``, ``K``, ``A``, ``N``), ``W_over_d_p`` (``1/eps``, the
    abscissa of figure 7) or ``xi`` for the profile variables of a sweep with ``profile_points``
    (``u_over_u0``, ``omega_hat``, ``m``, ``sigma_yx``). With ``asymptote`` and ``N = 1``, the
    Appendix C values are overlaid as open circles: ``Delta`` from
    :func:`asymptotics.Delta_asymptotic` (the limit, independent of K) and the profiles from
    :func:`asymptotics.composite`.
    """
    xdim = "eps" if x == "W_over_d_p" else x
    if xdim not in DIMS + ("xi",):
        raise ValueError(f"--x must be one of {', '.join(DIMS + ('W_over_d_p', 'xi'))}; got {x!r}")
    if y not in ds.data_vars or y == "status":
        names = ", ".join(v for v in ds.data_vars if v != "status")
        raise ValueError(f"--y must be a variable of the result ({names}); got {y!r}")
    if (xdim == "xi") != ("xi" in ds[y].dims):
        raise ValueError(f"--x xi goes with the profile variables ({', '.join(PROFILE_VARIABLES)})"
                         f"; {y!r} with --x {x!r} does not")
    if hue is not None and (hue not in DIMS or hue == xdim):
        raise ValueError(f"--hue must be a dimension other than --x; got {hue!r}")
    keep = (xdim,) + ((hue,) if hue else ())
    sub, fixed = select_slice(ds, keep, at)
    hues = sub[hue].values if hue else [None]
    fig = new_figure()
    ax = fig.subplots()
    fig_cmap = colormaps["viridis"]
    drawn_asym = False
    for k, hv in enumerate(hues):
        line = sub.sel({hue: hv}) if hue else sub
        p = dict(fixed)
        if hue:
            p[hue] = float(hv)
        xs = line[xdim].values.astype(float)
        ys = line[y].values.astype(float).reshape(-1)
        xplot = 1.0 / xs if x == "W_over_d_p" else xs
        color = f"C{k % 10}"
        label = f"{PARAMETERS[hue].symbol} = {float(hv):.4g}" if hue else "numerical"
        if len(hues) > MAX_LEGEND_HUES and 0 < k < len(hues) - 1:
            label = None  # a long hue axis: the legend names its first and last line only
        if len(hues) > 10:
            color = fig_cmap(k / max(1, len(hues) - 1))
        ax.plot(xplot, ys, "-", color=color, lw=2, label=label)
        if not asymptote:
            continue
        pts = {d: (xs if d == xdim else np.full(xs.shape, p.get(d, np.nan))) for d in DIMS}
        if xdim == "xi":
            pts = {d: np.full(xs.shape, p[d]) for d in DIMS}
        if not np.all(pts["N"] == 1.0):
            continue
        idx = np.unique(np.linspace(0, xs.size - 1, min(N_MARKERS, xs.size)).round().astype(int))
        if y == "Delta" and xdim != "xi":
            asym = np.array([asymptotics.Delta_asymptotic(pts["eps"][i], pts["L"][i]) for i in idx])
        elif xdim == "xi" and y in PROFILE_VARIABLES:
            asym = asymptotics.composite_profile(y, xs[idx], p["eps"], p["L"], p["K"])
        else:
            continue
        ax.plot(xplot[idx], asym, "o", mfc="none", color=color, ms=6,
                label=None if drawn_asym or len(hues) > 1 else ASYMPTOTIC_LABEL)
        drawn_asym = True
    if drawn_asym and len(hues) > 1:
        ax.plot([], [], label=ASYMPTOTIC_EACH_LABEL, **ASYMPTOTIC_PROXY)
    if x in ("eps", "W_over_d_p") and xs.size > 1 and xs.max() / xs.min() > 20:
        ax.set_xscale("log")
    if x == "K" and xs.size > 1 and xs.min() > 0 and xs.max() / xs.min() > 100:
        ax.set_xscale("log")
    ax.set_xlabel(axis_label(x))
    ax.set_ylabel(axis_label(y, ds[y]))
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    ax.set_title(parameter_title(**{d: fixed.get(d) for d in DIMS}))
    if path is not None:
        save_figure(fig, path)
    return fig


def profiles_figure(results, *, asymptotic=True, path=None):
    """Profiles of several solved points: ``u/u(0)``, ``omega_hat``, ``sigma_xy`` and ``sigma_yx``,
    ``m`` against ``xi`` (figures 2-6, 10, 11), one colour per point, the composite of Appendix C
    as open circles for points with ``N = 1``.

    Parameters
    ----------
    results : sequence of PointResult
        Solved with ``profile=xi`` (status ok).
    """
    results = list(results)
    if not results:
        raise ValueError("no results to plot")
    for r in results:
        if r.profile is None:
            raise ValueError(f"a result has no profile (status {r.status.name}): solve it with "
                             "profile=xi and check its status")
    varying = [d for d in DIMS if len({getattr(r, d) for r in results}) > 1]
    fixed = {d: getattr(results[0], d) for d in DIMS if d not in varying}
    fig = new_figure()
    axes = fig.subplots(2, 2, sharex=True)
    ax_u, ax_w, ax_s, ax_m = axes.flat
    drawn_asym = False
    for k, r in enumerate(results):
        pr = r.profile
        xi = pr["xi"]
        color = f"C{k % 10}"
        label = ", ".join(f"{PARAMETERS[d].symbol} = {getattr(r, d):.4g}" for d in varying) or "numerical"
        ax_u.plot(xi, pr["u_over_u0"], color=color, lw=2, label=label)
        ax_w.plot(xi, pr["omega_hat"], color=color, lw=2)
        ax_s.plot(xi, pr["sigma_yx"], color=color, lw=2, ls="-.",
                  label=outputs.PROFILES["sigma_yx"].symbol if len(results) == 1 else None)
        ax_m.plot(xi, pr["m"], color=color, lw=2)
        if asymptotic and r.N == 1.0:
            sel = np.unique(np.linspace(0, xi.size - 1, min(N_MARKERS, xi.size)).round().astype(int))
            c = {v: asymptotics.composite_profile(v, xi[sel], r.eps, r.L, r.K)
                 for v in ("u_over_u0", "omega_hat", "sigma_yx", "m")}
            kw = dict(ls="none", marker="o", mfc="none", color=color, ms=6)
            one = len(results) == 1
            ax_u.plot(xi[sel], c["u_over_u0"], label=ASYMPTOTIC_LABEL if one else None, **kw)
            ax_w.plot(xi[sel], c["omega_hat"], **kw)
            ax_s.plot(xi[sel], c["sigma_yx"], **kw)
            ax_m.plot(xi[sel], c["m"], **kw)
            drawn_asym = True
    if drawn_asym and len(results) > 1:
        ax_u.plot([], [], label=ASYMPTOTIC_EACH_LABEL, **ASYMPTOTIC_PROXY)
    ax_s.plot(results[0].profile["xi"], results[0].profile["sigma_xy"], color="k", lw=1.5,
              label=outputs.PROFILES["sigma_xy"].symbol + r" $= -\xi$")
    if len(results) > 1:  # one entry for the dash-dot curves of every colour
        ax_s.plot([], [], color="0.4", ls="-.", lw=2,
                  label=outputs.PROFILES["sigma_yx"].symbol + " (each point's colour)")
    ax_u.set_ylabel(axis_label("u_over_u0"))
    ax_w.set_ylabel(axis_label("omega_hat"))
    ax_s.set_ylabel(shear_stress_label())
    ax_m.set_ylabel(axis_label("m"))
    for ax in axes.flat:
        ax.set_xlim(0.0, 1.0)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(axis_label("xi"))
    ax_u.legend(loc="lower left", fontsize="small", handlelength=HANDLE_LENGTH)
    ax_s.legend(loc="lower left", fontsize="small", handlelength=HANDLE_LENGTH)
    fig.suptitle("Profiles: " + parameter_title(**{d: fixed.get(d) for d in DIMS}))
    if path is not None:
        save_figure(fig, path)
    return fig
