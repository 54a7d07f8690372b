"""Tests of the closed-form and asymptotic solutions in ``cosserat_channel.physics.asymptotics``.

The composite solution is checked against an independent scipy solution of the
full two-stage problem of ``docs/model.md``, written here on purpose (the
project's own solver must not validate itself).
"""

from functools import lru_cache

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq
from scipy.special import airy

from cosserat_channel.physics.asymptotics import (
    Delta_asymptotic,
    a_minus_one,
    a_minus_one_outputs,
    airy_I,
    airy_I_inf,
    composite,
    xi_bar_p,
    xi_bar_p_limit,
)

# ---------------------------------------------------------------------------
# Independent reference solver (model.md, stage 1 and stage 2), A > -1
# ---------------------------------------------------------------------------

XI1 = 1e-6


def _stage1_D(xi, d, A, N):
    return (A * A - 1.0) * xi * xi + 2.0 * (A + 1.0) * d * (2.0 * N - d)


def stage1(eps, L, A, N):
    """Solve eta dd/dxi = (A+1) xi - sqrt(D), d = (m + N L)/L, from XI1 to 1."""
    eta = eps * L
    a1 = A + 1.0
    y = 2.0 * a1 / (a1 * (eta + N) + np.sqrt(a1**2 * (eta + N) ** 2 - 2.0 * a1 * eta**2))
    d1 = 0.5 * y * XI1**2

    def rhs(xi, s):
        D = _stage1_D(xi, s[0], A, N)
        return [(a1 * xi - np.sqrt(max(D, 0.0))) / eta]

    sol = solve_ivp(rhs, (XI1, 1.0), [d1], method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
    assert sol.success, sol.message
    return sol.sol


def stage2(eps, L, A, N, sol1):
    """Integrate [log omega_hat, J] from the wall to the axis; return dense output and J(0)."""
    eta = eps * L
    a1 = A + 1.0

    def rhs(xi, s):
        d = sol1(xi)[0]
        sqD = np.sqrt(_stage1_D(xi, d, A, N))
        B = -2.0 * a1 * (d - N) / (eta * sqD)
        h = a1 * (1.0 - (A - 1.0) * xi / sqD)
        return [B, -h * np.exp(s[0])]

    def negligible(xi, s):
        return s[0] + 60.0  # omega_hat < e^-60: J no longer changes

    negligible.terminal = True
    sol = solve_ivp(rhs, (1.0, XI1), [0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-14,
                    dense_output=True, events=negligible)
    assert sol.success, sol.message
    return sol, sol.y[1, -1], sol.t[-1]


@lru_cache(maxsize=None)
def _stages(eps, L, A, N):
    s1 = stage1(eps, L, A, N)
    # K enters only through the plug-edge target, not the integration
    return (s1, *stage2(eps, L, A, N, s1))


def reference(eps, L, K, A, N):
    """Reference solution: stage-1 and stage-2 dense outputs, J(0), xi_stop and Delta."""
    s1, s2, J0, xi_stop = _stages(eps, L, A, N)
    target = 0.95 * J0 - 0.05 * eps * K
    xi_p = brentq(lambda x: s2.sol(x)[1] - target, xi_stop, 1.0, xtol=1e-15)
    return s1, s2, J0, xi_stop, (1.0 - xi_p) / eps


def reference_profiles(xi, eps, L, K, A, N):
    """m, sigma_yx, omega_hat, J of the reference solution (stresses over nu)."""
    s1, s2, J0, xi_stop, _ = reference(eps, L, K, A, N)
    d = s1(xi)[0]
    sqD = np.sqrt(_stage1_D(xi, d, A, N))
    inside = xi >= xi_stop
    st = s2.sol(np.where(inside, xi, xi_stop))
    omega_hat = np.where(inside, np.exp(st[0]), 0.0)
    J = np.where(inside, st[1], J0)
    return L * (d - N), A * xi - sqD, omega_hat, J


# ---------------------------------------------------------------------------
# Airy integral
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("x", [0.3, 1.0, 1.275, 3.0, 8.0])
def test_airy_antiderivative_matches_quadrature(x):
    """z Ai^2 - Ai'^2 is an antiderivative of Ai^2: I(x) equals quadrature."""
    ai0 = airy(0.0)[0]
    val, err = quad(lambda z: (airy(z)[0] / ai0) ** 2, 0.0, x, epsabs=1e-14, epsrel=1e-13)
    assert airy_I(x) == pytest.approx(val, rel=1e-12, abs=1e-14)


def test_airy_I_inf_matches_quadrature_to_infinity():
    """I(inf) = Ai'(0)^2/Ai(0)^2 equals quad to infinity and the large-x limit of I."""
    ai0 = airy(0.0)[0]
    val, _ = quad(lambda z: (airy(z)[0] / ai0) ** 2, 0.0, np.inf, epsabs=1e-14, epsrel=1e-13)
    assert airy_I_inf() == pytest.approx(val, rel=1e-11)
    assert airy_I(200.0) == pytest.approx(airy_I_inf(), rel=1e-15)


def test_xi_bar_p_limit_matches_paper():
    """lim xi_bar_p solves I/I(inf) = 0.95 and rounds to the paper's 1.275."""
    x = xi_bar_p_limit()
    assert airy_I(x) / airy_I_inf() == pytest.approx(0.95, rel=1e-14)
    assert abs(x - 1.275) < 5e-4, f"paper (Appendix C): lim xi_bar_p = 1.275; computed {x:.6f}"


def test_finite_xi_bar_p_tends_to_limit():
    """The finite-eps root I(xi_bar_p)/I(xi_bar_0) = 0.95 converges to the limit."""
    lim = xi_bar_p_limit()
    errs = [abs(xi_bar_p(e, 10.0) - lim) for e in (0.3, 0.1, 0.03)]
    assert errs[0] > errs[1] > errs[2] >= 0.0
    assert xi_bar_p(0.3, 10.0) < lim  # I(xi_bar_0) < I(inf) lowers the target


# ---------------------------------------------------------------------------
# A = -1 closed form
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("c", [10.0, 1e3, 1e5, 1e8])
def test_a_minus_one_profiles(c):
    """A = -1: J(1) = 0, omega_hat(1) = 1, dJ/dxi = -2 xi^c, all values finite."""
    L, N, K = 10.0, 1.0, 0.5
    eps = 2.0 * N / (c * L)
    xi = np.concatenate([[0.0], np.linspace(1e-3, 1.0, 2001)])
    p = a_minus_one(xi, eps, L, K, N)
    for arr in p:
        assert np.all(np.isfinite(arr))
    assert p.J[-1] == 0.0 and p.omega_hat[-1] == 1.0 and p.omega_hat[0] == 0.0
    assert np.all(p.m == -N * L) and np.array_equal(p.sigma_yx, -xi)
    assert p.J[0] == pytest.approx(2.0 / (c + 1.0), rel=1e-15)
    assert p.u_over_u0[0] == pytest.approx(1.0, rel=1e-15)
    # dJ/dxi = -2 xi^c by a centred difference close to the wall, where
    # the profile is non-trivial even for large c
    x = 1.0 - np.array([0.3, 1.0, 3.0]) / c
    hstep = 1e-4 / c
    dJ = (a_minus_one(x + hstep, eps, L, K, N).J - a_minus_one(x - hstep, eps, L, K, N).J) / (2 * hstep)
    # xi itself is only known to 1.1e-16, which limits the difference quotient
    rel = 1e-6 + 20 * np.finfo(float).eps / hstep
    assert dJ == pytest.approx(-2.0 * a_minus_one(x, eps, L, K, N).omega_hat, rel=rel)


@pytest.mark.parametrize("c", [10.0, 1e3, 1e5, 1e8])
def test_a_minus_one_plug_edge_closed_form(c):
    """A = -1: Delta > 0 and 1 - xi_p inverts xi_p^(c+1) = q to 1e-12 relative."""
    L, N, K = 10.0, 1.0, 0.5
    eps = 2.0 * N / (c * L)
    out = a_minus_one_outputs(eps, L, K, N)
    q = 0.05 * (1.0 + eps * K * (c + 1.0) / 2.0)
    assert q < 1.0 and out.Delta > 0.0 and np.isfinite(out.Delta)
    d = eps * out.Delta  # 1 - xi_p
    # independent inversion: (c+1) log(1 - d) must give log q
    assert (c + 1.0) * np.log1p(-d) == pytest.approx(np.log(q), rel=1e-12)
    # and the series of 1 - exp(-x), x = log(1/q)/(c+1)
    x = np.log(1.0 / q) / (c + 1.0)
    series = sum((-1) ** (k + 1) * x**k / np.prod(np.arange(1, k + 1)) for k in range(1, 25))
    assert d == pytest.approx(series, rel=1e-12)
    assert out.u_axis == pytest.approx(eps * K + 2.0 / (c + 1.0), rel=1e-15)
    assert out.slip == pytest.approx(eps * K / out.u_axis, rel=1e-15)


@pytest.mark.parametrize("c", [10.0, 100.0, 1e3])
def test_a_minus_one_Delta_by_root_finding(c):
    """A = -1: Delta equals brentq on u/u(0) = 0.95 of the profile."""
    L, N, K = 10.0, 1.0, 0.5
    eps = 2.0 * N / (c * L)
    f = lambda x: float(a_minus_one(x, eps, L, K, N).u_over_u0) - 0.95  # noqa: E731
    xi_p = brentq(f, 0.0, 1.0, xtol=1e-15, rtol=1e-15)
    assert a_minus_one_outputs(eps, L, K, N).Delta == pytest.approx((1.0 - xi_p) / eps, rel=1e-9)


def test_a_minus_one_no_shear_layer_for_smooth_wall():
    """A = -1: eps K >= 19 J(0) gives xi_p = 1 and Delta = 0 (and not just below)."""
    L, N, eps = 10.0, 1.0, 1.0 / 30.0
    c = 2.0 * N / (eps * L)
    K_crit = 19.0 * 2.0 / (c + 1.0) / eps
    out = a_minus_one_outputs(eps, L, K_crit * 1.0001, N)
    assert out.xi_p == 1.0 and out.Delta == 0.0
    assert a_minus_one_outputs(eps, L, K_crit * 0.999, N).Delta > 0.0


# ---------------------------------------------------------------------------
# Composite solution vs the independent numerical solution
# ---------------------------------------------------------------------------

A_REF, L_REF, N_REF = 1.0 / 3.0, 10.0, 1.0


def _composite_errors(eps):
    xi = np.linspace(0.0, 1.0, 4001)[1:]  # reference starts at XI1
    m_n, s_n, w_n, J_n = reference_profiles(xi, eps, L_REF, 0.0, A_REF, N_REF)
    c = composite(xi, eps, L_REF)
    return (
        np.max(np.abs(c.m - m_n)) / L_REF,
        np.max(np.abs(c.sigma_yx - s_n)),
        np.max(np.abs(c.omega_hat - w_n)),
        np.max(np.abs(c.J - J_n)) / J_n.max(),
    )


def test_composite_rejects_N_not_one():
    """The Appendix C composite refuses N != 1."""
    with pytest.raises(ValueError):
        composite(0.5, 1e-3, 10.0, N=1.5)


def test_composite_wall_and_axis_values():
    """Composite: omega_hat(1) = 1, J(1) = 0, m(0) -> -L, m(1) = (2 eps/L^2)^(1/3) L^2 Ai'(0)/Ai(0)."""
    eps, L = 1e-4, 10.0
    c = composite(np.array([0.0, 1.0]), eps, L)
    ai0, aip0, _, _ = airy(0.0)
    assert c.omega_hat[1] == 1.0 and c.J[1] == 0.0
    assert c.m[1] == pytest.approx((2 * eps / L**2) ** (1 / 3) * L**2 * aip0 / ai0, rel=1e-14)
    assert c.m[0] == pytest.approx(-L, rel=1e-3)
    assert c.sigma_yx[1] == pytest.approx(-1.0 + (4 * eps**2 * L**2) ** (1 / 3) * (aip0 / ai0) ** 2, rel=1e-14)
    # far from the wall the scaled Airy ratio must stay finite
    assert np.all(np.isfinite(composite(np.linspace(0, 1, 11), 1e-7, 10.0).m))


def test_composite_matches_numerical_profiles():
    """Composite m, sigma_yx, omega_hat, J agree with the full solution; error shrinks with eps."""
    e_big = _composite_errors(1.0 / 600.0)
    e_small = _composite_errors(1e-4)
    # Observed max errors (eps = 1/600 -> 1e-4): m/L 5.8e-3 -> 3.7e-4 and
    # sigma_yx 1.2e-2 -> 7.1e-4 (both ~ eps), omega_hat 1.2e-2 -> 1.9e-3 and
    # J/J(0) 2.0e-2 -> 3.0e-3 (~ eps^(2/3), the first neglected inner order).
    # Tolerances: those values with 50 % headroom.
    tol_big = (0.009, 0.018, 0.018, 0.03)
    tol_small = (6e-4, 1.1e-3, 3e-3, 4.5e-3)
    for name, eb, es, tb, ts in zip(("m/L", "sigma_yx", "omega_hat", "J/J0"), e_big, e_small, tol_big, tol_small):
        assert eb < tb, f"{name}: error {eb:.3g} at eps=1/600 exceeds {tb}"
        assert es < ts, f"{name}: error {es:.3g} at eps=1e-4 exceeds {ts}"
        assert es < eb, f"{name}: error did not shrink with eps ({eb:.3g} -> {es:.3g})"


def test_printed_formulas_disagree_with_numerics():
    """The formulas as printed (eq:44, eq:29, eq:32) miss the numerical solution by O(1); the corrected ones do not."""
    eps, L = 1e-4, L_REF
    xi = np.linspace(0.0, 1.0, 2001)[1:]
    m_n, s_n, _, J_n = reference_profiles(xi, eps, L, 0.0, A_REF, N_REF)
    c = composite(xi, eps, L)
    ai, aip, _, _ = airy(np.minimum(c.xi_bar, 50.0))  # R is saturated at the wall side only
    R = np.where(c.xi_bar < 50.0, aip / ai, -np.sqrt(c.xi_bar))
    m_printed = -L * np.sqrt(1 - xi**2) + (2 * eps / L**2) ** (1 / 3) * R + L * np.sqrt(2 * (1 - xi))
    s_printed = -2.0 + xi + (2 * eps**2 / L**2) ** (1 / 3) * R / L**2
    J_printed = 2.0 * (2 * eps**2 / L**2) ** (1 / 3) * airy_I(c.xi_bar)
    assert np.max(np.abs(m_printed - m_n)) / L > 1.0 > 100 * np.max(np.abs(c.m - m_n)) / L
    assert np.max(np.abs(s_printed - s_n)) > 1.0 > 100 * np.max(np.abs(c.sigma_yx - s_n))
    # eq:32's prefactor is off by (L^2/2)^(2/3) = 13.57 at L = 10
    assert J_n.max() / J_printed.max() == pytest.approx((L**2 / 2) ** (2 / 3), rel=0.01)
    assert c.J.max() == pytest.approx(J_n.max(), rel=0.005)


def test_Delta_numerical_over_asymptotic_tends_to_one():
    """Delta_numerical / Delta_asymptotic approaches 1 monotonically as eps -> 0 (K = 0 and 0.5)."""
    for K in (0.0, 0.5):
        ratios = [reference(e, L_REF, K, A_REF, N_REF)[4] / Delta_asymptotic(e, L_REF) for e in (1e-2, 1e-3, 1e-4)]
        dev = [abs(r - 1.0) for r in ratios]
        assert dev[0] > dev[1] > dev[2], f"K={K}: ratios {ratios} not approaching 1 monotonically"
        assert dev[2] < 0.03, f"K={K}: ratio {ratios[2]:.4f} at eps=1e-4 not within 3 %"
