"""The kernels' "compute only what is asked" paths against the full two-stage solve."""

import math

import numpy as np
import pytest

from cosserat_channel.integrate import stepping
from cosserat_channel import solve_point
from cosserat_channel.solver import batch, layout, plug_edge, stage1, stage2, stress_path
from cosserat_channel import status as st
from cosserat_channel.solver.point import Workspace
from cosserat_channel.sweep.block import solve_block
from cosserat_channel.sweep.plan import Plan

STAGE1_OUTPUTS = ["m_wall", "sigma_yx_wall", "xi_stop"]
# The test points of tests/test_solver_point.py (bulk, stiff, near and past the path edge, every regime).
POINTS = [
    (1e-4, 1.0, 0.5, 1 / 3, 1.0), (1e-4, 3.0, 5.0, 2.0, 2.0), (1 / 600, 10.0, 0.5, 1 / 3, 1.0),
    (1 / 30, 10.0, 0.5, 1 / 3, 1.0), (0.05, 5.0, 1.0, -0.85, 3.0), (0.01, 1.0, 10.0, 2.9, 0.7),
    (0.3, 10.0, 0.5, 1 / 3, 1.0), (0.32, 10.0, 0.5, 1 / 3, 1.0), (0.33, 10.0, 0.5, 1 / 3, 1.0),
    (0.3308, 10.0, 0.5, 1 / 3, 1.0), (0.335, 10.0, 0.5, 1 / 3, 1.0), (0.45, 10.0, 0.5, 1 / 3, 1.0),
    (0.05, 10.0, 0.5, 0.0, 0.7), (0.05, 10.0, 0.5, 0.1, 0.7), (1 / 30, 10.0, 0.5, -1.0, 1.0),
    (0.05, 10.0, 0.5, -1.5, 1.5), (0.0235, 10.0, 0.5, 3.0, 0.5),
]


def _random_domain(n, seed=15):
    """Points over the whole domain: eps 1e-7..0.5, L 0.5..100, A -3..5, N 0.3..10 (log where wide)."""
    rng = np.random.default_rng(seed)
    eps = 10 ** rng.uniform(-7, math.log10(0.5), n)
    L = 10 ** rng.uniform(math.log10(0.5), 2, n)
    A = rng.uniform(-3, 5, n)
    N = 10 ** rng.uniform(math.log10(0.3), 1, n)
    return [(e, l, 0.5, a, m) for e, l, a, m in zip(eps, L, A, N)]


def _edge_points():
    """Points within 1e-3 .. 1e-9 (relative) of eta_max at A = 1/3, N = 1, on both sides."""
    eta_max = 3.308860581
    return [(eta_max * (1 + s * d) / 10, 10.0, 0.5, 1 / 3, 1.0)
            for d in (1e-3, 1e-5, 1e-7, 1e-9) for s in (-1, 1)]


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10])
def test_status_path_decides_as_the_full_solve(rtol):
    """Workspace.status equals the full solve's status on the test points, near the edge and on a
    random domain-wide sample, at three tolerances."""
    ws_full, ws = Workspace(), Workspace()
    for eps, L, _K, A, N in POINTS + _edge_points() + _random_domain(300):
        eta = eps * L
        assert ws.status(eta, A, N, rtol, 1e-12) == ws_full.run(eta, A, N, rtol, 1e-12), (eps, L, A, N)


def test_status_path_skips_stage2_away_from_the_edge():
    """In the bulk the status path runs no stage 2 at all; next to the edge it does."""
    ws = Workspace()
    assert ws.status(1 / 3, 1 / 3, 1.0, 1e-8, 1e-12) == st.OK
    assert ws.stats2[stepping.STAT_ACCEPTED] == 0 and math.isnan(ws.res[layout.R_J_AXIS])
    ws.run(1 / 3, 1 / 3, 1.0, 1e-8, 1e-12)
    assert ws.stats2[stepping.STAT_ACCEPTED] > 0


def test_solve_point_subset_of_outputs():
    """Asking for stage-1 outputs gives the same bits as the full solve, without stage 2."""
    for p in POINTS + _random_domain(60, seed=3):
        full = solve_point(*p)
        part = solve_point(*p, outputs=STAGE1_OUTPUTS)
        assert part.status == full.status, p
        assert part.computed == tuple(STAGE1_OUTPUTS)
        for name in STAGE1_OUTPUTS:
            a, b = getattr(part, name), getattr(full, name)
            assert a == b or (math.isnan(a) and math.isnan(b)), (p, name)
        assert math.isnan(part.Delta) and part.to_dict()["Delta"] is None
        if part.ok and full.counters["stage2_accepted"] and not part.counters["stage2_accepted"]:
            assert part.counters["stage1_accepted"] == full.counters["stage1_accepted"]


def test_no_plug_edge_root_without_Delta():
    """slip needs stage 2 but no plug-edge root; Delta needs both."""
    r = solve_point(1 / 30, 10.0, 0.5, 1 / 3, 1.0, outputs=["slip"])
    full = solve_point(1 / 30, 10.0, 0.5, 1 / 3, 1.0)
    assert r.slip == full.slip and math.isnan(r.xi_p)
    assert r.counters["stage2_accepted"] == full.counters["stage2_accepted"]


def test_sweep_block_computes_only_what_is_asked():
    """A block asked for stage-1 outputs runs no stage 2 in the bulk and no root; statuses hold."""
    axes = {"eps": np.array([0.01, 1 / 30, 0.3308, 0.45]), "L": np.array([10.0]),
            "K": np.array([0.5, 5.0]), "A": np.array([1 / 3, 3.0]), "N": np.array([0.5, 1.0])}
    plan = Plan(axes, reduce=False, block_size=1000)
    inp = plan.inputs(0)
    full = solve_block(inp, 1e-8, 1e-12)
    part = solve_block(inp, 1e-8, 1e-12, None, False, False)
    assert np.array_equal(part["res"][:, layout.R_STATUS], full["res"][:, layout.R_STATUS])
    ok = full["res"][:, layout.R_STATUS] == st.OK
    for slot in (layout.R_MU_WALL, layout.R_SIGMA_YX_WALL):
        assert np.array_equal(part["res"][ok, slot], full["res"][ok, slot])
    assert np.isnan(part["one_minus"]).all()
    assert part["steps"][:, 1].sum() < full["steps"][:, 1].sum() / 4


def test_wall_form_of_D_matches_the_direct_formula_and_is_smooth():
    """stress_path._wall_form: D(1) + increment equals yield_D on the dense output to round-off of the
    O(1) terms, and next to the wall (where D(1) is tiny at the edge) it is smooth in xi where the
    direct formula is noise."""
    from cosserat_channel.integrate import dense
    from cosserat_channel.physics import model

    A, N = 0.0, 2.0
    eta = 3.7416566781580975 * (1 - 1e-6)  # 1e-6 inside the edge: D(1) ~ 2e-12
    ws = Workspace()
    assert ws.run(eta, A, N, 1e-10, 1e-14) == st.OK
    n1 = int(ws.res[layout.R_N1])
    T1, Q1, ax = ws.T1, ws.Q1, ws.ax
    buf = np.empty(1)
    delta1 = stress_path._delta_wall(T1, Q1, n1, buf)
    D1 = model.yield_D(1.0, delta1, A, N, ax)
    assert 0 < D1 < 1e-10
    C = stress_path._wall_increments(T1, Q1, n1)

    def both(s):
        xi = 1.0 - s
        k = dense.find_step(T1, n1, xi)
        d_w, D_w, noise = stress_path._wall_form(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1)
        dense.dense_eval_step(T1, Q1, k, xi, buf)
        d = xi * xi * buf[0]
        return d_w, D_w, d, model.yield_D(xi, d, A, N, ax), noise

    for s in (0.5, 0.3, 0.1, 1e-2, 1e-3):
        d_w, D_w, d, D, _ = both(s)
        assert d_w == pytest.approx(d, rel=1e-14, abs=1e-15)
        assert D_w == pytest.approx(D, abs=1e-14)
    # Next to the wall: second differences of D on a fine, uniform grid in s. A smooth D has
    # second differences ~ D'' h^2 (h = 1e-9: ~1e-18 at most here); the direct formula's are its
    # rounding noise, ~1e-16.
    s = 1e-6 + 1e-9 * np.arange(64)
    wall = np.array([both(x)[1] for x in s])
    direct = np.array([both(x)[3] for x in s])
    assert np.abs(np.diff(wall, 2)).max() < 1e-17
    assert np.abs(np.diff(direct, 2)).max() > 1e-17  # the noise this form removes
    assert np.all(wall > 0)
    # The noise bound stage 2 floors its tolerance with: at least the rounding of the increment
    # D - D(1) (a few ulps of the terms it sums, each at least as large as it), yet far below D.
    noise = np.array([both(x)[4] for x in s])
    assert np.all(noise >= 2.2e-16 * np.abs(wall - D1))
    assert noise.max() < 1e-6 * wall.min()


def test_stage2_next_to_the_edge_is_cheap():
    """Within 5e-7 (relative) of the edge at A = 0, N = 2 (a node: eta_max = sqrt(14) in closed
    form, regimes.node_edge_eta), D(1) ~ 1e-13 and stage 2 solves in hundreds of panels (it used to
    spend its 20,000-step budget on the noise of D there). Closer than ~3e-7 the status itself is
    within D(1)'s noise band (solve_stage1), so the test stays outside it."""
    ws = Workspace()
    for f in (1e-5, 1e-6, 5e-7):
        eta = math.sqrt(14.0) * (1 - f)
        assert ws.run(eta, 0.0, 2.0, 1e-10, 1e-14) == st.OK
        assert ws.res[layout.R_N2] < 1000


def test_series_plug_edge_root_converges_in_a_few_newton_steps():
    """Below xi2 the plug edge is a Newton root of log I in t = ln xi, from a quintic Hermite of the
    root over the levels eq:13 can ask for, that stops once the curvature predicts the step's
    error below 1e-16 of 1 - xi_p: 2 evaluations.
    (Once the step is below the resolution of t the iterate equals one end of the bracket; taking
    that for a step outside the bracket and bisecting cost 14 evaluations on average and up to 47
    at eta = 3, A = 2, N = 2.)"""
    import math

    from cosserat_channel.physics import model
    from cosserat_channel.integrate import roots

    for eta, A, N in ((3.0, 2.0, 2.0), (1 / 3, 1 / 3, 1.0)):
        ws = Workspace()
        assert ws.run(eta, A, N, 1e-8, 1e-12) == st.OK
        res, ax = ws.res, ws.ax
        J0 = res[layout.R_J_AXIS]
        consts = plug_edge._plug_constants(res, ax)
        t2, log_F2, slope, fa0, slope2, quiet = consts[:6]
        assert quiet
        counts = []
        for eps_K in np.geomspace(1e-4, 10.0, 400):
            target = model.plug_target(J0, eps_K)
            if not target > res[layout.R_J2]:
                continue
            fb = res[layout.R_LOGI2] - math.log(J0 - target)
            c = fb - log_F2
            a = math.log(stage2.XI_FLOOR)
            t0 = plug_edge._series_start(math.log(J0 - target), consts)
            t, n = roots.newton_root_d2(plug_edge._series_plug_level, (c, t2, slope, ax), a, t2,
                                        c + fa0, fb, t0, -1e-16 * t0, plug_edge.ROOT_MAX_ITER)
            assert plug_edge._series_plug_level(t, (c, t2, slope, ax))[0] == pytest.approx(0.0, abs=1e-14)
            assert t == plug_edge._series_plug_edge(target, res, ax, consts)
            counts.append(n)
        assert len(counts) > 300
        assert max(counts) <= 6 and np.mean(counts) < 2.2, (eta, np.bincount(counts))


def test_stage1_resolves_the_turn_at_xi_equal_N_at_loose_rtol():
    """For N < 1 the slow manifold w ~ sqrt(N^2 - xi^2) ends at xi = N just inside the wall; a path
    that survives turns there on a short scale. Without a step boundary at xi = N, rtol 1e-4 gave
    m_wall 1.3e-2 off (130 rtol) at this point of the work-precision set; scipy Radau at rtol 1e-12
    is the reference."""
    from cosserat_channel.physics import reference
    from cosserat_channel.solver.point import solve_point

    eps, L, K, A, N = (1.3595178970681561e-05, 89.34741392658945, 0.2001043014110207,
                       3.754885663209172, 0.9928761610766683)
    ref = reference.reference(eps, L, K, A, N, method="Radau")["m_wall"]
    for rtol in (1e-3, 1e-4, 1e-5):
        r = solve_point(eps, L, K, A, N, rtol=rtol)
        assert abs(r.m_wall / ref - 1) < 10 * rtol


def test_dop853_steps_are_short_enough_for_stage_2_to_read():
    """DOP853 (rtol <= DOP853_RTOL, here the near-edge re-march) could cross the whole stretch from
    the series start to the wall in one step, good at its end but not inside, where stage 2 reads
    it: Delta was 6e-3 off at rtol 1e-4 at this near-edge point of the work-precision set. Against
    scipy DOP853 at rtol 1e-12 (``reference``, its own formulation)."""
    from cosserat_channel.physics import reference
    from cosserat_channel.solver.point import solve_point

    eps, L, K, A, N = (0.30129683417074693, 11.55929836603691, 0.5185823201602671,
                       -0.09975520018273087, 2.2913017272900325)
    ref = reference.reference(eps, L, K, A, N)["Delta"]
    for rtol in (1e-3, 1e-4, 1e-5, 1e-6):
        r = solve_point(eps, L, K, A, N, rtol=rtol)
        assert abs(r.Delta / ref - 1) < 10 * rtol, rtol


@pytest.mark.parametrize("eta", [0.0234, 0.025, 0.0368])
def test_dop853_one_step_across_the_stretch_only_where_its_defect_passes(eta):
    """bench_point's grid (A = 1/3, N = 1): from the series start at xi1 = 0.9, DOP853 crossed to
    the wall in one step, accepted on an error estimate that missed its error: at rtol 1e-6
    u(0) was 2.9e-4 off at eta = 0.0234 and Delta 9e-5. Such a step is kept only where its
    interpolant's defect at its middle passes the tolerance. Against scipy DOP853 at rtol 1e-12
    (``reference``, its own formulation), at the rtols where DOP853 marches."""
    from cosserat_channel.physics import reference
    from cosserat_channel.solver.point import solve_point

    L, K = 10.0, 0.5
    ref = reference.reference(eta / L, L, K, 1 / 3, 1.0)
    for rtol in (1e-6, 5e-7, 1e-7):
        r = solve_point(eta / L, L, K, 1 / 3, 1.0, rtol=rtol, atol=rtol * 1e-2)
        assert abs(r.u_axis / ref["u_axis"] - 1) < 5 * rtol, rtol
        assert abs(r.Delta / ref["Delta"] - 1) < 5 * rtol, rtol


def test_dop853_grid_at_rtol_1e_6_within_its_tolerance():
    """bench_point's whole grid at rtol 1e-6, where DOP853 may cross the stretch in one step:
    the same statuses, and u(0) (J(0)), m_wall and Delta within 5 rtol of the same points at
    rtol 1e-12."""
    from cosserat_channel import solve

    eps = np.logspace(np.log10(1 / 600), np.log10(0.2), 50)[:, None]
    L = np.linspace(2, 20, 20)[None, :]
    loose = solve(eps, L, 0.5, 1 / 3, 1.0, rtol=1e-6, atol=1e-8, workers=1)
    tight = solve(eps, L, 0.5, 1 / 3, 1.0, rtol=1e-12, atol=1e-14, workers=1)
    np.testing.assert_array_equal(loose.status.values, tight.status.values)
    ok = loose.status.values == 0
    assert ok.sum() > 900  # the grid's corner at large eps L is past the path edge
    for name in ("u_axis", "m_wall", "Delta"):
        err = np.abs(loose[name].values[ok] / tight[name].values[ok] - 1)
        assert err.max() < 5e-6, (name, err.max())


# Points in bands ~1e-5 (relative) wide in eta where stage 1's first DOP853 trial step (half the
# stretch from the series start, |h lambda| ~ 16 or ~ 24) sits on a zero of the pair's error
# estimate: the step passed the error test with w off by O(1), and stage 2, integrating that
# solution, gave up after 65-69 rejected panels (integration_failed) at the default tolerances.
# The first was reported, the next two found by benchmarks/fuzz_stage2.py's random points (its
# "stiff start" domain, seed 1), the others by its band search (all at L = 2).
FIRST_STEP_BANDS = [
    (0.007390722033525775, 2.0, 0.5, 1.489795918367347, 1.0693877551020408),
    (0.012561988181163443 / 2, 2.0, 0.5, 3.1081934531689765, 0.9835296325845494),
    (0.013362628185310093 / 2, 2.0, 0.5, 0.6693017824677775, 1.0750604225446436),
    (0.009072417309512049 / 2, 2.0, 0.5, 4.707735808323018, 0.9381097059549877),
    (0.00961526424354731 / 2, 2.0, 0.5, 0.9398055668618642, 1.0165585118508902),
    (0.0036007415572872487 / 2, 2.0, 0.5, 2.716719476212939, 1.1717865958366986),
]


@pytest.mark.parametrize("point", FIRST_STEP_BANDS)
def test_first_step_on_a_zero_of_the_error_estimate(point):
    """ok at the default tolerances, stage 2 without a string of rejections, and the outputs of
    scipy Radau at rtol 1e-12 (``reference``, its own formulation) to 1e-6 relative, the
    accuracy the default rtol 1e-8 gives away from the edges (tests/test_domain.py)."""
    from cosserat_channel.physics import reference

    r = solve_point(*point)
    assert r.status == st.Status.ok
    assert r.counters["stage2_rejected"] <= 4
    ref = reference.reference(*point, method="Radau")
    for name in ("Delta", "m_wall", "u_axis", "sigma_yx_wall"):
        assert abs(getattr(r, name) / ref[name] - 1) < 1e-6, name


# Points where benchmarks/probes/probe_stiff_switch.py measured one stage-1 path at least 1.7x cheaper
# than the other (CPU time of both stages): (eta, A, N, rtol, the cheaper path). The first two
# were picked wrong by the earlier rule STIFF_LAMBDA sqrt(1e-6/rtol) (12x and 2.9x).
SWITCH_POINTS = [
    (2.81e-3, 3.335, 2.398, 1e-8, layout.PATH_STIFF),  # slow manifold to the wall (N > 1)
    (7.47e-3, 2.380, 0.327, 1e-8, layout.PATH_EXPLICIT),  # N < 1: fast turn to D = 0 after xi = N
    (1e-3, 1 / 3, 1.3, 1e-8, layout.PATH_STIFF),
    (1e-3, 1 / 3, 1.1, 1e-7, layout.PATH_STIFF),
    (1e-2, 1 / 3, 1.0, 1e-9, layout.PATH_EXPLICIT),  # N = 1: the manifold ends at the wall
    (1e-3, 1 / 3, 0.9, 1e-10, layout.PATH_EXPLICIT),
    (1e-4, 1 / 3, 1.0, 1e-6, layout.PATH_STIFF),
    (0.2524, -0.76, 0.942, 1e-7, layout.PATH_STIFF),  # next to the axis edge: stiff at the axis
    (1e-3, 1 / 3, 1.0, 1e-4, layout.PATH_STIFF),  # Dormand-Prince's side of the switch
]


@pytest.mark.parametrize("eta, A, N, rtol, cheaper", SWITCH_POINTS)
def test_stiff_switch_picks_the_path_with_less_work(eta, A, N, rtol, cheaper):
    """Where one path was measured clearly cheaper, the switch takes it, and it is the one with
    fewer right-hand-side evaluations in both stages (counted, independently of timing). Both
    give the same status, m_wall and J(0) to the tolerance, and xi_stop to ~sqrt(rtol) (where
    D falls to zero nearly tangentially it moves by the square root of the error in D)."""
    ws = Workspace()
    work, out = {}, {}
    for method in (layout.METHOD_EXPLICIT, layout.METHOD_STIFF):
        code = ws.run(eta, A, N, rtol, 1e-12, method)
        path = ws.res[layout.R_PATH]
        work[path] = ws.stats1[stepping.STAT_FEV] + ws.stats2[stepping.STAT_FEV]
        out[path] = (code, ws.res[layout.R_MU_WALL], ws.res[layout.R_J_AXIS],
                     ws.res[layout.R_XI_STOP])
    ws.run(eta, A, N, rtol, 1e-12)
    assert ws.res[layout.R_PATH] == cheaper
    other = layout.PATH_STIFF if cheaper == layout.PATH_EXPLICIT else layout.PATH_EXPLICIT
    assert work[cheaper] < work[other]
    (c1, m1, j1, x1), (c2, m2, j2, x2) = out.values()
    assert c1 == c2
    np.testing.assert_allclose([m1, j1], [m2, j2], rtol=100 * rtol, atol=0)
    np.testing.assert_allclose(x1, x2, rtol=10 * math.sqrt(rtol), atol=0)


def test_stiffness_diagnostic_on_the_dop853_path():
    """At rtol <= DOP853_RTOL the explicit path is DOP853, whose stiffness test now feeds the
    stage1_stiff diagnostic: forced onto it, stage 1 at eta = 1e-4 (Jacobian ~ -2/eta) is flagged
    stiff, at eta = 0.3 it is not; RODAS4P2 never flags."""
    ws = Workspace()
    for eta, stiff in ((1e-4, 1), (0.3, 0)):
        ws.run(eta, 1 / 3, 1.0, 1e-8, 1e-12, layout.METHOD_EXPLICIT)
        assert ws.stats1[stepping.STAT_STIFF] == stiff, eta
        ws.run(eta, 1 / 3, 1.0, 1e-8, 1e-12, layout.METHOD_STIFF)
        assert ws.stats1[stepping.STAT_STIFF] == 0 and ws.stats1[stepping.STAT_STIFF_STEPS] == 0


def _plug_edge_by_brentq(eps_K, res, ax, T2, Q2):
    """1 - xi_p by scipy brentq, independently of the kernel's search: the panel from the panel
    ends' values, then brentq on panels.panel_value in u; below xi2 brentq on log I(e^t) from
    model.series_F."""
    from scipy.optimize import brentq

    from cosserat_channel.physics import model
    from cosserat_channel.integrate import panels

    J0 = res[layout.R_J_AXIS]
    target = model.plug_target(J0, eps_K)
    if target <= 0.0:
        return 0.0
    if target > res[layout.R_J2]:
        xi2 = res[layout.R_XI2]
        t2 = math.log(xi2)
        level = math.log(J0 - target)

        def f(t):
            return (res[layout.R_LOGI2] + (ax[model.AX_BETA] + 1.0) * (t - t2)
                    + math.log(model.series_F(math.exp(t), ax) / model.series_F(xi2, ax)) - level)

        a = math.log(stage2.XI_FLOOR)
        if f(a) > 0.0:
            return -math.expm1(a)
        return -math.expm1(brentq(f, a, t2, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500))
    n2 = int(res[layout.R_N2])
    tops = Q2[:n2, panels.TOP, 1]
    p = int(np.searchsorted(tops, target)) - 1  # tops[p] < target <= tops[p + 1]
    top = Q2[p, panels.TOP, 1]
    if not panels.panel_value(Q2, p, 1, 2.0) > target:
        return -math.expm1(T2[p + 1])
    u = brentq(lambda v: panels.panel_value(Q2, p, 1, v) - target, 0.0, 2.0, xtol=1e-300,
               rtol=4 * np.finfo(float).eps, maxiter=500)
    assert top < target
    return -math.expm1(T2[p] - 0.5 * (T2[p] - T2[p + 1]) * u)


@pytest.mark.parametrize("order", ["sorted", "shuffled"])
def test_plug_edge_agrees_with_brentq_on_the_panel_series(order):
    """1 - xi_p from solve_batch (on the panels and below xi2) against scipy brentq on the same
    series, to 4e-15 relative, on 500 eps K per triple, sorted (a sweep) and shuffled; and the
    batch gives the bits of one_minus_xi_p called alone (a reduced sweep equals an unreduced one)."""
    rng = np.random.default_rng(7)
    triples = [(1 / 3, 1 / 3, 1.0), (0.01, 1 / 3, 1.0), (3.0, 2.0, 2.0), (1 / 60, 1 / 3, 1.0),
               (3.308860581 * (1 - 1e-7), 1 / 3, 1.0), (0.5, 0.0, 0.7), (0.1, -0.85, 3.0)]
    triples += [(10 ** rng.uniform(-4, 1), rng.uniform(-2, 4), 10 ** rng.uniform(-0.5, 1))
                for _ in range(12)]
    eta, A, N = (np.array(v) for v in zip(*triples))
    m = 500
    eps_K = np.concatenate([np.geomspace(1e-7, 30.0, m) for _ in triples])
    if order == "shuffled":
        eps_K = np.concatenate([rng.permutation(eps_K[i * m:(i + 1) * m]) for i in range(len(triples))])
    res = np.empty((eta.size, layout.N_R))
    stats = np.zeros((eta.size, 2, stepping.N_STATS), np.int64)
    one_minus = np.empty(eps_K.size)
    batch.solve_batch(eta, A, N, eps_K, np.arange(eta.size + 1) * m, 1e-8, 1e-12,
                       stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, res, stats, one_minus,
                       np.empty(0), np.empty((1, layout.N_PROF, 0)), True, True)
    ws = Workspace()
    worst = 0.0
    checked = {"panels": 0, "series": 0}
    for i in range(eta.size):
        if ws.run(eta[i], A[i], N[i], 1e-8, 1e-12) != st.OK:
            continue
        for j in range(i * m, (i + 1) * m):
            got = one_minus[j]
            assert got == plug_edge.one_minus_xi_p(eps_K[j], ws.res, ws.ax, ws.T2, ws.Q2)
            ref = _plug_edge_by_brentq(eps_K[j], ws.res, ws.ax, ws.T2, ws.Q2)
            if ref == 0.0:
                assert got == 0.0
                continue
            checked["series" if model_target_below(ws.res, eps_K[j]) else "panels"] += 1
            worst = max(worst, abs(got - ref) / ref)
    assert checked["panels"] > 1000 and checked["series"] > 1000, checked
    assert worst < 4e-15, worst


def model_target_below(res, eps_K):
    from cosserat_channel.physics import model

    return model.plug_target(res[layout.R_J_AXIS], eps_K) > res[layout.R_J2]


def test_plug_edge_where_the_series_is_noisy():
    """At eta = 0.057, A = 1/3, N = 1 the closed form's F has a condition number ~4e5 at xi2: log F
    carries noise ~1e-11, which voids the Newton steps' curvature test; the root then shrinks its
    bracket to a sign change as brentq does, and both stay within the noise band (~1e-11 of 1 - xi_p)."""
    from cosserat_channel.physics import model

    ws = Workspace()
    assert ws.run(0.05696071736871604, 1 / 3, 1.0, 1e-8, 1e-12) == st.OK
    assert not plug_edge._plug_constants(ws.res, ws.ax)[5]
    n = 0
    for eps_K in np.geomspace(1e-4, 30.0, 300):
        if not model.plug_target(ws.res[layout.R_J_AXIS], eps_K) > ws.res[layout.R_J2]:
            continue
        got = plug_edge.one_minus_xi_p(eps_K, ws.res, ws.ax, ws.T2, ws.Q2)
        ref = _plug_edge_by_brentq(eps_K, ws.res, ws.ax, ws.T2, ws.Q2)
        assert abs(got - ref) <= 2e-11 * ref, eps_K
        n += 1
    assert n > 100
