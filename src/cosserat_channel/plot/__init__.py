"""Every figure of the project: the only module that imports matplotlib.

Figures are built as :class:`Figure` objects (a :class:`matplotlib.figure.Figure`) on an Agg
canvas instead of through ``pyplot``: no global figure registry to leak memory in long sweeps, no
interactive backend picked up from the environment, and nothing to close afterwards. Files are
written atomically (:func:`save_figure`), so an interrupted run never leaves a truncated image
behind. In Jupyter a figure shows itself as a PNG (``display(fig)``, or a cell's last value),
although pyplot, which registers that display for its own figures, is never imported.

Layer: beside the results reader, below the paper's figures, the measurements and the command
line. May import matplotlib, numpy, xarray and the vocabulary modules (outputs, parameters,
status, regime_codes, files, and the closed forms of physics.analytic and physics.asymptotics); it
takes data and never solves: never the solver, the sweeps, the regimes or the atlas.
"""

from __future__ import annotations

import io
import math
import os

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure as _MplFigure

from .. import outputs
from ..files import atomic_output
from ..parameters import DIMS, PARAMETERS

DPI = 120
FIGSIZE = (10.0, 7.0)
# The length of a legend's line handles, in font sizes, where a figure draws dashed or dash-dot
# lines: at matplotlib's 2.0 a dash-dot line 2 points wide shows one solid dash in its legend
# entry (its pattern scales with the width), so the entry would not match its curve.
HANDLE_LENGTH = 4.5

# Axis labels of what is neither an output, a profile nor a parameter (those carry their own:
# :func:`axis_label`).
EXTRA_LABELS = {"W_over_d_p": r"channel half-width $W/d_p$"}


class Figure(_MplFigure):
    """A matplotlib Figure that Jupyter (IPython's display) renders as a PNG image.

    IPython shows a figure as an image only through a formatter that pyplot's inline backend
    registers; this package never imports pyplot, so without ``_repr_png_`` a notebook cell
    would print ``<Figure size 1000x700 with 4 Axes>`` instead of the figure.
    """

    def _repr_png_(self) -> bytes:
        buf = io.BytesIO()
        self.savefig(buf, format="png", dpi=DPI)
        return buf.getvalue()


# ---------------------------------------------------------------------------------------------
# Small reusable helpers
# ---------------------------------------------------------------------------------------------
def new_figure(figsize=FIGSIZE) -> Figure:
    """A constrained-layout figure attached to an Agg canvas (no pyplot state)."""
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def axis_label(name: str, da=None) -> str:
    """The axis label of variable ``name``: the ``label`` of its definition
    (:func:`cosserat_channel.outputs.definition`: long name, symbol, unit), so an output
    registered at run time is labelled like the rest.

    A name with no definition takes the ``long_name`` and ``units`` attributes of ``da`` (a
    DataArray) when given, else the name itself.
    """
    q = outputs.definition(name)
    if q is not None:
        return q.label
    if name in EXTRA_LABELS:
        return EXTRA_LABELS[name]
    attrs = getattr(da, "attrs", {})
    if "long_name" in attrs:
        units = attrs.get("units", "1")
        return attrs["long_name"] + ("" if units == "1" else f" ({units})")
    return name


def parameter_title(eps=None, L=None, K=None, A=None, N=None) -> str:
    """``"ε = …, L = …, K = …, A = …, N = …"`` in mathtext, leaving out parameters given as None.

    Parameters are in the project's order (eps, L, K, A, N); a figure over one axis of a sweep
    passes only the fixed ones.
    """
    values = (eps, L, K, A, N)
    parts = [f"{PARAMETERS[d].symbol} = {v:.6g}" for d, v in zip(DIMS, values) if v is not None]
    return ", ".join(parts)


def shear_stress_label() -> str:
    """The label of a panel with both shear stresses, from their two profile definitions."""
    xy, yx = outputs.PROFILES["sigma_xy"], outputs.PROFILES["sigma_yx"]
    return f"shear stresses {xy.symbol}, {yx.symbol} ({yx.unit_label})"


def figure_format(path) -> str:
    """The file format matplotlib will write for ``path``, from its suffix (PNG if none).

    Raises
    ------
    ValueError
        If the suffix names a format the Agg canvas cannot write.
    """
    suffix = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
    if not suffix:
        return "png"
    supported = FigureCanvasAgg.get_supported_filetypes()
    if suffix not in supported:
        raise ValueError(
            f"cannot write a figure to {os.fspath(path)!r}: unknown file type '.{suffix}' "
            f"(use one of {', '.join('.' + s for s in sorted(supported))})"
        )
    return suffix


def save_figure(fig: Figure, path, *, dpi: int = DPI, replace: bool = True) -> None:
    """Write ``fig`` to ``path`` atomically (:func:`cosserat_channel.files.atomic_output`): an
    existing file at ``path`` is replaced only by a complete one, and only with ``replace``
    (without it a file that appeared meanwhile is kept: ``OutputAppeared``)."""
    path = os.fspath(path)
    fmt = figure_format(path)
    atomic_output(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi), replace=replace)


# ---------------------------------------------------------------------------------------------
# Figures
# ---------------------------------------------------------------------------------------------
def _dimensional_axis(ax, scale: float, label: str):
    """A right-hand y axis showing the panel's scaled values times ``scale`` (e.g. in Pa)."""
    if not (math.isfinite(scale) and scale > 0.0):
        return None
    sec = ax.secondary_yaxis("right", functions=(lambda v: v * scale, lambda v: v / scale))
    sec.set_ylabel(label)
    return sec


def point_profiles(result, path=None) -> Figure:
    """Profiles of one solved point against ``xi``: velocity, spin, shear stresses, couple stress.

    Parameters
    ----------
    result : PointResult
        From :func:`cosserat_channel.solver.point.solve_point` with ``profile=`` given and status ok.
    path : str or path-like, optional
        Where to save the figure (format from the suffix, PNG at 120 dpi by default).

    Returns
    -------
    matplotlib.figure.Figure
        Four panels: ``u/u(0)``, ``omega_hat``, ``sigma_xy`` with ``sigma_yx``, and ``m``; the
        plug edge ``xi_p`` (eq:13) is a dashed vertical line on each. With a material (``nu``
        finite) the title gives ``nu`` and the stress and couple-stress panels get a right-hand
        axis in Pa and Pa m (scaled by ``rho_p g W nu``, from the result's wall values).

    Raises
    ------
    ValueError
        If the result has no profile (a point without solution, or solved without ``profile=``).
    """
    prof = result.profile
    if prof is None:
        if result.ok:
            raise ValueError("result has no profile: solve it with profile=xi")
        raise ValueError(
            f"no profile to plot: status {result.status.name} ({result.status.message})"
        )
    xi = prof["xi"]
    fig = new_figure()
    axes = fig.subplots(2, 2, sharex=True)
    ax_u, ax_w, ax_s, ax_m = axes.flat

    profiles = outputs.PROFILES
    ax_u.plot(xi, prof["u_over_u0"], color="C0")
    ax_u.set_ylabel(axis_label("u_over_u0"))
    ax_w.plot(xi, prof["omega_hat"], color="C1")
    ax_w.set_ylabel(axis_label("omega_hat"))
    ax_s.plot(xi, prof["sigma_xy"], color="C2", label=profiles["sigma_xy"].symbol)
    ax_s.plot(xi, prof["sigma_yx"], color="C3", ls="-.", label=profiles["sigma_yx"].symbol)
    ax_s.set_ylabel(shear_stress_label())
    ax_m.plot(xi, prof["m"], color="C4")
    ax_m.set_ylabel(axis_label("m"))

    plug_label = rf"plug edge $\xi_p$ ($\Delta$ = {result.Delta:.3g} $d_p$)"
    for i, ax in enumerate(axes.flat):
        # Labelled once: the same line on every panel needs only one legend entry.
        ax.axvline(result.xi_p, color="0.4", ls="--", lw=1.0, label=plug_label if i == 0 else None)
        ax.set_xlim(0.0, 1.0)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(axis_label("xi"))
    ax_u.legend(loc="best", handlelength=HANDLE_LENGTH)
    ax_s.legend(loc="best", handlelength=HANDLE_LENGTH)
    title = parameter_title(result.eps, result.L, result.K, result.A, result.N)
    nu = float(getattr(result, "nu", math.nan))
    if math.isfinite(nu):
        title += rf", $\nu$ = {nu:.4g}"
        _dimensional_axis(ax_s, -result.sigma_xy_wall_Pa, "stress (Pa)")
        if result.m_wall != 0.0:
            _dimensional_axis(ax_m, result.m_wall_Pa_m / result.m_wall, "couple stress (Pa m)")
    fig.suptitle(title)
    if path is not None:
        save_figure(fig, path)
    return fig
