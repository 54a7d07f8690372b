"""The equations of model.py against the paper's own forms and the facts model.md derives."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cosserat_channel.physics import model
from cosserat_channel import status as st

RNG = np.random.default_rng(20261121)


def _ax(eta, A, N):
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    return ax


def _random_admissible(n):
    """(eta, A, N) with A > -1 and the axis condition met."""
    out = []
    while len(out) < n:
        eta = 10 ** RNG.uniform(-4, 1.5)
        A = RNG.uniform(-0.95, 4.0)
        N = RNG.uniform(0.3, 5.0)
        if model.axis_margin(eta, A, N) > 0:
            out.append((eta, A, N))
    return out


def test_axis_condition_is_existence_of_the_admissible_root():
    """(A-1) eta + 2(A+1) N >= 0 exactly when eq:20 has a real root with eps x <= A+1 (model.md)."""
    for _ in range(4000):
        eps = 10 ** RNG.uniform(-4, 0)
        L = 10 ** RNG.uniform(-0.3, 2)
        A = RNG.uniform(-0.99, 5)
        N = RNG.uniform(0.3, 10)
        a, b, c = eps**2, -2 * (A + 1) * (eps + N / L), 2 * (A + 1)
        disc = b * b - 4 * a * c
        direct = disc >= 0 and eps * (-b - math.sqrt(disc)) / (2 * a) <= (A + 1) * (1 + 1e-12)
        margin = model.axis_margin(eps * L, A, N)
        if abs(margin) < 1e-9:  # skip points on the boundary itself
            continue
        assert direct == (margin >= 0), (eps, L, A, N)


def test_axis_series_root_and_cancellation_free_forms():
    """y solves eq:20 (scaled), c0 = A+1-eta*y and c0^2 = A^2-1+2(A+1)Ny hold."""
    for eta, A, N in _random_admissible(300):
        ax = _ax(eta, A, N)
        y, c0 = ax[model.AX_Y], ax[model.AX_C0]
        quad = eta**2 * y**2 - 2 * (A + 1) * (eta + N) * y + 2 * (A + 1)
        assert abs(quad) <= 1e-12 * max(1.0, 2 * (A + 1) * (eta + N) * y)
        assert c0 == pytest.approx(A + 1 - eta * y, rel=1e-9, abs=1e-12)
        assert c0**2 == pytest.approx(A * A - 1 + 2 * (A + 1) * N * y, rel=1e-8, abs=1e-12)
        assert eta * y <= A + 1 + 1e-12  # the root the paper keeps (eq:20)


def test_D_equals_the_papers_form():
    """yield_D is the polynomial of eq:a3 (scaled): (A^2-1) xi^2 + 2(A+1) delta (2N - delta)."""
    for eta, A, N in _random_admissible(200):
        ax = _ax(eta, A, N)
        for xi in (1e-3, 0.2, 0.7, 1.0):
            for delta in (0.0, 0.3 * N, 0.9 * N):
                paper = (A * A - 1) * xi * xi + 2 * (A + 1) * delta * (2 * N - delta)
                ours = model.yield_D(xi, delta, A, N, ax)
                assert ours == pytest.approx(paper, rel=1e-9, abs=1e-11 * (1 + abs(A * A - 1)))


def test_D_near_the_axis_edge_is_free_of_cancellation():
    """On the axis series D = (c0 xi)^2 to round-off even with c0 ~ 1e-8, where eq:a3 as printed fails."""
    A, N = 1 / 3, 1.0
    eta = 2 * (A + 1) * N / (1 - A) * (1 - 1e-8)  # just inside the axis edge
    ax = _ax(eta, A, N)
    c0 = ax[model.AX_C0]
    assert 0 < c0 < 1e-7
    xi = 1e-3 * c0  # well inside the series' radius (~c0)
    delta = model.delta_axis_series(xi, ax)
    ours = model.yield_D(xi, delta, A, N, ax)
    naive = (A * A - 1) * xi * xi + 2 * (A + 1) * delta * (2 * N - delta)
    exact = (c0 * xi) ** 2
    assert ours == pytest.approx(exact, rel=1e-6)
    assert abs(naive - exact) > 1e-3 * exact  # the printed form has lost the answer here


def test_quartic_axis_term_makes_the_series_an_order_more_accurate():
    """The series residual in e-61 is O(xi^5) with the quartic term (O(xi^3) without it)."""
    for eta, A, N in _random_admissible(50):
        ax = _ax(eta, A, N)
        res = []
        for xi in (1e-2, 5e-3):
            delta = model.delta_axis_series(xi, ax)
            slope = ax[model.AX_Y] * xi + 4 * ax[model.AX_K] * xi**3
            res.append(abs(model.ddelta_dxi(xi, delta, eta, A, N, ax) - slope))
        if res[0] > 1e-13:
            assert res[0] / max(res[1], 1e-300) > 2**4.5, (eta, A, N, res)


def test_stage1_jacobian_is_minus_B():
    """d(delta')/d(delta) = -B (model.md): finite differences against spin_rate_B."""
    for eta, A, N in _random_admissible(100):
        ax = _ax(eta, A, N)
        xi, delta = 0.5, 0.1 * N
        D = model.yield_D(xi, delta, A, N, ax)
        if D <= 1e-6:
            continue
        hstep = 1e-7 * N
        fd = (model.ddelta_dxi(xi, delta + hstep, eta, A, N, ax)
              - model.ddelta_dxi(xi, delta - hstep, eta, A, N, ax)) / (2 * hstep)
        B = model.spin_rate_B(delta, 1 / math.sqrt(D), eta, A, N)
        assert fd == pytest.approx(-B, rel=1e-5)


def test_B_and_h_equal_the_papers_flow_rule():
    """B and h equal e-60 and e-59 written with the unscaled stresses of eq:19 and eq:56."""
    eps, L, A, N, nu = 1 / 30, 10.0, 1 / 3, 1.2, 0.6
    eta = eps * L
    ax = _ax(eta, A, N)
    for xi, delta in ((0.3, 0.05), (0.8, 0.4)):
        D = model.yield_D(xi, delta, A, N, ax)
        m_bar = nu * L * (delta - N)
        s_xy = -nu * xi  # eq:19
        s_yx = A * nu * xi - nu * math.sqrt(D)  # eq:56 (scaled D times nu^2)
        B_paper = 2 * (1 + A) * m_bar / (eps * L**2 * (s_yx + A * s_xy))  # e-60
        h_paper = (1 + A) * (s_xy + s_yx) / (s_yx + A * s_xy)  # e-59
        assert model.spin_rate_B(delta, 1 / math.sqrt(D), eta, A, N) == pytest.approx(B_paper, rel=1e-12)
        assert model.shear_rate_h(xi, 1 / math.sqrt(D), A) == pytest.approx(h_paper, rel=1e-12)


@pytest.mark.parametrize(
    "eta, A, N, expected",
    [
        (0.3, 1 / 3, 0.7, st.OK),  # 1 - 2N^2 = 0.02 < A
        (0.3, 0.0, 0.7, st.WALL_INADMISSIBLE),  # A < 1 - 2N^2 = 0.02
        (0.3, -1.5, 2.0, st.AXIS_SPIN_UNBOUNDED),  # 1 - 2N^2 = -7 < A < -1
        (0.3, -8.0, 2.0, st.WALL_INADMISSIBLE),  # A < 1 - 2N^2 = -7
        (0.3, -1.0, 1.0, st.OK),  # A = -1: closed form
        (4.5, 1 / 3, 1.0, st.EPS_TOO_LARGE_AXIS),  # eta above 2(A+1)N/(1-A) = 4
        (3.9, 1 / 3, 1.0, st.OK),  # axis fine (the path may still fail)
        (0.3, -1 + 1e-6, 1.0, st.EPS_TOO_LARGE_AXIS),  # A -> -1+: axis needs eta < ~(A+1)N
    ],
)
def test_classify_regimes(eta, A, N, expected):
    """Appendix A's regimes and the axis condition, including both sides of A = -1."""
    assert model.classify(eta, A, N) == expected


def test_other_root_between_regimes_has_unbounded_axis_spin():
    """For 1-2N^2 < A < -1 the E+ root from m(0)=+NL reaches the wall with B < 0 near the axis (model.md)."""
    A, N, eta = -1.5, 2.0, 0.05
    # mu = m/L starts at +N; with p = mu - N, eta p' = (A+1) xi + sqrt(D)   (eq:a1)
    def D(xi, p):
        mu = N + p
        return (A * A - 1) * xi * xi + 2 * (A + 1) * (N * N - mu * mu)

    def f(xi, z):
        return [((A + 1) * xi + math.sqrt(max(D(xi, z[0]), 0.0))) / eta]

    def hit(xi, z):
        return D(xi, z[0])

    hit.terminal = True
    sol = solve_ivp(f, [1e-6, 1.0], [0.0], method="Radau", rtol=1e-10, atol=1e-14, events=hit,
                    dense_output=True)
    assert sol.status == 0 and sol.t[-1] == 1.0  # reaches the wall
    for xi in (1e-4, 1e-3, 1e-2):
        p = float(sol.sol(xi)[0])
        s = math.sqrt(D(xi, p))  # sigma_yx + A sigma_xy = +sqrt(D) on this root
        B = 2 * (A + 1) * (N + p) / (eta * s)
        assert B < 0
        assert B * xi < -1.0  # B ~ beta/xi with beta < 0: omega_hat ~ xi^beta -> infinity


def _reference_stage1(eta, A, N, ax):
    """w(xi) from an independent march: scipy Radau at rtol 1e-13 from next to the axis."""
    xi0 = 1e-4 * min(1.0, ax[model.AX_C0])
    w0 = 0.5 * ax[model.AX_Y] + ax[model.AX_K] * xi0 * xi0

    def rhs(xi, w):
        delta = xi * xi * w[0]
        D = model.yield_D(xi, delta, A, N, ax)
        return [((A + 1) * xi - math.sqrt(max(D, 0.0))) / eta / (xi * xi) - 2 * w[0] / xi]

    def hit(xi, w):
        return model.yield_D(xi, xi * xi * w[0], A, N, ax)

    hit.terminal = True
    return solve_ivp(rhs, [xi0, 1.0], [w0], method="Radau", rtol=1e-13, atol=1e-15,
                     dense_output=True, events=hit)


def test_axis_series_is_good_to_its_tolerance_where_series_reach_says():
    """The power series of w at the axis (model.axis_series), used up to model.series_reach, agrees
    with an independent Radau march to the tolerance asked, at random admissible points."""
    checked = 0
    for eta, A, N in _random_admissible(40):
        ax = _ax(eta, A, N)
        assert ax[model.AX_W] == pytest.approx(0.5 * ax[model.AX_Y], rel=1e-15)
        assert ax[model.AX_W + 1] == pytest.approx(ax[model.AX_K], rel=1e-12)
        tol = 1e-10
        xi_s = model.series_reach(ax, tol, 0.9)
        ref = _reference_stage1(eta, A, N, ax)
        if xi_s == 0.0 or ref.t[-1] < xi_s:
            continue
        for xi in (0.3 * xi_s, 0.7 * xi_s, xi_s):
            w_ref = ref.sol(xi)[0]
            # the reference's own error is ~1e-12 relative
            assert model.w_axis_series(xi, ax) == pytest.approx(w_ref, rel=tol + 3e-12)
        checked += 1
    assert checked >= 25


def _stage2_series_agree(eta, A, N):
    """Check one point (see the test below); False where it does not apply."""
    from scipy.integrate import quad

    ax = _ax(eta, A, N)
    xi_s = model.series_reach(ax, 1e-12, 0.9)
    if xi_s == 0.0:
        return False
    model.stage2_series(eta, A, N, ax)
    xi2 = model.stage2_series_reach(ax, 1e-10, xi_s)
    ref = _reference_stage1(eta, A, N, ax)
    beta = ax[model.AX_BETA]
    if xi2 < 0.05 or ref.t[-1] < xi2 or beta > 60:
        return False

    def rates(xi):
        delta = xi * xi * ref.sol(xi)[0]
        D = model.yield_D(xi, delta, A, N, ax)
        return (xi * model.spin_rate_B(delta, 1 / math.sqrt(D), eta, A, N),
                model.shear_rate_h(xi, 1 / math.sqrt(D), A))

    xa = 0.5 * xi2
    # log omega_hat(xi2) - log omega_hat(xa) = int_xa^xi2 B
    lhs = beta * math.log(xi2 / xa) + model.series_G(xi2, ax) - model.series_G(xa, ax)
    rhs = quad(lambda x: rates(x)[0] / x, xa, xi2, epsabs=0, epsrel=1e-12)[0]
    assert lhs == pytest.approx(rhs, rel=1e-8, abs=1e-9)

    # int_0^xi2 h omega_hat / omega_hat(xi2), with omega_hat(xi) / omega_hat(xi2) from G (above)
    def integrand(x):
        ratio = (x / xi2) ** beta * math.exp(model.series_G(x, ax) - model.series_G(xi2, ax))
        return rates(x)[1] * ratio

    series = xi2 * model.series_F(xi2, ax) / math.exp(model.series_G(xi2, ax))
    direct = quad(integrand, 1e-9, xi2, epsabs=0, epsrel=1e-12, limit=200)[0]
    assert series == pytest.approx(direct, rel=1e-8)
    return True


@pytest.mark.slow
def test_stage2_series_are_the_quadratures_of_B_and_h():
    """model.stage2_series: log omega_hat and int_0^xi h omega_hat from the series equal scipy
    quadratures of e-60 and e-59 on the independent stage-1 march, below stage2_series_reach."""
    checked = sum(_stage2_series_agree(eta, A, N) for eta, A, N in _random_admissible(60))
    assert checked >= 10
