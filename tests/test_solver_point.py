"""solve_point against an independent scipy reference, the paper's numbers and model.md's facts."""

import json
import math

import numpy as np
import pytest

from cosserat_channel.physics import asymptotics
from cosserat_channel import status as st
from cosserat_channel.parameters import ParameterError
from cosserat_channel.solver.point import solve_point

from cosserat_channel.physics.reference import profile as ref_profile
from cosserat_channel.physics.reference import reference

FIG2 = dict(eps=1 / 30, L=10.0, K=0.5, A=1 / 3, N=1.0)  # paper figure 2 (L = 10 curve)
OUTPUTS = ("Delta", "m_wall", "sigma_yx_wall", "slip")


def _ref(eps, L, K, A, N):
    # Radau is fast on the stiff small-eps points; DOP853 elsewhere (they agree to ~1e-11).
    return reference(eps, L, K, A, N, method="Radau" if eps * L < 0.05 else "DOP853")


# A spread over the acceptance ranges: eps 1e-4 .. the edge, L 1..30, A in (-0.9, 3), N 0.7..3,
# K 0.1..100; comments say why each row is there.
SPREAD = [
    (1e-4, 1.0, 0.5, 1 / 3, 1.0),  # smallest eps, stiff (eta = 1e-4)
    (1e-4, 30.0, 0.1, 1 / 3, 1.0),  # smallest eps, large L
    (1e-4, 3.0, 5.0, 2.0, 2.0),  # large A, smoother wall
    (1e-3, 10.0, 100.0, 0.5, 1.5),  # large K: thin shear layer, big slip
    (1 / 600, 10.0, 0.5, 1 / 3, 1.0),  # paper figure 4
    (1 / 30, 10.0, 0.5, 1 / 3, 1.0),  # paper figure 2
    (1 / 30, 2.0, 0.5, 1 / 3, 1.0),  # figure 2, L = 2
    (0.12, 10.0, 0.5, 1 / 3, 1.0),  # paper figure 3
    (0.05, 5.0, 1.0, -0.85, 3.0),  # A close to -1 with large N
    (0.02, 20.0, 0.3, -0.5, 1.2),  # negative A
    (0.01, 1.0, 10.0, 2.9, 0.7),  # largest A, smallest N
    (0.2, 15.0, 2.0, 1.0, 1.0),  # A = 1: axis condition always met
    (0.3, 10.0, 0.5, 1 / 3, 1.0),  # near the edge
    (0.32, 10.0, 0.5, 1 / 3, 1.0),  # nearer the edge (D(1) ~ 5e-3)
    (0.33, 10.0, 0.5, 1 / 3, 1.0),  # at the edge (D(1) ~ 2e-4): feasible, see test below
    (0.335, 10.0, 0.5, 1 / 3, 1.0),  # just over the edge: path fails
    (0.38, 10.0, 0.5, 1 / 3, 1.0),  # path fails early
    (0.45, 10.0, 0.5, 1 / 3, 1.0),  # axis fails: eta + 2(A+1) N < 0
    (0.05, 10.0, 0.5, 0.0, 0.7),  # A < 1 - 2N^2 = 0.02: wall inadmissible
    (0.05, 10.0, 0.5, 0.1, 0.7),  # A just above 1 - 2N^2: path meets D = 0 before the wall
]


@pytest.mark.parametrize("point", SPREAD, ids=[str(p) for p in SPREAD])
def test_agrees_with_scipy_reference(point):
    """At the default rtol, Delta, m_wall, sigma_yx_wall and slip agree with solve_ivp (rtol 1e-12)
    to 1e-6; statuses agree."""
    eps, L, K, A, N = point
    ours = solve_point(eps, L, K, A, N)
    ref = _ref(eps, L, K, A, N)
    assert ours.status.name == ref["status"]
    if ref["status"] == "ok":
        for name in OUTPUTS:
            assert getattr(ours, name) == pytest.approx(ref[name], rel=1e-6), name
        assert math.isnan(ours.xi_stop)
    else:
        for name in OUTPUTS:
            assert math.isnan(getattr(ours, name))
    if ref["status"] == "eps_too_large_path":
        # Where the path meets D = 0 the RHS has a sqrt kink; even DOP853 and Radau at rtol 1e-12
        # place it ~1e-6 apart, so xi_stop is held to 1e-5 (it is not one of the 1e-6 outputs).
        assert ours.xi_stop == pytest.approx(ref["xi_stop"], rel=1e-5)


def test_profiles_agree_with_reference():
    """u/u(0), omega_hat, m and sigma_yx profiles match the reference to 1e-6."""
    xi = np.linspace(0.05, 1.0, 39)
    ours = solve_point(**FIG2, profile=xi)
    ref = _ref(**FIG2)
    want = ref_profile(ref, xi, **FIG2)
    for name in ("u_over_u0", "omega_hat", "m", "sigma_yx"):
        np.testing.assert_allclose(ours.profile[name], want[name], rtol=1e-6, atol=1e-9, err_msg=name)
    assert ours.profile["u_over_u0"][-1] == pytest.approx(ours.slip, rel=1e-12)
    assert ours.profile["omega_hat"][-1] == pytest.approx(1.0, rel=1e-12)


def test_profile_down_to_the_axis():
    """Below where stage 2 stopped the profile stays monotone, omega_hat -> 0 and u/u(0) -> 1."""
    xi = np.concatenate([[0.0, 1e-6, 1e-3], np.linspace(0.01, 1, 100)])
    prof = solve_point(**FIG2, profile=xi).profile
    assert prof["u_over_u0"][0] == pytest.approx(1.0, abs=1e-12)
    assert prof["omega_hat"][0] == 0.0
    assert np.all(np.diff(prof["omega_hat"]) >= 0)
    assert np.all(np.diff(prof["u_over_u0"]) <= 1e-14)
    assert prof["m"][0] == pytest.approx(-FIG2["N"] * FIG2["L"], rel=1e-12)  # eq:54
    assert prof["sigma_yx"][0] == 0.0  # eq:11


def test_tolerance_is_honoured():
    """Tightening rtol tightens the error: rtol 1e-10 is 1e-8 accurate where 1e-6 is not."""
    ref = _ref(**FIG2)
    errs = {rtol: abs(solve_point(**FIG2, rtol=rtol).Delta / ref["Delta"] - 1) for rtol in (1e-6, 1e-10)}
    assert errs[1e-10] < 1e-8
    assert errs[1e-10] < errs[1e-6]


# --------------------------------------------------------------------------------------------
# The paper's numbers (model.md's table); each assertion message says what the paper states.
# --------------------------------------------------------------------------------------------
def test_paper_figure2_shear_layer_thickness():
    """Paper (figure 2): Delta 'about 10.5' at eps = 1/30, L = 10, A = 1/3, N = 1, K = 0.5."""
    r = solve_point(**FIG2)
    assert r.status == st.Status.ok
    # We get 10.253 (the reference agrees to 1e-8); "about 10.5" is read off a figure.
    assert r.Delta == pytest.approx(10.5, rel=0.03), f"paper: about 10.5; ours: {r.Delta:.4f}"


def test_paper_delta_vanishes_for_K_above_200():
    """Paper: for K > 200 (eps = 1/30) the wall moves at > 95 % of the centre, so Delta = 0."""
    r = solve_point(**FIG2)
    J_axis = r.u_axis - FIG2["eps"] * FIG2["K"]
    K_star = 19 * J_axis / FIG2["eps"]  # eps K = 19 J(0)
    assert K_star == pytest.approx(200, rel=0.02), f"paper: 200; ours: {K_star:.2f}"
    params = dict(FIG2)
    params["K"] = 1.01 * K_star
    assert solve_point(**params).Delta == 0.0
    params["K"] = 0.99 * K_star
    assert 0 < solve_point(**params).Delta < 0.5


def test_paper_figure7_delta_grows_with_channel_width():
    """Paper (figure 7): Delta increases with W/d_p."""
    widths = [10, 20, 30, 60, 100, 200, 600]
    deltas = [solve_point(1 / w, 10, 0.5, 1 / 3, 1).Delta for w in widths]
    assert np.all(np.diff(deltas) > 0), deltas


def test_paper_figure8_delta_grows_weakly_with_L():
    """Paper (figure 8): Delta is a weak (sub-linear) increasing function of L."""
    Ls = np.array([2.0, 5.0, 10.0, 20.0])
    deltas = np.array([solve_point(1 / 30, L, 0.5, 1 / 3, 1).Delta for L in Ls])
    assert np.all(np.diff(deltas) > 0)
    assert deltas[-1] / deltas[0] < (Ls[-1] / Ls[0]) ** (2 / 3)  # at most the small-eps L^(2/3)


def test_paper_figure9_delta_flat_in_K_for_small_K():
    """Paper (figure 9): little variation with K for small K, significant in K ~ 1..200."""
    d = {K: solve_point(1 / 30, 10, K, 1 / 3, 1).Delta for K in (0.0, 0.1, 1.0, 50.0, 150.0)}
    assert abs(d[0.1] / d[0.0] - 1) < 0.01
    assert d[1.0] > d[50.0] > d[150.0]
    assert d[150.0] < 0.2 * d[1.0]


def test_paper_edge_eps_033_is_feasible_with_round_off_care():
    """Paper (Appendix A): 'no solution at eps = 0.33'; exact arithmetic says there is one, just."""
    r = solve_point(0.33, 10, 0.5, 1 / 3, 1)
    ref = _ref(0.33, 10, 0.5, 1 / 3, 1)
    # The reference (different formulation, rtol 1e-12) also reaches the wall, with D(1) ~ 2.2e-4.
    assert ref["status"] == "ok" and r.status == st.Status.ok, (
        "paper: no solution at eps = 0.33; we (and scipy at rtol 1e-12) find one, D(1) = "
        f"{(ref['sigma_yx_wall'] - 1 / 3) ** 2:.2e}: the paper's verdict is round-off near the axis"
    )
    assert solve_point(0.335, 10, 0.5, 1 / 3, 1).status == st.Status.eps_too_large_path


@pytest.mark.parametrize(
    "eps, material, nu_paper",
    [
        (1 / 30, dict(d_p=0.002, rho_p=2940, phi=25), 0.603),  # figure 2 (and 12): 0.60 / 0.603
        (0.003 / 0.0255, dict(d_p=0.003, rho_p=2940, phi=28), 0.59),  # figure 3
    ],
)
def test_paper_solids_fraction(eps, material, nu_paper):
    """Paper: nu = 0.60 (0.603) for figure 2 and 0.59 for figure 3, with Lambda = 817 Pa."""
    r = solve_point(eps, 10, 0.5, 1 / 3, 1, material=material)
    assert r.nu == pytest.approx(nu_paper, abs=0.005), f"paper: {nu_paper}; ours: {r.nu:.4f}"


def test_paper_table1_wall_stresses():
    """Paper (table 1): 7.97 kPa normal, 1.12 kPa shear at nu = 0.625; the printed closure gives ~1 % less."""
    N = math.sin(math.radians(30)) / math.tan(math.radians(8))
    r = solve_point(2.29e-3 / 0.155, 10, 0.5, 1 / 3, N,
                    material=dict(d_p=2.29e-3, rho_p=1180, phi=30))
    assert r.nu == pytest.approx(0.625, rel=0.02), f"paper: 0.625; ours: {r.nu:.4f}"
    assert r.sigma_xx_wall_Pa == pytest.approx(7970, rel=0.02), f"paper: 7.97 kPa; ours {r.sigma_xx_wall_Pa:.0f} Pa"
    assert -r.sigma_xy_wall_Pa == pytest.approx(1120, rel=0.02), f"paper: 1.12 kPa; ours {-r.sigma_xy_wall_Pa:.0f} Pa"
    # Internal consistency: sigma_xx = sigma_c(nu) and the wall friction law eq:5.
    assert -r.sigma_xy_wall_Pa / r.sigma_xx_wall_Pa == pytest.approx(math.tan(math.radians(8)), rel=1e-12)


def test_small_eps_approaches_the_airy_asymptote():
    """Appendix C: for N = 1, Delta / ((L^2/2)^(1/3) eps^(-1/3) 1.2748) -> 1 as eps -> 0."""
    ratios = [solve_point(eps, 10, 0.0, 1 / 3, 1).Delta / asymptotics.Delta_asymptotic(eps, 10)
              for eps in (1e-2, 1e-3, 1e-4)]
    assert ratios[0] < ratios[1] < ratios[2] < 1.0
    assert ratios[2] == pytest.approx(1.0, abs=0.01)


# --------------------------------------------------------------------------------------------
# model.md's similarity and the closed form
# --------------------------------------------------------------------------------------------
SIMILAR = [(1 / 30, 10.0, 0.5), (1 / 60, 20.0, 1.0), (1 / 15, 5.0, 0.25)]


def test_similarity_holds_in_the_reference():
    """model.md: 1-xi_p, J(0), sigma_yx(1), m(1)/L depend on (eps L, A, N, eps K) only (independent solver)."""
    refs = [reference(eps, L, K, 1 / 3, 1.0, rtol=1e-13) for eps, L, K in SIMILAR]
    base = refs[0]
    for (_eps, L, _K), r in zip(SIMILAR[1:], refs[1:]):
        assert 1 - r["xi_p"] == pytest.approx(1 - base["xi_p"], rel=1e-9)
        assert r["J_axis"] == pytest.approx(base["J_axis"], rel=1e-9)
        assert r["sigma_yx_wall"] == pytest.approx(base["sigma_yx_wall"], rel=1e-9)
        assert r["m_wall"] / L == pytest.approx(base["m_wall"] / SIMILAR[0][1], rel=1e-9)


def test_similarity_holds_in_solve_point():
    """The same three points through solve_point agree to 13 digits (model.md's check)."""
    rs = [solve_point(eps, L, K, 1 / 3, 1.0) for eps, L, K in SIMILAR]
    for (eps, L, _K), r in zip(SIMILAR, rs):
        assert r.Delta * eps == pytest.approx(rs[0].Delta * SIMILAR[0][0], rel=1e-13)
        assert r.m_wall / L == pytest.approx(rs[0].m_wall / SIMILAR[0][1], rel=1e-13)
        assert r.sigma_yx_wall == pytest.approx(rs[0].sigma_yx_wall, rel=1e-13)


def test_K_costs_no_integration():
    """J(0) = u_axis - eps K is the same for every K (K enters only through eq:13 and eq:7)."""
    J = [solve_point(1 / 30, 10, K, 1 / 3, 1).u_axis - K / 30 for K in (0.0, 0.5, 50.0)]
    assert J[1] == pytest.approx(J[0], rel=1e-15) and J[2] == pytest.approx(J[0], rel=1e-15)


@pytest.mark.parametrize("eps, L, K, N", [(1 / 30, 10, 0.5, 1.0), (1e-3, 10, 0.0, 1.0), (0.01, 2, 5, 3.0)])
def test_A_minus_one_closed_form(eps, L, K, N):
    """A = -1 follows Appendix A's closed form (independent implementation in asymptotics).

    A = -1 runs through the stage-2 integrator (B = c/xi, h = 2) like every other
    A instead of short-cutting to the closed form, so agreement is to the integration tolerance
    (measured <= 1.3e-7 at rtol 1e-8), not to 1e-12; tests/test_domain.py takes c up to 1e7.
    """
    r = solve_point(eps, L, K, -1.0, N, profile=np.linspace(0, 1, 11))
    cf = asymptotics.a_minus_one_outputs(eps, L, K, N)
    assert r.status == st.Status.ok
    assert r.Delta == pytest.approx(cf.Delta, rel=3e-7)
    assert r.slip == pytest.approx(cf.slip, rel=3e-8)
    assert r.m_wall == pytest.approx(-N * L) and r.sigma_yx_wall == -1.0
    prof = asymptotics.a_minus_one(r.profile["xi"], eps, L, K, N)
    np.testing.assert_allclose(r.profile["u_over_u0"], prof.u_over_u0, rtol=3e-7)
    np.testing.assert_allclose(r.profile["omega_hat"], prof.omega_hat, rtol=1e-7)


def test_regime_statuses_and_messages():
    """Each regime of Appendix A gets its status, with a message, and no numbers."""
    cases = {
        st.Status.wall_inadmissible: (0.05, 10, 0.5, -2.0, 1.0),
        st.Status.axis_spin_unbounded: (0.05, 10, 0.5, -1.5, 2.0),
        st.Status.eps_too_large_axis: (0.45, 10, 0.5, 1 / 3, 1.0),
        st.Status.eps_too_large_path: (0.36, 10, 0.5, 1 / 3, 1.0),
    }
    for want, point in cases.items():
        r = solve_point(*point)
        assert r.status == want
        assert r.status.message and r.to_dict()["status"] == want.name
        assert r.to_dict()["Delta"] is None


def test_counters_are_reported():
    """The result carries both stages' step counts, which grow when the tolerance tightens."""
    loose = solve_point(**FIG2, rtol=1e-5).counters
    tight = solve_point(**FIG2, rtol=1e-10).counters
    assert 0 < loose["stage1_accepted"] < tight["stage1_accepted"]
    assert 0 < loose["stage2_accepted"] < tight["stage2_accepted"]
    assert tight["stage1_fev"] >= 6 * tight["stage1_accepted"]


# --------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(eps=math.nan), "eps"),
        (dict(eps=math.inf), "eps"),
        (dict(eps=0.0), "eps"),
        (dict(eps=-0.1), "eps"),
        (dict(L=0.0), "L"),
        (dict(L=math.nan), "L"),
        (dict(K=-1.0), "K"),
        (dict(K=math.inf), "K"),
        (dict(A=math.nan), "A"),
        (dict(N=0.0), "N"),
        (dict(N=-1.0), "N"),
        (dict(rtol=0.0), "rtol"),
        (dict(rtol=1.0), "rtol"),
        (dict(rtol=math.nan), "rtol"),
        (dict(atol=0.0), "atol"),
        (dict(eps="abc"), "eps"),
        (dict(eps=True), "eps"),
        (dict(material=dict(d_p=0.002, rho_p=2940, phi=25, colour="red")), "colour"),
        (dict(material=dict(d_p=0.002, rho_p=2940)), "phi"),
        (dict(material=dict(d_p=-1, rho_p=2940, phi=25)), "material.d_p"),
        (dict(material=dict(d_p=0.002, rho_p=2940, phi=95)), "material.phi"),
        (dict(material=dict(d_p=0.002, rho_p=2940, phi=25, nu_min=0.7)), "nu_min"),
        (dict(profile=[0.5, 1.5]), "profile"),
    ],
)
def test_bad_input_raises_naming_the_parameter(kwargs, name):
    """Bad input raises a ValueError subclass naming the parameter (and its range)."""
    args = dict(FIG2)
    args.update(kwargs)
    with pytest.raises(ParameterError) as info:
        solve_point(args.pop("eps"), args.pop("L"), args.pop("K"), args.pop("A"), args.pop("N"), **args)
    assert isinstance(info.value, ValueError)
    assert name in str(info.value)
    if name in ("eps", "L", "K", "N", "rtol"):
        assert "(" in str(info.value) or "[" in str(info.value)  # the allowed range is stated


def test_axis_edge_exactly_is_infeasible_not_a_crash():
    """On the axis edge itself ((A-1) eta + 2(A+1) N = 0) the point is eps_too_large_axis, no exception."""
    r = solve_point(0.2, 10.0, 0.5, 0.0, 1.0)  # eta = 2: margin = -2 + 2 = 0
    assert r.status == st.Status.eps_too_large_axis


@pytest.mark.parametrize("rel_margin", [1e-2, 1e-3, 1e-4])
def test_next_to_the_axis_edge(rel_margin):
    """Just inside the axis edge (c0 -> 0, beta huge) status and xi_stop match the reference, with bounded work."""
    A, N, L = 0.0, 1.0, 10.0
    eps = 2 * (A + 1) * N / (1 - A) / L * (1 - rel_margin)
    r = solve_point(eps, L, 0.5, A, N)
    # The reference evaluates D in the printed form, which loses digits like 1/c0^2 here (its
    # own DOP853 and Radau runs differ by 2 % at rel_margin 1e-3); Radau is the stable one.
    ref = reference(eps, L, 0.5, A, N, method="Radau")
    assert r.status.name == ref["status"]
    if ref["status"] == "ok":
        for name in OUTPUTS:
            assert getattr(r, name) == pytest.approx(ref[name], rel=1e-6), name
    else:
        assert r.xi_stop == pytest.approx(ref["xi_stop"], rel=2e-4)
    assert r.counters["stage1_accepted"] < 5000


def test_within_resolution_of_the_axis_edge():
    """Closer than ~1e-5 to the axis edge: eps_too_large_path without a location (NaN), never a wrong one."""
    A, N, L = 0.0, 1.0, 10.0
    for rel_margin in (1e-7, 1e-10):
        r = solve_point(2 * (A + 1) * N / (1 - A) / L * (1 - rel_margin), L, 0.5, A, N)
        assert r.status == st.Status.eps_too_large_path
        assert math.isnan(r.xi_stop)


def test_batch_profiles_match_solve_point_including_A_minus_one():
    """solve_batch's per-triple profiles give solve_point's profiles, also for the A = -1 closed form."""
    from cosserat_channel.integrate import stepping
    from cosserat_channel.solver import batch, layout, stage1, stage2

    xi = np.linspace(0.0, 1.0, 21)
    pts = [(1 / 30, 10.0, 0.5, 1 / 3, 1.0), (0.01, 2.0, 5.0, -1.0, 3.0)]
    n = len(pts)
    eta = np.array([p[0] * p[1] for p in pts])
    res = np.empty((n, layout.N_R))
    stats = np.zeros((n, 2, stepping.N_STATS), np.int64)
    one_minus = np.empty(n)
    prof = np.empty((n, layout.N_PROF, xi.size))
    batch.solve_batch(eta, np.array([p[3] for p in pts]), np.array([p[4] for p in pts]),
                      np.array([p[0] * p[2] for p in pts]), np.arange(n + 1), 1e-8, 1e-12,
                      stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, res, stats, one_minus, xi, prof)
    for i, (eps, L, K, A, N) in enumerate(pts):
        want = solve_point(eps, L, K, A, N, profile=xi).profile
        J_axis = res[i, layout.R_J_AXIS]
        u = (eps * K + prof[i, layout.P_J]) / (eps * K + J_axis)
        np.testing.assert_allclose(u, want["u_over_u0"], rtol=1e-12)
        np.testing.assert_allclose(prof[i, layout.P_OMEGA_HAT], want["omega_hat"], rtol=1e-12)
        np.testing.assert_allclose(L * (prof[i, layout.P_DELTA] - N), want["m"], rtol=1e-12)
        np.testing.assert_allclose(prof[i, layout.P_SIGMA_YX], want["sigma_yx"], rtol=1e-12)


@pytest.mark.parametrize("rtol", [1e-8, 1e-10, 1e-12])
def test_at_the_path_edge_any_tolerance_never_integration_failed(rtol):
    """1e-6 inside the path edge (D(1) ~ 1e-11): ok or eps_too_large_path at the wall, never integration_failed."""
    A, N, L = 0.0, 2.0, 10.0
    eps = 3.7415412700 / L * (1 - 1e-6)  # edge eta_max traced at rtol 1e-12
    r = solve_point(eps, L, 0.5, A, N, rtol=rtol, atol=1e-14)
    assert r.status in (st.Status.ok, st.Status.eps_too_large_path)
    if r.status == st.Status.eps_too_large_path:
        assert r.xi_stop == 1.0  # D = 0 at the wall within the solver's resolution
    else:
        assert math.isfinite(r.Delta)


def test_default_workspace_is_reused_without_carrying_state():
    """Calls without a workspace share one per thread: a point's values and counters do not
    depend on what the thread solved before, nor on which thread solves it."""
    from concurrent.futures import ThreadPoolExecutor

    from cosserat_channel.solver.point import Workspace

    points = [(1 / 30, 10, 0.5, 1 / 3, 1), (0.2, 3, 0.1, -0.5, 0.4), (0.3, 9.0, 0.0, 2.0, 2.0),
              (1e-3, 1.0, 5.0, 0.0, 1.0)]

    def key(r):
        return (r.status, r.counters, {k: v for k, v in r.values.items() if not math.isnan(v)},
                sorted(k for k, v in r.values.items() if math.isnan(v)))

    fresh = [key(solve_point(*p, workspace=Workspace())) for p in points]
    assert [key(solve_point(*p)) for p in points + points[::-1]] == fresh + fresh[::-1]
    with ThreadPoolExecutor(2) as pool:
        assert list(pool.map(lambda p: key(solve_point(*p)), points * 3)) == fresh * 3


@pytest.mark.slow
def test_a_point_compiles_only_the_integrators_it_marches_with(tmp_path, monkeypatch):
    """On an empty kernel cache, a point on the explicit path at the default rtol compiles DOP853
    alone, neither Dormand-Prince nor RODAS4P2; a point on the stiff path then adds RODAS4P2, and
    the first point solved again through that entry gives the same bits."""
    from support import run_python

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # a fresh interpreter: every kernel compiles
    code = """if True:
        import json
        import cosserat_channel as cc
        from cosserat_channel.solver import stage1

        def compiled():  # signatures of Dormand-Prince's, DOP853's and RODAS4P2's march
            return [len(f.signatures) for f in (stage1._march_dopri5, stage1._march_dop853,
                                                 stage1._march_rodas)]

        first = cc.solve_point(1 / 30, 10, 0.5, 1 / 3, 1)
        after_first = compiled()
        stiff = cc.solve_point(1e-4, 1, 0.5, 1 / 3, 1)
        after_stiff = compiled()
        again = cc.solve_point(1 / 30, 10, 0.5, 1 / 3, 1)
        print(json.dumps([first.counters["stage1_path"], stiff.counters["stage1_path"], after_first,
                          after_stiff, first.status.name, again.to_dict() == first.to_dict()]))
    """
    assert json.loads(run_python(code)) == ["explicit", "stiff", [0, 1, 0], [0, 1, 1], "ok", True]


# The stiff path where the wall sits at the end of the slow manifold (N = 1, small eta): the
# outputs read N - delta, which is ~eta^(1/3) of delta there (stage1.TURN_KAPPA).
STIFFEST = [(eta, A, N) for eta in (1e-6, 6e-6, 3e-5) for A, N in ((1 / 3, 1.0), (-0.5, 1.0))] + [
    (6e-6, 1.0, 1.0),  # A = 1
    (1e-4, 1 / 3, 1.003),  # N just above 1: a smaller amplification, the turn still inside the layer
]


@pytest.mark.parametrize("eta, A, N", STIFFEST, ids=[str(p) for p in STIFFEST])
@pytest.mark.parametrize("rtol", [1e-5, 1e-6])
def test_stiffest_points_every_output_within_100_rtol(eta, A, N, rtol):
    """At loose rtol every output of the stiffest points is within 100 rtol of scipy's Radau at
    rtol 1e-12 (before the turn was marched again, Delta was up to ~1000 rtol off at rtol 1e-6)."""
    L, K = 10.0, 0.5
    eps = eta / L
    ours = solve_point(eps, L, K, A, N, rtol=rtol)
    ref = reference(eps, L, K, A, N, method="Radau")
    assert ours.ok and ref["status"] == "ok"
    for name in ("Delta", "xi_p", "slip", "u_axis", "m_wall", "sigma_yx_wall"):
        assert getattr(ours, name) == pytest.approx(ref[name], rel=100 * rtol), name


A_MINUS_ONE_GRID = [(eta, N) for eta in (1e-12, 1e-11, 5.6e-10, 1e-8) for N in (1.0, 1e3, 1e4, 1e6)]


@pytest.mark.parametrize("eta, N", A_MINUS_ONE_GRID, ids=[str(p) for p in A_MINUS_ONE_GRID])
def test_A_minus_one_at_any_exponent_is_the_closed_form(eta, N):
    """A = -1 is always solvable: up to c = 2N/eta = 2e18, where omega_hat = xi^c falls within
    1e-18 of the wall, solve_point gives Appendix A's closed form (it gave integration_failed
    for N >= 1e3 at eta <= 5.6e-10). K = 0 has a shear layer of 3/c, K = 0.5 a plug up to the
    wall wherever eps K > 19 J(0)."""
    L = 1.0
    eps = eta / L
    for K in (0.0, 0.5):
        r = solve_point(eps, L, K, -1.0, N)
        cf = asymptotics.a_minus_one_outputs(eps, L, K, N)
        assert r.status == st.Status.ok, (K, r.status)
        assert r.Delta == pytest.approx(cf.Delta, rel=1e-6, abs=0.0)
        assert r.xi_p == pytest.approx(cf.xi_p, rel=1e-12)
        assert r.u_axis == pytest.approx(cf.u_axis, rel=1e-6)
        assert r.slip == pytest.approx(cf.slip, rel=1e-6, abs=1e-300)
        assert r.m_wall == pytest.approx(-N * L) and r.sigma_yx_wall == -1.0
