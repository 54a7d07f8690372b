"""Figures: the right data on the right axes, labelled in the paper's symbols, saved atomically."""

import os

import numpy as np
import pytest
from matplotlib.figure import Figure

from cosserat_channel import outputs, plot, run_sweep
from cosserat_channel.parameters import PARAMETERS
from cosserat_channel.solver.point import solve_point
from support import assert_legend_lines_show_their_curves, run_python

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def result():
    """Paper figure 2 (eps = 1/30, L = 10, K = 0.5, A = 1/3, N = 1) with a profile."""
    return solve_point(1 / 30, 10, 0.5, 1 / 3, 1, profile=np.linspace(0, 1, 201))


@pytest.fixture(scope="module")
def fig(result):
    """The profiles figure of figure 2, not saved."""
    return plot.point_profiles(result)


def _data_lines(ax):
    """Lines of ``ax`` other than the vertical plug-edge marker."""
    return [ln for ln in ax.get_lines() if not np.allclose(ln.get_xdata(), ln.get_xdata()[0])]


def _axes_with_ylabel(fig, symbol):
    found = [ax for ax in fig.axes if symbol in ax.get_ylabel()]
    assert len(found) == 1, f"{symbol!r} is the y label of {len(found)} axes"
    return found[0]


def test_returns_figure_with_four_panels(fig):
    """A Figure with at least four axes comes back."""
    assert isinstance(fig, Figure)
    assert len(fig.axes) >= 4


@pytest.mark.parametrize(
    "symbol, keys",
    [
        (r"$u/u(0)$", ["u_over_u0"]),
        (r"\hat\omega", ["omega_hat"]),
        (r"\bar\sigma_{xy}", ["sigma_xy", "sigma_yx"]),  # both shear stresses share a panel
        (r"\bar m/\nu", ["m"]),
    ],
)
def test_panel_plots_profile_arrays(fig, result, symbol, keys):
    """Each panel, found by its y label, draws the matching profile arrays against xi."""
    ax = _axes_with_ylabel(fig, symbol)
    lines = _data_lines(ax)
    for key in keys:
        assert any(
            np.allclose(ln.get_xdata(), result.profile["xi"])
            and np.allclose(ln.get_ydata(), result.profile[key])
            for ln in lines
        ), f"no line with profile[{key!r}] on the {symbol} panel"


def test_shear_stress_panel_has_legend_for_both(fig):
    """The two-line stress panel has a legend naming sigma_xy and sigma_yx, each entry drawn as
    its curve (sigma_yx's dash-dot, the plug edge's dashes)."""
    assert assert_legend_lines_show_their_curves(fig) == 2
    ax = _axes_with_ylabel(fig, r"\bar\sigma_{xy}")
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(r"\sigma_{xy}" in t for t in texts)
    assert any(r"\sigma_{yx}" in t for t in texts)


def test_xi_axis_labelled(fig):
    """The bottom panels carry the xi = x/W label."""
    labels = [ax.get_xlabel() for ax in fig.axes]
    assert labels.count(outputs.XI.label) >= 2 and r"$\xi = x/W$" in outputs.XI.label


@pytest.fixture(scope="module")
def sweep():
    """Every output over eps (and the profiles), with a material: a small sweep."""
    return run_sweep({"grid": {"eps": [0.02, 1 / 30, 0.05], "L": 10.0, "K": 0.5,
                               "A": 1 / 3, "N": 1.0},
                      "material": {"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0},
                      "output": {"variables": list(outputs.OUTPUTS), "profile_points": 5}},
                     workers=1, progress=False)


@pytest.mark.parametrize("name", list(outputs.OUTPUTS))
def test_every_output_is_labelled_by_its_own_definition(sweep, name):
    """The y label of an output against eps is its long name, symbol and unit; the x label is
    eps's (both from their definitions: no table of labels beside them)."""
    from cosserat_channel.plot.lines import line_plot

    ax = line_plot(sweep, "eps", name, asymptote=False).axes[0]
    o = outputs.OUTPUTS[name]
    assert ax.get_ylabel() == o.label
    assert o.long_name in ax.get_ylabel() and o.symbol in ax.get_ylabel()
    assert ax.get_xlabel() == PARAMETERS["eps"].label


def test_an_output_registered_at_run_time_reaches_the_figure_label(sweep):
    """Adding one Output is all it takes: the sweep file and the figure both carry its label."""
    from cosserat_channel.plot.lines import line_plot

    new = outputs.Output("Delta_per_L", "1", "thickness per length",
                         lambda x: x.get("Delta") / x.L, plug_edge=True, symbol=r"$\Delta/L$",
                         description="shear-layer thickness over the Cosserat length (test only)")
    with outputs.registered(new):
        ds = run_sweep({"grid": {"eps": [0.02, 1 / 30], "L": 10.0, "K": 0.5, "A": 1 / 3,
                                 "N": 1.0}, "output": {"variables": ["Delta_per_L"]}},
                       workers=1, progress=False)
        assert ds["Delta_per_L"].attrs["long_name"] == "thickness per length"
        ax = line_plot(ds, "eps", "Delta_per_L").axes[0]
        assert ax.get_ylabel() == r"thickness per length $\Delta/L$"
    # Once unregistered, a variable of a file is labelled from the file's own attributes.
    ax = line_plot(ds, "eps", "Delta_per_L").axes[0]
    assert ax.get_ylabel() == "thickness per length"


def test_profile_labels_come_from_the_profiles(sweep):
    """Profiles against xi: y label from outputs.PROFILES, x label from outputs.XI."""
    from cosserat_channel.plot.lines import line_plot

    for name in ("u_over_u0", "omega_hat", "m", "sigma_yx"):
        ax = line_plot(sweep, "xi", name, at={"eps": 0.02}, asymptote=False).axes[0]
        assert ax.get_ylabel() == outputs.PROFILES[name].label
        assert ax.get_xlabel() == outputs.XI.label


def test_plug_edge_line_at_xi_p(fig, result):
    """Every panel has a dashed vertical line at xi_p, and one legend entry names it with Delta."""
    for ax in fig.axes:
        vlines = [
            ln for ln in ax.get_lines()
            if np.allclose(ln.get_xdata(), result.xi_p) and ln.get_linestyle() == "--"
        ]
        assert len(vlines) == 1
    entries = [
        t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()
    ]
    plug = [t for t in entries if r"\xi_p" in t]
    assert len(plug) == 1
    assert "plug edge" in plug[0] and f"{result.Delta:.3g}" in plug[0]


def test_suptitle_names_parameters(fig):
    """The suptitle states eps, L, K, A and N with their values."""
    title = fig.get_suptitle()
    parts = (r"$\varepsilon$ = 0.0333333", "$L$ = 10", "$K$ = 0.5", "$A$ = 0.333333", "$N$ = 1")
    for part in parts:
        assert part in title


def test_parameter_title_omits_missing():
    """parameter_title leaves out parameters passed as None (a sweep axis is not fixed)."""
    title = plot.parameter_title(eps=0.1, K=2.0)
    assert title == r"$\varepsilon$ = 0.1, $K$ = 2"


def test_save_writes_png(result, tmp_path):
    """Given a path, point_profiles writes a PNG there and no temporary file."""
    target = tmp_path / "profiles.png"
    fig = plot.point_profiles(result, target)
    assert isinstance(fig, Figure)
    assert target.read_bytes()[:8] == PNG_SIGNATURE
    assert os.listdir(tmp_path) == ["profiles.png"]


def test_failed_save_leaves_old_file_intact(fig, tmp_path, monkeypatch):
    """A save that fails half-way removes its temporary file and keeps the existing target."""
    target = tmp_path / "keep.png"
    target.write_bytes(b"old")

    def broken_savefig(tmp, **kwargs):
        with open(tmp, "wb") as fh:  # a partial file exists when the failure comes
            fh.write(b"partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(fig, "savefig", broken_savefig)
    with pytest.raises(RuntimeError, match="disk full"):
        plot.save_figure(fig, target)
    assert os.listdir(tmp_path) == ["keep.png"]
    assert target.read_bytes() == b"old"


def test_unknown_suffix_rejected():
    """figure_format refuses a suffix matplotlib cannot write and defaults to PNG without one."""
    assert plot.figure_format("a/b") == "png"
    assert plot.figure_format("a/b.PDF") == "pdf"
    with pytest.raises(ValueError, match="nosuch"):
        plot.figure_format("a/b.nosuch")


def test_result_without_profile_is_refused():
    """A point without solution has no profile: point_profiles says so with its status."""
    r = solve_point(0.4, 10, 0.5, 1 / 3, 1, profile=np.linspace(0, 1, 11))
    with pytest.raises(ValueError, match="eps_too_large_axis"):
        plot.point_profiles(r)


def test_plot_imports_no_solver_module():
    """Figures take data: importing every plot module loads neither numba nor a solver module."""
    code = ("import sys; import cosserat_channel.plot.lines, cosserat_channel.plot.regimes, "
            "cosserat_channel.plot.stability, cosserat_channel.plot.workprecision; "
            "print(sorted(m for m in sys.modules if m == 'numba' or m.startswith(tuple("
            "'cosserat_channel.' + s for s in ('integrate', 'solver', 'regimes', 'atlas', 'measure', "
            "'physics.model', 'physics.reference')))))")
    assert run_python(code) == "[]"
