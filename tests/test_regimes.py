"""Solvability: phase-plane data, the traced edge eta_max(A, N), and the analytic regime lines."""

import math

import numpy as np
import pytest

from cosserat_channel.physics import analytic, model
from cosserat_channel import regimes
from cosserat_channel import status as st
from cosserat_channel.parameters import PARAMETERS, ParameterError
from cosserat_channel.solver.point import Workspace, solve_point
from cosserat_channel.sweep import run_sweep

# (A, N) with a bounded edge, one per region of interest.
BOUNDED = [
    (1 / 3, 1.0),  # the paper's A with a fully rough wall (Appendix A: eps = 0.33 at L = 10)
    (-0.5, 1.0),  # A between -1 and 0
    (0.9, 2.0),  # close to A = 1, smoother wall
]


@pytest.fixture(scope="module")
def edges():
    """Traced edges of the BOUNDED cases."""
    return {an: regimes.trace_edge(*an) for an in BOUNDED}


@pytest.mark.parametrize("A,N", BOUNDED)
def test_traced_edge_agrees_with_direct_solves(edges, A, N):
    """solve_point is ok at eta_max (1 - 1e-6) and not ok at eta_max (1 + 1e-6)."""
    e = edges[(A, N)]
    assert e.kind == regimes.EDGE_BOUNDED and e.monotone
    L = max(10.0, 2.0 * e.eta_max)  # keeps eps <= 1/2
    d = max(1e-6, 2.0 * e.bands[-1])  # outside the band where the status is noise
    inside = solve_point(e.eta_max * (1 - d) / L, L, 0.5, A, N, rtol=1e-10, atol=1e-14)
    outside = solve_point(e.eta_max * (1 + d) / L, L, 0.5, A, N, rtol=1e-10, atol=1e-14)
    assert inside.ok
    assert not outside.ok
    # At the solver's default tolerance the edge holds to ~1e-5 (see regimes.EDGE_RTOL).
    assert solve_point(e.eta_max * (1 - 1e-5) / L, L, 0.5, A, N).ok
    assert not solve_point(e.eta_max * (1 + 1e-5) / L, L, 0.5, A, N).ok


def test_paper_appendix_a_edge(edges):
    """A = 1/3, N = 1: eta_max in (3.30, 3.35) (eps 0.33 feasible, 0.335 not at L = 10)."""
    e = edges[(1 / 3, 1.0)]
    assert 3.30 < e.eta_max < 3.35
    assert e.status_above == st.EPS_TOO_LARGE_PATH


def test_edge_below_axis_condition(edges):
    """For A < 1 the path fails before the axis edge 2(A+1)N/(1-A)."""
    for (A, N), e in edges.items():
        assert e.eta_max < float(regimes.axis_edge_eta(A, N))


def test_bisection_bracket_width():
    """The bracket is 1e-10 relative: a second trace with another coarse grid agrees to ~1e-9."""
    a = regimes.trace_edge(0.0, 1.0)
    b = regimes.trace_edge(0.0, 1.0, n_coarse=17)
    assert abs(a.eta_max - b.eta_max) <= 1e-9 * a.eta_max


def test_bisect_edge_on_a_known_predicate():
    """The bracket holds the change, is xtol wide, and keeps the ends' sides (upper and lower edge)."""
    calls = []

    def below_pi(eta):
        calls.append(eta)
        return eta < math.pi

    lo, hi = regimes.bisect_edge(below_pi, 1e-3, 50.0, 1e-12)
    assert lo < math.pi <= hi and hi / lo - 1 <= 1e-12
    # Log-space halving: log2(log(5e4) / 1e-12) ~ 43 calls, whatever the span in decades.
    assert len(calls) <= math.ceil(math.log2(math.log(5e4) / 1e-12)) + 1
    lo, hi = regimes.bisect_edge(lambda eta: eta > 0.5, 0.01, 10.0, 1e-10, feasible_lo=False)
    assert lo <= 0.5 < hi and hi / lo - 1 <= 1e-10


@pytest.mark.parametrize("A,N,kind", [
    (-2.0, 1.0, regimes.EDGE_NONE),  # A < 1 - 2N^2: wall inadmissible
    (-1.5, 2.0, regimes.EDGE_NONE),  # 1 - 2N^2 <= A < -1: axis spin unbounded
    (-1.0, 1.0, regimes.EDGE_UNBOUNDED),  # A = -1: closed form for every eta
    (1.0, 1.0, regimes.EDGE_UNBOUNDED),  # A = 1: ok up to eta = 100
])
def test_edge_kinds(A, N, kind):
    """Regimes without an edge inside (0, 100] are flagged, with eta_max = 100 when unbounded."""
    e = regimes.trace_edge(A, N)
    assert e.kind == kind
    if kind == regimes.EDGE_UNBOUNDED:
        assert e.eta_max == regimes.ETA_SEARCH_MAX
        assert solve_point(1.0, 100.0, 0.5, A, N).ok
    else:
        assert math.isnan(e.eta_max)


def test_non_monotone_feasibility_found():
    """A = 3, N = 0.5: small eta fails, large eta is ok; the trace reports the lower edge."""
    e = regimes.trace_edge(3.0, 0.5)
    assert e.kind == regimes.EDGE_UNBOUNDED
    assert 0.01 < e.eta_min < 1.0
    assert not solve_point(e.eta_min * (1 - 1e-5) / 10, 10, 0.5, 3.0, 0.5).ok
    assert solve_point(e.eta_min * (1 + 1e-5) / 10, 10, 0.5, 3.0, 0.5).ok


def test_monotone_assumption_on_fine_grid():
    """For A = 1/3, N = 1 a 200-point scan sees exactly the one change that trace_edge reports."""
    e = regimes.trace_edge(1 / 3, 1.0)
    etas = np.geomspace(1e-3, 3.9, 200)
    ok = np.array([solve_point(x / 10, 10, 0.5, 1 / 3, 1.0).ok for x in etas])
    changes = np.flatnonzero(ok[1:] != ok[:-1])
    assert changes.size == 1
    assert etas[changes[0]] <= e.eta_max <= etas[changes[0] + 1]


def test_trace_boundary_dataset():
    """trace_boundary returns eta_max on (A, N) with flag attributes and the axis edge."""
    ds = regimes.trace_boundary([-2.0, 0.0, 1 / 3, 2.0], [1.0])
    assert ds["eta_max"].dims == ("A", "N")
    kinds = ds["edge_kind"].values[:, 0]
    assert list(kinds) == [regimes.EDGE_NONE, regimes.EDGE_BOUNDED, regimes.EDGE_BOUNDED,
                           regimes.EDGE_UNBOUNDED]
    assert ds["edge_kind"].attrs["flag_meanings"].split() == list(regimes.EDGE_KINDS)
    assert ds["axis_edge_eta"].sel(A=0.0, N=1.0) == pytest.approx(2.0)


@pytest.mark.parametrize("call, named", [
    (lambda: regimes.trace_edge(0.0, -1.0), "N"),
    (lambda: regimes.trace_edge(5000.0, 1.0), "A"),
    (lambda: regimes.trace_edge(-1e3 * (1 + 1e-15), 1.0), "A"),
    (lambda: regimes.trace_edge(0.0, 1e300), "N"),
    (lambda: regimes.trace_edge(math.nan, 1.0), "A"),
    (lambda: regimes.trace_boundary([0.0, 5000.0], [1.0]), "A"),
    (lambda: regimes.trace_boundary([0.0], [1.0, 1e300]), "N"),
    (lambda: regimes.phase_plane(0.03, 10.0, 5000.0, 1.0), "A"),
    (lambda: regimes.phase_plane(0.03, 10.0, 0.3, 1e300), "N"),
])
def test_entry_points_refuse_parameters_outside_their_range(call, named):
    """Every entry point checks through parameters.py, before any solve: the message names the
    parameter and the interval defined there."""
    with pytest.raises(ParameterError) as info:
        call()
    message = str(info.value)
    assert message.startswith(f"{named} = ") and PARAMETERS[named].interval in message


@pytest.mark.parametrize("eta_range", [(1.0, 0.5), (1e-20, 1.0), (1.0, 1e300), (0.0, 1.0),
                                       (math.nan, 1.0), ("a", 1.0)])
def test_trace_refuses_an_eta_range_the_solver_does_not_resolve(eta_range):
    with pytest.raises(ParameterError, match="eta_range"):
        regimes.trace_edge(0.0, 1.0, eta_range=eta_range)
    with pytest.raises(ParameterError, match="eta_range"):
        regimes.trace_boundary([0.0], [1.0], eta_range=eta_range)


def test_trace_accepts_the_ends_of_the_ranges():
    """The ends of A's and N's intervals are inside (closed): they trace without overflow."""
    for A, N in ((PARAMETERS["A"].lo, 1.0), (PARAMETERS["A"].hi, 1.0),
                 (0.0, PARAMETERS["N"].hi)):
        e = regimes.trace_edge(A, N, n_coarse=4)
        assert e.kind in (regimes.EDGE_BOUNDED, regimes.EDGE_UNBOUNDED, regimes.EDGE_NONE)


@pytest.fixture(scope="module")
def fine_sweep():
    """A fine (A, N) sweep at eps = 1/30, L = 10 (eta = 1/3)."""
    return run_sweep({"grid": {"eps": 1 / 30, "L": 10, "K": 0.5,
                               "A": {"linspace": [-3, 3, 121]},
                               "N": {"linspace": [0.3, 3, 55]}}}, workers=2)


def test_analytic_lines_match_status_changes(fine_sweep):
    """wall_inadmissible exactly below A = 1 - 2N^2, axis_spin_unbounded exactly in
    [1 - 2N^2, -1), eps_too_large_axis exactly where (A-1) eta + 2(A+1)N <= 0 (A > -1)."""
    s = fine_sweep["status"].squeeze().transpose("A", "N").values
    A = fine_sweep["A"].values[:, None]
    N = fine_sweep["N"].values[None, :]
    eta = 1 / 30 * 10
    wall = A < 1 - 2 * N**2
    spin = ~wall & (A < -1)
    axis = ~wall & (A > -1) & ((A - 1) * eta + 2 * (A + 1) * N <= 0)
    np.testing.assert_array_equal(s == st.WALL_INADMISSIBLE, wall)
    np.testing.assert_array_equal(s == st.AXIS_SPIN_UNBOUNDED, spin)
    np.testing.assert_array_equal(s == st.EPS_TOO_LARGE_AXIS, axis)
    assert wall.any() and spin.any() and axis.any()


def test_traced_edge_matches_path_statuses(fine_sweep):
    """Where A is in (-1, 1) and the axis condition holds, ok exactly where eta < eta_max(A, N)."""
    # A from -0.95 to 0.9 in steps of 0.3, N = 0.8, 1.0, 2.0.
    sub = fine_sweep.isel(A=slice(41, 80, 6), N=[10, 14, 34])
    bds = regimes.trace_boundary(sub["A"].values, sub["N"].values)
    eta = 1 / 30 * 10
    s = sub["status"].squeeze().transpose("A", "N").values
    em = bds["eta_max"].values
    candidate = (bds["edge_kind"].values == regimes.EDGE_BOUNDED) & (s != st.EPS_TOO_LARGE_AXIS)
    assert candidate.sum() >= 5
    np.testing.assert_array_equal((s == st.OK)[candidate], (eta < em)[candidate])


def test_phase_plane_figure12():
    """Figure 12: E+ from -NL meets D = 0 before the wall, E- from -NL reaches the wall with the
    solver's m(1), E+ cannot leave +NL; D = 0 and nullcline curves are the analytic ones."""
    pp = regimes.phase_plane(1 / 30, 10, 1 / 3, 1)
    tr = {(t.root, t.start < 0): t for t in pp.trajectories}
    assert tr[("+", True)].end == "D=0" and 0.2 < tr[("+", True)].xi[-1] < 0.9
    assert tr[("+", False)].end == "no_start"
    em = tr[("-", True)]
    assert em.end == "wall"
    r = solve_point(1 / 30, 10, 0.5, 1 / 3, 1)
    assert em.m[-1] == pytest.approx(r.m_wall, rel=1e-5)
    # D = 0 on the curve, sqrt(D) = (A+1) xi on the nullcline.
    xi = pp.xi[::20]
    assert np.allclose(regimes.yield_D(xi, regimes.d_zero_curve(xi, 10, 1 / 3, 1), 10, 1 / 3, 1),
                       0, atol=1e-9)
    nc = regimes.nullcline_curve(xi, 10, 1)
    ok = np.isfinite(nc)
    D = regimes.yield_D(xi[ok], nc[ok], 10, 1 / 3, 1)
    assert np.allclose(np.sqrt(D), (4 / 3) * xi[ok], atol=1e-9)
    # Sign regions: E+ >= 0 wherever D >= 0 (A > -1), as Appendix A argues.
    assert np.all(pp.E_plus[pp.D >= 0] >= -1e-12)
    assert set(np.unique(pp.region)) <= {regimes.REGION_D_NEGATIVE, regimes.REGION_EP_POS_EM_NEG,
                                         regimes.REGION_EM_POS}


def test_series_root_is_models_axis_root():
    """For E- from -NL the series coefficient is eq:20's smaller root (model.axis_constants)."""
    eps, L, A, N = 1 / 30, 10.0, 1 / 3, 1.0
    x = regimes._series_coefficient(eps, L, A, N, "-", -1.0)
    ax = np.empty(model.N_AX)
    model.axis_constants(eps * L, A, N, ax)
    assert x / L == pytest.approx(ax[model.AX_Y], rel=1e-12)


def _scipy_D_wall(eta, A, N):
    """D(1) of an independent stage 1: scipy's DOP853 at rtol 1e-13 from next to the axis."""
    from scipy.integrate import solve_ivp

    from cosserat_channel.solver import stage1

    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    xi1, w1 = stage1.ivp_start(ax)
    sol = solve_ivp(lambda x, w: [model.dw_dxi(x, w[0], eta, A, N, ax)], [xi1, 1.0], [w1],
                    method="DOP853", rtol=1e-13, atol=1e-16)
    return model.yield_D(1.0, sol.y[0, -1], A, N, ax)


def _zero_of_sqrt_D(d, D, rho):
    """Where sqrt(D) extrapolates to zero, relative to the eta that ``d`` is measured from.

    ``d``: relative distances below that eta. Least squares of sqrt(D) on 1, d, d^2 and d^rho
    (rho of the node: regimes.node_edge_eta); returns sqrt(D) at d = 0 over its slope, i.e. how far
    (relative) the zero lies beyond d = 0. The d^rho term is what a node adds to the linear fall
    of sqrt(D): without it a polynomial extrapolation is biased by ~1e-8 where rho < 2.
    """
    u = d / d[-1]
    basis = np.array([np.ones_like(u), u, u**2, u**rho]).T
    c, *_ = np.linalg.lstsq(basis, np.sqrt(D), rcond=None)
    return c[0] / c[1] * d[-1]


# Nodes at the wall (N^2 > (5 + 3A)/2), from deep inside (ratio 15) to near the focus (ratio 1.5).
NODE_CASES = [(0.0, 2.0), (-0.5, 1.5), (0.5, 2.5), (0.0, 3.0), (-0.27, 1.47)]


@pytest.mark.parametrize("A,N", NODE_CASES)
def test_tangential_edge_against_an_independent_stage_1(A, N):
    """At a tangential edge trace_edge reports the node's eta. Independently of our solver,
    scipy's DOP853 at rtol 1e-13 gives D(1) 1e-5..1e-4 (relative) below it: D(1) falls like the
    square of the distance (local power 2 within 2 %), and sqrt(D(1)) extrapolates to zero within
    5e-9 of eta_max. The status bisection alone ends up to ~1e-6 away (its noise band)."""
    e = regimes.trace_edge(A, N)
    assert e.kind == regimes.EDGE_BOUNDED and e.tangential.tolist() == [True]
    d = np.geomspace(1e-5, 1e-4, 8)
    D = np.array([_scipy_D_wall(e.eta_max * (1 - x), A, N) for x in d])
    power = math.log(D[-1] / D[0]) / math.log(d[-1] / d[0])
    assert abs(power - 2.0) < 0.04
    zero = _zero_of_sqrt_D(d, D, regimes.node_edge_eta(A, N)[2])
    assert abs(zero) < 5e-9, zero
    old = regimes.trace_edge(A, N, tangential=False)
    assert abs(old.eta_max / e.eta_max - 1.0) < 2 * e.bands[-1]


def test_node_edge_eta_is_the_singular_point_at_the_wall():
    """At eta_node the point of D(1) = 0 with delta = N - (1-A) eta/(2(A+1)) has dD/dxi = 0 along
    the flow with sqrt(D) = 0 (finite differences of regimes.yield_D, independent of the algebra);
    node and focus switch where N^2 = (5 + 3A)/2."""
    for A, N in [(0.0, 2.0), (-0.5, 1.5), (0.7, 3.0), (0.09, 1.5)]:
        eta, node, ratio = regimes.node_edge_eta(A, N)
        L = 1.0
        mu = -(1 - A) * eta / (2 * (A + 1))  # m/(nu L) = delta - N
        assert abs(regimes.yield_D(1.0, mu * L, L, A, N)) < 1e-13
        h = 1e-6
        # d(delta)/dxi = (A+1) xi / eta where sqrt(D) = 0
        dD = (regimes.yield_D(1 + h, (mu + h * (A + 1) / eta) * L, L, A, N)
              - regimes.yield_D(1 - h, (mu - h * (A + 1) / eta) * L, L, A, N)) / (2 * h)
        assert abs(dD) < 1e-8
        assert node == (N * N > (5 + 3 * A) / 2)
        assert (ratio > 1.0) if node else math.isnan(ratio)
    assert math.isnan(regimes.node_edge_eta(1.5, 2.0)[0])  # A > 1: no upper node
    assert math.isnan(regimes.node_edge_eta(0.0, 0.5)[0])  # below the wall line


def test_node_focus_switch_is_where_the_linearisation_turns_from_node_to_focus():
    """On the curve N = node_focus_switch_N(A) the linearisation at eta_node (ds/dtau = 2z,
    dz/dtau = -Phi s - gamma z) has a double eigenvalue, gamma^2 = 8 Phi; just above it two real
    ones (node, with node_edge_eta's ratio of them), just below a complex pair (focus)."""
    for A in np.linspace(-0.95, 0.95, 39):
        Ns = analytic.node_focus_switch_N(A)
        for N, node in ((Ns * (1 - 1e-6), False), (Ns, None), (Ns * (1 + 1e-6), True)):
            eta, is_node, ratio = regimes.node_edge_eta(A, N)
            gamma, Phi = 2 * (1 - A), 4 * (A + 1) ** 3 / eta**2
            if node is None:
                assert abs(gamma**2 - 8 * Phi) < 1e-12 * gamma**2
                continue
            assert is_node == node == (gamma**2 > 8 * Phi)
            if node:
                lam = np.sort(np.abs(np.roots([1.0, gamma, 2 * Phi])))
                assert ratio == pytest.approx(lam[1] / lam[0], rel=1e-6)
    assert math.isnan(analytic.node_focus_switch_N(1.2))
    assert math.isnan(analytic.node_focus_switch_N(-1.2))


@pytest.mark.parametrize("A,N", [(1 / 3, 1.0), (-0.9, 1.0)])
def test_transversal_edges_keep_the_status_bisection(A, N):
    """At a focus (N^2 < (5 + 3A)/2) away from the switch the edge is the status bisection's,
    identical to a trace without probes, above the singular point's eta; scipy's D(1) there is
    not quadratic (local power below 1.9) and its own root is within 1e-8 of it."""
    from scipy.optimize import brentq

    e = regimes.trace_edge(A, N)
    old = regimes.trace_edge(A, N, tangential=False)
    assert not e.tangential.any() and not e.smooth.any() and e.eta_max == old.eta_max
    assert e.eta_max > regimes.node_edge_eta(A, N)[0] * (1 + 1e-6)
    d = np.array([1e-5, 1e-4])
    D = np.array([_scipy_D_wall(x, A, N) for x in e.eta_max * (1 - d)])
    assert math.log(D[1] / D[0]) / math.log(10.0) < 1.9
    root = brentq(lambda x: _scipy_D_wall(x, A, N), e.eta_max * (1 - 1e-6), e.eta_max * (1 + 1e-6),
                  xtol=1e-15)
    assert abs(root / e.eta_max - 1) < 1e-8


@pytest.mark.parametrize("A,N", [(0.0, 2.0), (0.0, 3.0), (-0.1, 1.5), (0.9, 2.5)])
def test_noise_band_holds_the_flipping_statuses(A, N):
    """The solver's status disagrees with the traced edge only within the stated band: 150
    random eta within 3 bands (at least 2e-6) of it, at tangential edges and at a transversal one
    next to the node/focus switch (-0.1, 1.5), where D(1) also rises slowly."""
    e = regimes.trace_edge(A, N)
    band = e.bands[-1]
    assert 1e-8 < band < 1e-5
    rng = np.random.default_rng(7)
    w = max(2e-6, 3 * band)
    rel = rng.uniform(-w, w, 150)
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    ok = np.array([ws.status(e.eta_max * (1 + r), A, N, regimes.EDGE_RTOL, regimes.EDGE_ATOL)
                   == st.OK for r in rel])
    wrong = (ok & (rel > 0)) | (~ok & (rel < 0))
    assert np.all(np.abs(rel[wrong]) <= band)


def test_probe_edge_on_synthetic_wall_values(monkeypatch):
    """probe_edge on made-up D(1): quadratic (with a cubic term) gives the zero to round-off,
    power 2 and the band sqrt(noise / c); linear gives power ~1 and the band noise / a."""
    eta0, delta = 2.0, 0.3
    sens = 4.0 * 1.0 * abs(2.0 - delta) * delta  # A = 0, N = 2

    def fake(D_of):
        def wall_D(ws, etas, A, N, rtol=0, atol=0):
            etas = np.asarray(etas, dtype=float)
            return (np.zeros(etas.size, np.int8), D_of(etas), np.full(etas.size, delta))
        return wall_D

    noise = regimes.D_NOISE * 1e-13 * sens
    x = lambda eta: eta0 / eta - 1  # noqa: E731  (relative distance below eta0, ~)
    monkeypatch.setattr(regimes.wall, "wall_D", fake(lambda e: 0.1 * x(e) ** 2 * (1 + 3 * x(e))))
    p = regimes.probe_edge(None, eta0 * (1 - 2e-7), -1, 0.0, 2.0)
    assert abs(p.root3 / eta0 - 1) < 1e-11 and abs(p.root2 / eta0 - 1) < 1e-7
    assert abs(p.exponent - 2) < 0.01
    assert p.band == pytest.approx(math.sqrt(noise / 0.1), rel=0.05)
    monkeypatch.setattr(regimes.wall, "wall_D", fake(lambda e: 1e-3 * x(e)))
    p = regimes.probe_edge(None, eta0 * (1 - 2e-7), -1, 0.0, 2.0)
    assert abs(p.exponent - 1) < 0.05
    assert p.band == pytest.approx(noise / 1e-3, rel=0.5)
    monkeypatch.setattr(regimes.wall, "wall_D", fake(lambda e: -x(e)))  # not ok: no probe
    assert regimes.probe_edge(None, eta0, -1, 0.0, 2.0) is None


def _scipy_D_state_wall(eta, A, N, xi_switch=0.8):
    """D(1) of an independent march that carries D as a state next to the wall: scipy's DOP853
    at rtol 1e-13 from next to the axis (stage1.ivp_start) in w to ``xi_switch``, then in
    (delta, D) with D' = F - (D_delta/eta) sqrt(D) (node_edge_eta's algebra), to the wall."""
    from scipy.integrate import solve_ivp

    from cosserat_channel.solver import stage1

    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    xi1, w1 = stage1.ivp_start(ax)
    sol = solve_ivp(lambda x, w: [model.dw_dxi(x, w[0], eta, A, N, ax)], [xi1, xi_switch], [w1],
                    method="DOP853", rtol=1e-13, atol=1e-16)
    d0 = xi_switch**2 * sol.y[0, -1]
    a1 = A + 1

    def f(x, y):
        d, D = y
        s = math.sqrt(max(D, 0.0))
        F = 2 * a1 * x * ((A - 1) + 2 * a1 * (N - d) / eta)
        return [(a1 * x - s) / eta, F - 4 * a1 * (N - d) * s / eta]

    sol = solve_ivp(f, [xi_switch, 1.0], [d0, model.yield_D(xi_switch, d0, A, N, ax)],
                    method="DOP853", rtol=1e-13, atol=[1e-16, 1e-30])
    return sol.y[1, -1], model.yield_D(1.0, sol.y[0, -1], A, N, ax)


# Transversal edges next to the node/focus switch N^2 = (5 + 3A)/2 (focus side), where D(1) rises
# slowly and the status is noise over 1e-7..1e-6; (-0.265, 1.415) was bench_atlas's worst. One on
# each side of A = 0: a point between them, (-0.1, 1.5), takes the same path for a minute more.
SWITCH_CASES = [(-0.265, 1.415), (0.09, 1.5)]


# The first takes about 30 s (the independent stage 1 resolves D(1) ~ 1e-8): slow.
@pytest.mark.parametrize("A,N", [pytest.param(*SWITCH_CASES[0], marks=pytest.mark.slow),
                                 SWITCH_CASES[1]])
def test_smooth_edge_against_an_independent_stage_1(A, N):
    """Next to the switch trace_edge reports the zero of the smooth D(1). An independent march
    (scipy DOP853, D carried as a state from xi = 0.8) has D(1) > 0 1e-9 (relative) below it and
    D(1) ~ 0 (the path met D = 0) 1e-9 above it, so the zero is within 1e-9 of the model's edge;
    the status bisection alone ends up to its noise band away. Far from the edge the carried D(1)
    equals the model's D(delta(1)) (so it is the same function), and our smooth D(1) agrees with
    scipy's to 1e-3 relative 1e-6 below the edge, where D(1) ~ 1e-12."""
    e = regimes.trace_edge(A, N)
    assert e.kind == regimes.EDGE_BOUNDED and e.smooth.tolist() == [True]
    assert not e.tangential.any()
    below, _ = _scipy_D_state_wall(e.eta_max * (1 - 1e-9), A, N)
    above, _ = _scipy_D_state_wall(e.eta_max * (1 + 1e-9), A, N)
    assert below > 1e-17 and abs(above) < 1e-4 * below, (below, above)
    carried, from_delta = _scipy_D_state_wall(e.eta_max * (1 - 1e-4), A, N)
    assert abs(carried - from_delta) < 1e-12 * max(1.0, abs(from_delta)) + 1e-13
    ref, _ = _scipy_D_state_wall(e.eta_max * (1 - 1e-6), A, N)
    ours = regimes.smooth_wall_D(e.eta_max * (1 - 1e-6), A, N)
    assert ref > 0 and abs(ours / ref - 1) < 1e-3
    assert regimes.smooth_wall_D(e.eta_max * (1 + 1e-6), A, N) < 0
    old = regimes.trace_edge(A, N, tangential=False)
    assert abs(old.eta_max / e.eta_max - 1.0) <= e.bands[-1]
    assert e.eta_max > regimes.node_edge_eta(A, N)[0]


def test_smooth_wall_D_is_smooth_in_eta():
    """Across 4e-8 (relative) about the edge at (-0.265, 1.415) the smooth D(1) is monotone and
    within 1e-15 of a cubic in eta (stage 1's D(1), regimes.wall_D, has a noise of ~1e-13).
    It changes sign within the 4e-8."""
    A, N = SWITCH_CASES[0]
    e = regimes.trace_edge(A, N)
    r = np.linspace(-2e-8, 2e-8, 21)
    v = np.array([regimes.smooth_wall_D(e.eta_max * (1 + x), A, N) for x in r])
    assert np.all(np.diff(v) < 0)
    fit = np.polyval(np.polyfit(r / 1e-8, v, 3), r / 1e-8)
    assert np.max(np.abs(v - fit)) < 1e-15
    assert v[0] > 0 > v[-1]


# ---------------------------------------------------------------------------------------------
# Continuation: a transition predicted from a neighbour, corrected on the smooth D(1)
# ---------------------------------------------------------------------------------------------
class _Count:
    """Workspace stand-in that counts stage-1 marches (status solves and regimes' own)."""

    def __init__(self):
        self.ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
        self.solves = 0

    def status(self, *args):
        self.solves += 1
        return self.ws.status(*args)

    def count(self, n):
        self.solves += n


def _reference_ok(eta, A, N):
    """Status of an independent scipy solve (reference.py, rtol 1e-12) at eta: ok or not."""
    from cosserat_channel.physics.reference import reference

    L = max(10.0, 4.0 * eta)
    return reference(eta / L, L, 0.5, A, N, method="Radau", status_only=True)["status"] == "ok"


@pytest.mark.parametrize("A,N,k", [(1 / 3, 1.0, 0), (2.0, 0.6, 0), (0.25, 0.85, 0),
                                   (0.25, 0.85, 1)])
def test_corrector_on_a_transversal_edge_against_an_independent_solver(A, N, k):
    """Continued from a neighbour 0.002 away in A and N, each transition agrees with a fresh status
    bisection to 1e-8 (its edge holds to ~1e-8 at regimes.EDGE_RTOL) and an independent scipy
    solver (rtol 1e-12) has a solution 1e-8 (relative) on its ok side and none 1e-8 beyond it:
    upper edges (ok below) and lower ones (ok above) alike."""
    near = regimes.trace_edge(A + 0.002, N + 0.002)
    low, guesses = regimes.guesses_from(near, spread=0.05)
    c = regimes.continue_edge(A, N, low, guesses, workspace=_Count())
    fresh = regimes.trace_edge(A, N)
    assert c is not None and c.continued and c.transitions.size == fresh.transitions.size
    t = c.transitions[k]
    assert abs(t / fresh.transitions[k] - 1) < 1e-8
    ok_below = guesses[k].side == -1
    assert _reference_ok(t * (1 - 1e-8), A, N) == ok_below
    assert _reference_ok(t * (1 + 1e-8), A, N) != ok_below


def test_corrector_on_the_node_edge():
    """At a tangential edge the continued transition is the node's closed form, flagged so, and
    costs two checks of it and the low end's status."""
    A, N = 0.0, 2.0
    low, guesses = regimes.guesses_from(regimes.trace_edge(A + 0.02, N - 0.02))
    ws = _Count()
    c = regimes.continue_edge(A, N, low, guesses, workspace=ws)
    assert c.transitions.tolist() == [regimes.node_edge_eta(A, N)[0]]
    assert c.tangential.tolist() == [True] and ws.solves <= 5
    assert 3e-7 < c.bands[0] < 1e-5


def test_corrector_costs_few_marches_from_a_good_prediction():
    """From a prediction 1e-6 off with a slope, a transversal transition costs at most four
    marches, the status at the low end of the range one more; the root is bracketed to tau."""
    A, N = 1 / 3, 1.0
    fresh = regimes.trace_edge(A, N)
    low, guesses = regimes.guesses_from(regimes.continue_edge(
        A, N, *regimes.guesses_from(regimes.trace_edge(A + 1e-3, N)), workspace=_Count()))
    guesses[0].eta = fresh.eta_max * (1 + 1e-6)
    ws = _Count()
    c = regimes.continue_edge(A, N, low, guesses, workspace=ws, tau=1e-9)
    assert ws.solves <= 5
    assert abs(c.eta_max / fresh.eta_max - 1) < 1e-8


def test_corrector_closes_from_a_prediction_thirty_percent_off():
    """A lower edge predicted 30 % low (a coarse interpolant next to N = 1) with a neighbour's
    slope is still corrected, within regimes.CORRECT_MAX_EVALS marches, to the fresh trace's
    transition (1e-8), not handed back to a fresh trace."""
    A, N = 0.25, 0.942
    fresh = regimes.trace_edge(A, N)
    assert fresh.transitions.size == 2
    t = fresh.transitions[0]
    guess = regimes.Guess(0.7 * t, 1, 0.05, 40.4)
    ws = _Count()
    c = regimes.correct_transition(ws, A, N, guess, tau=1.25e-9)
    assert c is not None and not c.outside
    assert ws.solves <= regimes.CORRECT_MAX_EVALS
    assert abs(c.eta / t - 1) < 1e-8


def test_a_wrong_prediction_is_never_accepted():
    """A prediction with a transition too many, or on the wrong side, is rejected by the
    corrector or the checks of the range's ends; trace_edge then traces afresh."""
    A, N = 1 / 3, 1.0
    fresh = regimes.trace_edge(A, N)
    t = fresh.eta_max
    wrong = [
        (True, [regimes.Guess(0.01, 1), regimes.Guess(0.02, -1), regimes.Guess(t, -1)]),
        (False, [regimes.Guess(t, 1)]),
        (True, []),
    ]
    for low, guesses in wrong:
        assert regimes.continue_edge(A, N, low, guesses) is None
        e = regimes.trace_edge(A, N, prediction=(low, guesses))
        assert not e.continued and np.array_equal(e.transitions, fresh.transitions)


def test_a_prediction_of_no_solution_is_traced_afresh():
    """Below N = 1 solutions exist only in a window eta_min < eta < eta_max inside the range:
    a prediction of no transition and no solution at the low end passes both end checks (no
    solution at either end), so it is never accepted; the fresh trace finds the window."""
    A, N = 0.0, 0.98203125
    fresh = regimes.trace_edge(A, N)
    assert fresh.transitions.size == 2  # the window the ends cannot see
    assert regimes.continue_edge(A, N, False, []) is None
    e = regimes.trace_edge(A, N, prediction=(False, []))
    assert not e.continued and np.array_equal(e.transitions, fresh.transitions)
