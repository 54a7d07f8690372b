"""What a reader of each figure needs, checked on its artists.

Legend entries that say what they stand for, lines that stay visible where they coincide,
legends that cover no data, the same counts in both panels, and units a user can use.
"""

import math

import numpy as np
from matplotlib.colors import to_rgba

from cosserat_channel import plot, regimes
from cosserat_channel.plot import lines as pl
from cosserat_channel.plot import regimes as pr
from cosserat_channel.plot import stability as ps
from cosserat_channel.plot import workprecision as pw
from cosserat_channel.solver.point import solve_point
from cosserat_channel.measure.stability import Report
from cosserat_channel.sweep import run_sweep
from cosserat_channel.measure.report import Comparison, Curve


def _legend(ax):
    leg = ax.get_legend()
    return leg, [t.get_text() for t in leg.get_texts()]


def _renderer(fig):
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _legend_outside_axes(ax):
    """The legend's box does not overlap the axes' box (so it covers no curve)."""
    r = _renderer(ax.figure)
    return not ax.get_legend().get_window_extent(r).overlaps(ax.get_window_extent(r))


def test_delta_plot_one_asymptote_entry_that_speaks_for_every_line():
    """With one line per L, the single circle entry is neutral (no line's colour) and says the
    circles take each line's colour; with one line it is the plain label."""
    ds = run_sweep({"grid": {"eps": {"logspace": [-3, -1, 6]}, "L": [2.0, 10.0, 20.0], "K": 0.5,
                             "A": 1 / 3, "N": 1.0}}, workers=1)
    fig = pl.line_plot(ds, "eps", "Delta", hue="L")
    ax = fig.axes[0]
    leg, texts = _legend(ax)
    assert texts == ["$L$ = 2", "$L$ = 10", "$L$ = 20", pl.ASYMPTOTIC_EACH_LABEL]
    lines = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    circles = [ln for ln in ax.get_lines() if ln.get_marker() == "o" and len(ln.get_xdata())]
    assert len(circles) == 3
    for line, circ in zip(lines, circles):  # each line's circles in its colour
        assert to_rgba(circ.get_color()) == to_rgba(line.get_color())
    proxy = leg.legend_handles[-1]
    assert to_rgba(proxy.get_color()) not in {to_rgba(ln.get_color()) for ln in lines}
    single = pl.line_plot(ds, "eps", "Delta", at={"L": 10.0})
    assert _legend(single.axes[0])[1] == ["numerical", pl.ASYMPTOTIC_LABEL]


def test_regime_map_traced_edge_stays_visible_under_the_analytic_lines():
    """The traced edge is an opaque line twice as wide as the axis-condition line and drawn
    below it: where the two coincide both show, and its colour does not mix with the region's
    beneath. Both are in the legend."""
    ds = run_sweep({"grid": {"eps": 1 / 30, "L": 10, "K": 0.5, "A": {"linspace": [-0.95, 0.9, 12]},
                             "N": {"linspace": [0.6, 3, 8]}}}, workers=2)
    bds = regimes.trace_boundary(np.linspace(-0.95, 0.9, 6), np.linspace(0.6, 3, 4), n_coarse=16)
    fig = pr.regime_map(ds, "A", "N", boundary=bds)
    ax = fig.axes[0]
    _, texts = _legend(ax)
    assert pr.BOUNDARY_LABELS["traced"] in texts and pr.BOUNDARY_LABELS["axis"] in texts
    by_colour = {}
    for cs in ax.collections:
        if hasattr(cs, "levels"):
            by_colour[to_rgba(cs.get_edgecolor()[0], 1.0)] = cs
    traced = by_colour[to_rgba(pr.BOUNDARY_STYLES["traced"]["color"])]
    axis = by_colour[to_rgba(pr.BOUNDARY_STYLES["axis"]["color"])]
    assert traced.get_zorder() < axis.get_zorder()
    assert traced.get_linewidth()[0] >= 2 * axis.get_linewidth()[0]
    assert traced.get_alpha() in (None, 1.0)
    assert any(len(seg) for seg in traced.allsegs[0])  # drawn in this slice


def test_phase_plane_legend_below_and_title_cites_the_equation_labels():
    """The legend sits below the plane (not beside it) and the title cites eq:a1/eq:a2."""
    pp = regimes.phase_plane(1 / 30, 10, 1 / 3, 1, n_xi=41, n_m=41)
    fig = pr.phase_plane_figure(pp)
    ax = fig.axes[0]
    r = _renderer(fig)
    leg = ax.get_legend().get_window_extent(r)
    box = ax.get_window_extent(r)
    assert leg.y1 <= box.y0 and leg.width <= box.width
    assert box.width >= 0.8 * fig.bbox.width  # the plane keeps the figure's width
    title = ax.get_title()
    assert "(A1)" not in title and "eq:a1" in title and "eq:a2" in title
    assert not any("(A1)" in t or "(A2)" in t for t in _legend(ax)[1])


def _row(case, eta, path, s1, err, A=1 / 3, N=1.0):
    return {"case": case, "A": A, "N": N, "eta": eta, "status": "ok", "path": path,
            "s1_acc": s1, "s1_rej": 0, "s2_acc": 30, "s2_rej": 0, "fev": 6 * s1, "us": 50.0,
            "D_wall": 0.1, "err_Delta": err, "err_m_wall": err / 2, "ref": "radau"}


def test_stability_zero_steps_on_the_bottom_edge_and_error_label_names_the_error():
    """A point with 0 stage-1 steps is a triangle on the bottom edge (axes coordinates), not a
    point at 0.8; the error axis says which error against what."""
    rows = [_row("sweep", 1e-8, "stiff", 400, 1e-7), _row("sweep", 0.3, "explicit", 90, 5e-8),
            _row("A = -1, c = 1e+05", 2e-5, "none", 0, 1e-7, A=-1.0)]
    fig = ps.stability_figure(Report(rows=rows, rtol=1e-8))
    ax_s, _, ax_e = fig.axes[:3]
    r = _renderer(fig)
    plotted = [(c.get_offsets()[0], c.get_offset_transform()) for c in ax_s.collections
               if len(c.get_offsets())]
    ys = [xy[1] for xy, _ in plotted]
    assert 0.8 not in ys and min(ys) == 0.0
    zero = [t.transform(xy) for xy, t in plotted if xy[1] == 0.0]
    assert len(zero) == 1  # the A = -1 point, on the axes' bottom edge in display coordinates
    assert math.isclose(zero[0][1], ax_s.get_window_extent(r).y0, abs_tol=1.0)
    assert ps.ZERO_STEPS_LABEL in _legend(ax_s)[1]
    assert "larger of" in ax_e.get_ylabel() and "Delta" in ax_e.get_ylabel()
    assert "reference" in ax_e.get_title()
    for ax in fig.axes[:3]:
        assert _legend_outside_axes(ax)


def _curve(method, n, solved_every, rtols=(1e-4, 1e-6, 1e-8), scale=1.0):
    c = Curve(method, "stage1", "subsample" if method != "ours" else "full set", n)
    c.rtol = list(rtols)
    c.time_us = [scale * 10 * (i + 1) for i in range(len(rtols))]
    c.failed = [n - solved_every] + [0] * (len(rtols) - 1)
    c.median = {"m_wall": [r * 0.5 for r in rtols]}
    c.max = {"m_wall": [r * 5 for r in rtols]}
    c.n_points = {"m_wall": [solved_every] * len(rtols)}
    return c


def test_work_precision_counts_agree_colours_differ_and_legends_cover_nothing():
    """Both panels give a peer the same point count; 'ours on the same points' is in our colour,
    not the peer's; neither legend overlaps its axes."""
    both = Curve("ours", "both", "full set", 60)
    both.rtol, both.time_us = [1e-4, 1e-6, 1e-8], [20.0, 40.0, 80.0]
    both.failed, both.median = [0, 0, 0], {"Delta": [1e-4, 1e-6, 1e-8]}
    both.max = both.median
    ours = _curve("ours", 60, 60)
    rk45 = _curve("scipy-RK45", 60, 29, scale=1000.0)
    comp = Comparison(rk45, _curve("ours", 60, 60), _curve("scipy-RK45", 29, 29, scale=1000.0),
                      _curve("ours", 29, 29))
    fig = pw.work_precision_figure(both, [ours, rk45], [comp])
    left, right = fig.axes[:2]
    left_text = [t for t in _legend(left)[1] if t.startswith("scipy-RK45")][0]
    right_texts = _legend(right)[1]
    assert "29 of 60 solved at every rtol" in left_text
    assert any(t.startswith("scipy-RK45 (29 points") for t in right_texts)
    ours_line = [ln for ln in right.get_lines() if ln.get_label().startswith("ours on the same")]
    peer_line = [ln for ln in right.get_lines() if ln.get_label().startswith("scipy-RK45")]
    assert to_rgba(ours_line[0].get_color()) == to_rgba(pw.STYLES["ours"][0])
    assert to_rgba(ours_line[0].get_color()) != to_rgba(peer_line[0].get_color())
    assert ours_line[0].get_marker() == peer_line[0].get_marker()  # which peer: by marker
    assert _legend_outside_axes(left) and _legend_outside_axes(right)


def test_work_precision_panels_each_have_a_legend_of_their_own_lines():
    """One panel per quantity from work_precision.csv rows: every panel with lines has a legend
    that names exactly them, so the m_wall panel names the stage-1 peers the others lack."""
    rows = []
    for q in ("Delta", "m_wall", "slip"):
        for k, rtol in enumerate((1e-4, 1e-6, 1e-8)):
            rows.append(dict(method="ours", stages="both", rtol=str(rtol), quantity=q,
                             time_per_point_us=str(10.0 * (k + 1)), median_rel_err=str(rtol)))
    for method in ("scipy-RK45", "scipy-LSODA"):
        for k, rtol in enumerate((1e-4, 1e-6)):
            rows.append(dict(method=method, stages="stage1", rtol=str(rtol), quantity="m_wall",
                             time_per_point_us=str(1000.0 * (k + 1)), median_rel_err=str(rtol)))
    fig = pw.quantity_panels_figure(rows)
    panels = {ax.get_title(): ax for ax in fig.axes}
    assert len(panels) == 3
    for title, ax in panels.items():
        drawn = {ln.get_label() for ln in ax.get_lines()}
        assert ax.get_legend() is not None, title
        assert set(_legend(ax)[1]) == drawn, title
    m_wall = next(ax for t, ax in panels.items() if "wall couple stress" in t)
    assert {"scipy-RK45 (stage1)", "scipy-LSODA (stage1)", "ours (both)"} == set(_legend(m_wall)[1])
    delta = next(ax for t, ax in panels.items() if "shear-layer" in t)
    assert set(_legend(delta)[1]) == {"ours (both)"}


def test_point_plot_with_material_shows_nu_and_stresses_in_pa():
    """With a material: nu in the title, and right-hand axes in Pa (stress) and Pa m (couple
    stress) whose scale maps the wall value to the result's wall stress in Pa."""
    r = solve_point(1 / 30, 10, 0.5, 1 / 3, 1, profile=np.linspace(0, 1, 51),
                    material={"d_p": 0.002, "rho_p": 2940, "phi": 25})
    fig = plot.point_profiles(r)
    assert rf"$\nu$ = {r.nu:.4g}" in fig._suptitle.get_text()
    ax_s, ax_m = fig.axes[2], fig.axes[3]
    sec_s = [c for c in ax_s.child_axes]
    sec_m = [c for c in ax_m.child_axes]
    assert sec_s and sec_s[0].get_ylabel() == "stress (Pa)"
    assert sec_m and sec_m[0].get_ylabel() == "couple stress (Pa m)"
    forward = sec_s[0]._functions[0]
    assert math.isclose(forward(-1.0), r.sigma_xy_wall_Pa, rel_tol=1e-12)  # sigma_xy(1)/nu = -1
    assert math.isclose(sec_m[0]._functions[0](r.m_wall), r.m_wall_Pa_m, rel_tol=1e-12)
    plain = plot.point_profiles(solve_point(1 / 30, 10, 0.5, 1 / 3, 1, profile=np.linspace(0, 1, 51)))
    assert r"\nu" not in plain._suptitle.get_text() and not plain.axes[2].child_axes
