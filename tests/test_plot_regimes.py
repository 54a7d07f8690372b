"""Regime maps, phase plane, boundary and line/profile figures from real results; the CLI."""


import numpy as np
import pytest

from cosserat_channel import cli, regimes
from cosserat_channel import status as st
from cosserat_channel.plot import lines as pl
from cosserat_channel.plot import regimes as pr
from cosserat_channel.solver.point import solve_point
from cosserat_channel.sweep import run_sweep
from support import assert_legend_lines_show_their_curves


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
    """One legend entry per status present and per boundary line (each dashed or dotted one
    showing its pattern); labels and title."""
    fig = pr.regime_map(regime_ds, "A", "N", boundary=boundary_ds)
    assert assert_legend_lines_show_their_curves(fig) >= 2
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
    # The E+ trajectories are dash-dot, the E- dotted, the nullcline dashed: so are their entries.
    drawn = sum(tr.xi.size > 1 for tr in pp.trajectories)
    assert drawn >= 3 and assert_legend_lines_show_their_curves(fig) == 1 + drawn


def test_boundary_figure_lines(boundary_ds):
    """One eta_max line per N with a legend entry; log y; labelled axes."""
    fig = pr.boundary_figure(boundary_ds)
    ax = fig.axes[0]
    texts = _legend_texts(fig)
    assert sum("eta_{\\max}$, $N$" in t for t in texts) == boundary_ds.sizes["N"]
    assert ax.get_yscale() == "log" and r"\eta" in ax.get_ylabel() and "$A" in ax.get_xlabel()


def _meshes(ax):
    from matplotlib.collections import QuadMesh

    return [c for c in ax.collections if isinstance(c, QuadMesh)]


def test_regime_map_cells_end_on_the_computed_range(regime_ds):
    """No cell reaches past the first or last grid value, each grid point lies in its own cell,
    and the wall cells are exactly the points below A = 1 - 2N^2 (the line runs between them)."""
    fig = pr.regime_map(regime_ds, "A", "N")
    ax = fig.axes[0]
    (mesh,) = _meshes(ax)
    A, N = regime_ds["A"].values, regime_ds["N"].values
    xy = mesh.get_coordinates()
    assert xy.shape == (N.size + 1, A.size + 1, 2)
    assert (xy[..., 0].min(), xy[..., 0].max()) == (A.min(), A.max())
    assert (xy[..., 1].min(), xy[..., 1].max()) == (N.min(), N.max())
    assert ax.get_xlim() == (A.min(), A.max()) and ax.get_ylim() == (N.min(), N.max())
    assert np.all((xy[0, :-1, 0] <= A) & (A <= xy[0, 1:, 0]))
    assert np.all((xy[:-1, 0, 1] <= N) & (N <= xy[1:, 0, 1]))
    for cs in ax.collections:  # every line drawn stays inside the grid's extent
        if hasattr(cs, "allsegs"):
            for seg in (s for level in cs.allsegs for s in level):
                assert np.all((seg[:, 0] >= A.min()) & (seg[:, 0] <= A.max()))
                assert np.all((seg[:, 1] >= N.min()) & (seg[:, 1] <= N.max()))
    cells = np.asarray(mesh.get_array()).reshape(N.size, A.size)
    AA, NN = np.meshgrid(A, N)
    margin = AA - (1.0 - 2.0 * NN**2)
    clear = np.abs(margin) > 1e-9  # a point on the line could go either way in rounding
    assert clear.sum() > 0.9 * clear.size and (margin < 0).sum() > 10
    np.testing.assert_array_equal((cells == st.Status.wall_inadmissible.value)[clear],
                                  (margin < 0)[clear])


def test_regime_map_marks_the_points_of_a_coarse_grid(regime_ds):
    """A coarse map marks every computed point (each cell's colour is the status there); a
    fine one does not."""
    coarse = regime_ds.isel(A=slice(None, None, 4), N=slice(None, None, 3))
    ax = pr.regime_map(coarse, "A", "N").axes[0]
    dots = [ln for ln in ax.get_lines() if ln.get_marker() == "."]
    assert len(dots) == 1 and dots[0].get_label() in _legend_texts(ax.figure)
    AA, NN = np.meshgrid(coarse["A"].values, coarse["N"].values)
    assert sorted(zip(dots[0].get_xdata(), dots[0].get_ydata())) == sorted(zip(AA.ravel(),
                                                                              NN.ravel()))
    assert regime_ds.sizes["A"] * regime_ds.sizes["N"] > pr.MAP_NODES_SHOWN
    fine = pr.regime_map(regime_ds, "A", "N").axes[0]
    assert not [ln for ln in fine.get_lines() if ln.get_marker() == "."]


def _panel_norms(fig):
    """The norm of each panel's eta mesh (None for a panel without finite eta)."""
    out = []
    for ax in fig.axes[:2]:
        shaded = [m for m in _meshes(ax) if m.get_cmap().name == "viridis"]
        out.append(shaded[0].norm if shaded else None)
    return out


def _shown(bds):
    """eta_max where bounded and eta_min where above the search range, as the panels show them."""
    from cosserat_channel import regime_codes as rc

    kind = bds["edge_kind"].values
    lo = bds.attrs["eta_search_min"]
    em = np.where(kind == rc.EDGE_BOUNDED, bds["eta_max"].values, np.nan)
    en = bds["eta_min"].values
    return em, np.where((kind != rc.EDGE_NONE) & (en > lo), en, np.nan)


def test_solvable_region_colour_scale_fits_each_panel(boundary_ds):
    """Each panel's colour limits are its own data's extremes, inside the search range, log
    only where the data span more than a decade; one colourbar per shaded panel."""
    from matplotlib.colors import LogNorm

    for bds in (boundary_ds, boundary_ds.isel(A=[4, 5], N=[2, 3])):
        fig = pr.solvable_region_figure(bds)
        norms = _panel_norms(fig)
        for norm, shown in zip(norms, _shown(bds)):
            if not np.isfinite(shown).any():
                assert norm is None
                continue
            assert (norm.vmin, norm.vmax) == (np.nanmin(shown), np.nanmax(shown))
            assert bds.attrs["eta_search_min"] < norm.vmin <= norm.vmax
            assert norm.vmax < bds.attrs["eta_search_max"]
            assert isinstance(norm, LogNorm) == (norm.vmax > pr.LOG_SCALE_RATIO * norm.vmin)
        assert len(fig.axes) == 2 + sum(n is not None for n in norms)
    wide, narrow = (_panel_norms(pr.solvable_region_figure(b))[0]
                    for b in (boundary_ds, boundary_ds.isel(A=[4, 5], N=[2, 3])))
    assert isinstance(wide, LogNorm) and not isinstance(narrow, LogNorm)  # both kinds seen


def test_solvable_region_one_legend_of_what_is_drawn(boundary_ds):
    """One figure legend, no label twice, no line that misses the box, inside the saved image."""
    fig = pr.solvable_region_figure(boundary_ds)  # A in [-0.95, 0.95], N in [0.3, 3]
    assert not any(ax.get_legend() for ax in fig.axes) and len(fig.legends) == 1
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert len(texts) == len(set(texts))
    assert pr.BOUNDARY_LABELS["wall"] in texts and pr.BOUNDARY_LABELS["switch"] in texts
    assert pr.BOUNDARY_LABELS["A=-1"] not in texts and not any("$A = 1$" in t for t in texts)
    drawn = {ln.get_label() for ax in fig.axes[:2] for ln in ax.get_lines()}
    assert pr.BOUNDARY_LABELS["A=-1"] not in drawn
    fig.canvas.draw()
    box = fig.legends[0].get_window_extent(fig.canvas.get_renderer())
    assert box.x0 >= 0 and box.y0 >= 0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1
    for ax in fig.axes[:2]:
        assert not box.overlaps(ax.get_window_extent())
    # N <= 0.75: the node/focus switch (1 <= N <= 2) is outside the box, so neither drawn nor listed
    low = pr.solvable_region_figure(boundary_ds.isel(N=[0, 1]))
    texts = [t.get_text() for t in low.legends[0].get_texts()]
    assert pr.BOUNDARY_LABELS["switch"] not in texts and pr.BOUNDARY_LABELS["wall"] in texts
    assert pr.BOUNDARY_LABELS["switch"] not in {ln.get_label() for ln in low.axes[0].get_lines()}


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
    assert assert_legend_lines_show_their_curves(fig) == 1  # sigma_yx, dash-dot in every colour
    one = pl.profiles_figure(rs[1:2])
    assert assert_legend_lines_show_their_curves(one) == 1  # sigma_yx: the curve itself
    leg = one.axes[2].get_legend()
    yx = [h for h, t in zip(leg.legend_handles, leg.get_texts()) if "sigma_{yx}" in t.get_text()]
    assert [h.get_color() for h in yx] == ["C0"]  # the one point's colour, not a grey proxy
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


def test_solvable_region_marks_an_error_above_the_tolerance(boundary_ds):
    """Where the data state an error above their tolerance (an atlas's envelope cell) the figure
    dots the area and its legend states the largest error; at or below it nothing is added."""
    bds = boundary_ds.copy()
    err = np.where(np.isfinite(bds["eta_max"].values), 1e-8, np.nan)
    bds["eta_error"] = (("A", "N"), err)
    bds.attrs["atlas_tol"] = 1e-8

    def dotted(fig):
        texts = [t.get_text() for t in fig.legends[0].get_texts()]
        return [t for t in texts if "above the atlas's tolerance" in t]

    assert dotted(pr.solvable_region_figure(bds)) == []
    err[2, 3] = 0.37
    bds["eta_error"] = (("A", "N"), err)
    fig = pr.solvable_region_figure(bds)
    assert len(dotted(fig)) == 1 and "0.37" in dotted(fig)[0]
    hatches = [h for c in fig.axes[0].collections
               for h in (getattr(c, "hatches", None) or [c.get_hatch()])]
    assert "...." in hatches
