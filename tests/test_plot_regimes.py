"""Regime maps, phase plane, boundary and line/profile figures from real results; the CLI."""


import numpy as np
import pytest

from cosserat_channel import cli, regimes
from cosserat_channel import status as st
from cosserat_channel.plot import lines as pl
from cosserat_channel.plot import regimes as pr
from cosserat_channel.solver.point import solve_point
from cosserat_channel.sweep import run_sweep


def _legend_texts(fig):
    return [t.get_text() for ax in fig.axes if ax.get_legend()
            for t in ax.get_legend().get_texts()]


@pytest.fixture(scope="module")
def regime_ds():
    """Status over (A, N) at eps = 1/30, L = 10 (all five statuses but integration_failed)."""
    return run_sweep({"grid": {"eps": 1 / 30, "L": 10, "K": 0.5, "A": {"linspace": [-3, 5, 33]},
                               "N": {"linspace": [0.3, 3, 19]}}}, workers=2)


@pytest.fixture(scope="module")
def boundary_ds(regime_ds):
    """The traced edge on a coarse (A, N) grid over the map's range."""
    return regimes.trace_boundary(np.linspace(-0.95, 0.95, 11), np.linspace(0.3, 3, 7))


def test_regime_map_legend_has_each_status_and_boundary(regime_ds, boundary_ds):
    """One legend entry per status present and per boundary line; labels and title."""
    fig = pr.regime_map(regime_ds, "A", "N", boundary=boundary_ds)
    texts = _legend_texts(fig)
    present = {st.Status(int(c)).name for c in np.unique(regime_ds["status"].values)}
    assert present >= {"ok", "wall_inadmissible", "eps_too_large_axis", "eps_too_large_path",
                       "axis_spin_unbounded"}
    for name in present:
        assert texts.count(name) == 1
    assert "integration_failed" not in texts
    for key in ("wall", "axis", "A=-1", "traced"):
        assert pr.BOUNDARY_LABELS[key] in texts
    ax = fig.axes[0]
    assert "$A" in ax.get_xlabel() and "$N" in ax.get_ylabel()
    assert "varepsilon" in ax.get_title() and "L$ = 10" in ax.get_title()
    assert len(ax.collections) >= 5  # the mesh and four boundary contours


def test_regime_map_needs_at_for_varying_dims(regime_ds):
    """A slice with another varying dimension is rejected, naming it."""
    ds = run_sweep({"grid": {"eps": [0.01, 0.02], "L": 10, "K": 0.5, "A": [0.0, 1.0],
                             "N": [1.0, 2.0]}}, workers=1)
    with pytest.raises(ValueError, match="eps"):
        pr.regime_map(ds, "A", "N")
    fig = pr.regime_map(ds, "A", "N", at={"eps": 0.02})
    assert "0.02" in fig.axes[0].get_title()


def test_regime_trace_grid_spans_the_plotted_range(regime_ds):
    """n values over each plotted one of A, N; None when neither is plotted or a side is flat."""
    A, N = pr.regime_trace_grid(regime_ds, "A", "N", n=5)
    assert np.allclose(A, np.linspace(-3, 5, 5)) and np.allclose(N, np.linspace(0.3, 3, 5))
    A, N = pr.regime_trace_grid(regime_ds.isel(N=[0, 4]), "A", "N")
    assert A.size == 12 and N.size == 12 and N[-1] == pytest.approx(regime_ds["N"].values[4])
    assert pr.regime_trace_grid(regime_ds.isel(N=[3]), "A", "N") is None
    with pytest.raises(ValueError, match="different dimensions"):
        pr.regime_trace_grid(regime_ds, "A", "A")


def test_phase_plane_figure_artists():
    """Figure 12: two D = 0 curves, two nullcline halves, four trajectories, a legend entry each."""
    pp = regimes.phase_plane(1 / 30, 10, 1 / 3, 1, n_xi=61, n_m=61)
    fig = pr.phase_plane_figure(pp, nu=0.603)
    ax = fig.axes[0]
    texts = _legend_texts(fig)
    assert "$D = 0$" in texts
    assert any("E_{-} = 0" in t for t in texts)
    for tr in pp.trajectories:
        assert tr.label in texts
    assert sum(1 for t in texts if t.startswith(r"$E_{+}$ from")) == 2
    assert len(ax.get_lines()) >= 2 + 2 + 4
    assert r"\bar m" in ax.get_ylabel() and r"\xi" in ax.get_xlabel()
    assert "0.603" in ax.get_title() and "$A$ = 0.333333" in ax.get_title()


def test_boundary_figure_lines(boundary_ds):
    """One eta_max line per N with a legend entry; log y; labelled axes."""
    fig = pr.boundary_figure(boundary_ds)
    ax = fig.axes[0]
    texts = _legend_texts(fig)
    assert sum("eta_{\\max}$, $N$" in t for t in texts) == boundary_ds.sizes["N"]
    assert ax.get_yscale() == "log" and r"\eta" in ax.get_ylabel() and "$A" in ax.get_xlabel()


@pytest.fixture(scope="module")
def fig7_ds():
    """Figure 7 on a coarse grid, with L as hue."""
    return run_sweep({"grid": {"eps": {"logspace": [-2.7781512503836434, -0.7, 8]},
                               "L": [2, 10], "K": 0.5, "A": 1 / 3, "N": 1.0}}, workers=2)


def test_line_plot_hue_and_asymptote(fig7_ds):
    """Delta against W/d_p: one line per L and the Appendix C circles; log x; labels."""
    fig = pl.line_plot(fig7_ds, "W_over_d_p", "Delta", hue="L")
    ax = fig.axes[0]
    texts = _legend_texts(fig)
    assert "$L$ = 2" in texts and "$L$ = 10" in texts and pl.ASYMPTOTIC_EACH_LABEL in texts
    solid = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    circles = [ln for ln in ax.get_lines() if ln.get_marker() == "o" and len(ln.get_xdata())]
    assert len(solid) == 2 and len(circles) == 2
    line10 = solid[1].get_ydata()
    np.testing.assert_allclose(line10, fig7_ds["Delta"].sel(L=10).squeeze().values)
    assert ax.get_xscale() == "log"
    assert "W/d_p" in ax.get_xlabel() and r"\Delta" in ax.get_ylabel()
    assert "$K$ = 0.5" in ax.get_title() and "$A$" in ax.get_title()


def test_line_plot_rejects_bad_axes(fig7_ds):
    """Unknown variables, profile mix-ups and unfixed dimensions raise ValueError."""
    with pytest.raises(ValueError, match="--y"):
        pl.line_plot(fig7_ds, "eps", "nope")
    with pytest.raises(ValueError, match="L"):
        pl.line_plot(fig7_ds, "eps", "Delta")
    with pytest.raises(ValueError, match="xi"):
        pl.line_plot(fig7_ds, "xi", "Delta", hue="L")


def test_profiles_figure_with_composite():
    """Figure 2: three profiles per panel, composite circles, sigma_xy line, suptitle."""
    xi = np.linspace(0, 1, 51)
    rs = [solve_point(1 / 30, L, 0.5, 1 / 3, 1, profile=xi) for L in (2, 10, 20)]
    fig = pl.profiles_figure(rs)
    ax_u, ax_w, ax_s, ax_m = fig.axes[:4]
    assert len([ln for ln in ax_u.get_lines() if ln.get_linestyle() == "-"]) == 3
    assert len([ln for ln in ax_m.get_lines() if ln.get_marker() == "o"]) == 3
    texts = _legend_texts(fig)
    assert {"$L$ = 2", "$L$ = 10", "$L$ = 20", pl.ASYMPTOTIC_EACH_LABEL} <= set(texts)
    assert any("sigma_{xy}" in t for t in texts)
    assert "u/u(0)" in ax_u.get_ylabel() and r"\bar m" in ax_m.get_ylabel()
    assert "L" not in fig._suptitle.get_text().split(":")[1].replace("Lambda", "")
    # Composite agrees with the numerical m within a few percent at eps = 1/30, L = 10.
    circ = [ln for ln in ax_m.get_lines() if ln.get_marker() == "o"][1]
    np.testing.assert_allclose(circ.get_ydata(), np.interp(circ.get_xdata(), xi, rs[1].profile["m"]),
                               atol=0.1 * 10)


def test_line_plot_profiles_from_sweep():
    """--x xi: profiles of a sweep with profile_points, one line per eps, composite overlaid."""
    ds = run_sweep({"grid": {"eps": [1 / 30, 1 / 600], "L": 10, "K": 0.5, "A": 1 / 3, "N": 1.0},
                    "output": {"profile_points": 41}}, workers=1)
    fig = pl.line_plot(ds, "xi", "m", hue="eps")
    ax = fig.axes[0]
    assert len([ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]) == 2
    assert pl.ASYMPTOTIC_EACH_LABEL in _legend_texts(fig)


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def _main(argv, capsys):
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_phase_plane(tmp_path, capsys):
    """phase-plane writes a PNG and reports the four trajectories."""
    out = tmp_path / "pp.png"
    code, text, err = _main(["phase-plane", "--eps", "0.0333333333333", "--L", "10", "--A",
                             "0.3333333333333", "--N", "1", "--nu", "0.603", "-o", str(out)], capsys)
    assert code == 0, err
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "E+ from m(0) = -10: D=0" in text and "E- from m(0) = -10: wall" in text


@pytest.mark.parametrize("argv", [
    ["phase-plane", "--eps", "2", "--L", "10", "--A", "0.3", "--N", "1", "-o", "{tmp}/x.png"],
    ["phase-plane", "--eps", "0.1", "--L", "10", "--A", "0.3", "--N", "1", "-o", "{tmp}/x.xyz"],
    ["boundary", "--A", "a,b", "--N", "1", "-o", "{tmp}/b.nc"],
    ["boundary", "--A", "0", "--N=-1", "-o", "{tmp}/b.nc"],
    ["boundary", "--A", "0", "--N", "1", "--eta-range", "5:1", "-o", "{tmp}/b.nc"],
    ["plot", "{tmp}/missing.nc", "--x", "A", "--y", "N", "--regime", "-o", "{tmp}/m.png"],
    ["plot", "{tmp}/r.nc", "--x", "A", "--y", "N", "--at", "eps", "-o", "{tmp}/m.png"],
])
def test_cli_rejects_bad_input(argv, tmp_path, capsys):
    """Bad input: exit 2, one line on stderr, no file written."""
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code, _, err = _main(argv, capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("cosserat-channel: error:")
    assert not any(p.suffix in (".png", ".nc") for p in tmp_path.iterdir())


def test_cli_boundary_and_plots(tmp_path, capsys, regime_ds):
    """boundary writes NetCDF and a figure; plot --regime and plot --x/--y/--hue write PNGs."""
    b = tmp_path / "b.nc"
    code, text, err = _main(["boundary", "--A=0.3333333333333333,2", "--N", "1", "-o", str(b),
                             "--plot", str(tmp_path / "b.png")], capsys)
    assert code == 0, err
    assert "3.3088" in text and "unbounded_in_range" in text
    import xarray as xr

    with xr.open_dataset(b) as ds:
        assert 3.30 < float(ds["eta_max"].sel(A=1 / 3, N=1.0, method="nearest")) < 3.35
    assert (tmp_path / "b.png").stat().st_size > 0
    res = tmp_path / "r.nc"
    regime_ds.to_netcdf(res)
    code, _, err = _main(["plot", str(res), "--regime", "--x", "A", "--y", "N", "--boundary", str(b),
                          "-o", str(tmp_path / "map.png")], capsys)
    assert code == 0, err
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"
    code, _, err = _main(["plot", str(res), "--x", "A", "--y", "Delta", "--hue", "N",
                          "-o", str(tmp_path / "d.png")], capsys)
    assert code == 0, err
    code, _, err = _main(["plot", str(res), "--x", "A", "--y", "Delta", "-o",
                          str(tmp_path / "e.png")], capsys)
    assert code == 2 and "--at" in err
