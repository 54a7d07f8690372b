"""Tests for the Numba Dormand–Prince 5(4) integrator in ``cosserat_channel.integrate.rk45``."""

from fractions import Fraction as F
import math

import numpy as np
import pytest
from numba import njit
from scipy.integrate import solve_ivp

from cosserat_channel.integrate import dense, rk45
from cosserat_channel.integrate.rk45 import control, dopri5, dopri5_step, integrate
from cosserat_channel.integrate.stepping import (
    EVENT,
    MAX_STEPS,
    N_STATS,
    NONFINITE,
    STAT_ACCEPTED,
    STAT_FEV,
    STAT_REJECTED,
    STEP_TOO_SMALL,
    SUCCESS,
    no_event,
)
from problems import (OSC_ARGS, const_one, gauss, gauss_exact, nan_after_t0, osc_exact,
                      oscillator, stiff, vdp, y_half)


# ---------------------------------------------------------------------------
# Right-hand sides and events (module level so that Numba can cache them)
# ---------------------------------------------------------------------------
@njit(cache=True)
def decay(t, y, args, out):
    out[0] = -y[0]


@njit(cache=True)
def blowup(t, y, args, out):
    out[0] = y[0] * y[0]


@njit(cache=True)
def t_half(t, y, args):
    return t - 0.5


@njit(cache=True)
def gauss_event_driver(T, Q, stats):
    # A jitted caller with the RHS as a global: the pattern used by sweeps.
    return dopri5(gauss, y_half, 0.0, np.array([1.0]), 2.0, (), 1e-11,
                  np.array([1e-13]), 0.0, 0.0, T, Q, stats)


# ---------------------------------------------------------------------------
# 1. Tableau
# ---------------------------------------------------------------------------
C_EXACT = [F(0), F(1, 5), F(3, 10), F(4, 5), F(8, 9), F(1), F(1)]
A_EXACT = [
    [],
    [F(1, 5)],
    [F(3, 40), F(9, 40)],
    [F(44, 45), F(-56, 15), F(32, 9)],
    [F(19372, 6561), F(-25360, 2187), F(64448, 6561), F(-212, 729)],
    [F(9017, 3168), F(-355, 33), F(46732, 5247), F(49, 176), F(-5103, 18656)],
    [F(35, 384), F(0), F(500, 1113), F(125, 192), F(-2187, 6784), F(11, 84)],
]
B_EXACT = [F(35, 384), F(0), F(500, 1113), F(125, 192), F(-2187, 6784), F(11, 84), F(0)]
BHAT_EXACT = [F(5179, 57600), F(0), F(7571, 16695), F(393, 640), F(-92097, 339200),
              F(187, 2100), F(1, 40)]


def _matrix():
    A = [[F(0)] * 7 for _ in range(7)]
    for i, row in enumerate(A_EXACT):
        for j, a in enumerate(row):
            A[i][j] = a
    return A


def _trees(max_order):
    """All rooted trees up to `max_order`, as canonical nested sorted tuples."""

    def grow(tree):
        yield tuple(sorted(tree + ((),)))
        for idx, child in enumerate(tree):
            for g in grow(child):
                yield tuple(sorted(tree[:idx] + (g,) + tree[idx + 1:]))

    levels = [{()}]
    for _ in range(max_order - 1):
        levels.append({g for t in levels[-1] for g in grow(t)})
    return levels


def _order(tree):
    return 1 + sum(_order(c) for c in tree)


def _gamma(tree):
    g = _order(tree)
    for c in tree:
        g *= _gamma(c)
    return g


def _stage_weights(tree, A):
    s = len(A)
    phi = [F(1)] * s
    for child in tree:
        inner = _stage_weights(child, A)
        for i in range(s):
            phi[i] *= sum(A[i][j] * inner[j] for j in range(s))
    return phi


def _residuals(b, A, order):
    return [sum(bi * p for bi, p in zip(b, _stage_weights(t, A))) - F(1, _gamma(t))
            for t in _trees(order)[order - 1]]


def test_module_constants_match_exact_tableau():
    """The float tableau constants equal the exact Dormand–Prince fractions."""
    A = _matrix()
    for i in range(1, 6):
        for j in range(i):
            v = getattr(rk45, f"A{i + 1}{j + 1}")
            assert v == pytest.approx(float(A[i][j]), rel=1e-16, abs=1e-16)
    for j in range(7):
        assert getattr(rk45, f"B{j + 1}") == pytest.approx(float(B_EXACT[j]), rel=1e-16, abs=0)
        e = B_EXACT[j] - BHAT_EXACT[j]
        assert getattr(rk45, f"E{j + 1}") == pytest.approx(float(e), rel=1e-15, abs=1e-18)
    for i in range(1, 7):
        assert getattr(rk45, f"C{i + 1}") == pytest.approx(float(C_EXACT[i]), rel=1e-16)


def test_row_sums_equal_nodes():
    """c_i = sum_j a_ij for every stage, including the FSAL row."""
    A = _matrix()
    for i in range(7):
        assert sum(A[i]) == C_EXACT[i]


def test_tree_enumeration():
    """There are 1, 1, 2, 4, 9 rooted trees of orders 1..5."""
    assert [len(level) for level in _trees(5)] == [1, 1, 2, 4, 9]


def test_fifth_order_conditions():
    """The propagating weights b satisfy all 17 order conditions up to order 5."""
    A = _matrix()
    for p in range(1, 6):
        assert all(r == 0 for r in _residuals(B_EXACT, A, p)), p


def test_embedded_is_genuinely_fourth_order():
    """bhat satisfies all conditions up to order 4 but not all of order 5."""
    A = _matrix()
    for p in range(1, 5):
        assert all(r == 0 for r in _residuals(BHAT_EXACT, A, p)), p
    assert any(r != 0 for r in _residuals(BHAT_EXACT, A, 5))


# ---------------------------------------------------------------------------
# 2.-3. Fixed-step behaviour
# ---------------------------------------------------------------------------
def _fixed_step_run(fun, y0, t_end, nsteps, args):
    n = len(y0)
    y = np.array(y0, dtype=float)
    k1 = np.empty(n)
    y_new = np.empty(n)
    y_err = np.empty(n)
    K = np.empty((7, n))
    h = t_end / nsteps
    t = 0.0
    fun(t, y, args, k1)
    for _ in range(nsteps):
        dopri5_step(fun, t, y, h, args, k1, y_new, y_err, K)
        y[:] = y_new
        k1[:] = K[6]
        t += h
    return y


@pytest.mark.parametrize("case", ["gauss", "oscillator"])
def test_observed_convergence_order_is_five(case):
    """Fixed-step global error at t=1 decays with slope 5 in h."""
    # exp(-t^2) is still pre-asymptotic at h = 1/8 (local slope 4.1), so its
    # ladder starts one halving later; it stays well above round-off.
    hs = np.array([1 / 8, 1 / 16, 1 / 32, 1 / 64]) / (2 if case == "gauss" else 1)
    errs = []
    for h in hs:
        m = int(round(1 / h))
        if case == "gauss":
            y = _fixed_step_run(gauss, [1.0], 1.0, m, ())
            errs.append(abs(y[0] - gauss_exact(1.0)))
        else:
            y = _fixed_step_run(oscillator, [1.0, 0.0], 1.0, m, (1.5,))
            errs.append(np.max(np.abs(y - osc_exact(1.0, 1.5))))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 4.7 <= slope <= 5.3, (slope, errs)


def test_step_outputs_fsal_and_stages():
    """K[0] is k1, K[6] is f(t+h, y_new), and K[1] is f at the second stage."""
    y = np.array([0.7])
    k1 = np.empty(1)
    gauss(0.3, y, (), k1)
    y_new, y_err, K = np.empty(1), np.empty(1), np.empty((7, 1))
    h = 0.1
    dopri5_step(gauss, 0.3, y, h, (), k1, y_new, y_err, K)
    assert K[0, 0] == k1[0]
    assert K[6, 0] == pytest.approx(-2.0 * 0.4 * y_new[0], rel=1e-14)
    assert K[1, 0] == pytest.approx(-2.0 * (0.3 + h / 5) * (0.7 + h / 5 * k1[0]), rel=1e-14)
    assert y[0] == 0.7  # input untouched


def test_error_estimate_bounds_local_errors():
    """From the exact solution, |y_err| ~ 4th-order local error and exceeds the 5th-order one."""
    t0 = 0.3
    y = np.array([gauss_exact(t0)])
    k1 = np.empty(1)
    gauss(t0, y, (), k1)
    y_new, y_err, K = np.empty(1), np.empty(1), np.empty((7, 1))
    for h in [0.2, 0.1, 0.05, 0.025, -0.1]:
        dopri5_step(gauss, t0, y, h, (), k1, y_new, y_err, K)
        exact = gauss_exact(t0 + h)
        le5 = abs(y_new[0] - exact)
        le4 = abs(y_new[0] - y_err[0] - exact)
        assert le5 <= abs(y_err[0]), h
        assert abs(y_err[0]) >= 0.5 * le4, h
        assert abs(y_err[0]) <= 2.0 * le4, h


@pytest.mark.parametrize("rtol", [1e-4, 1e-6, 1e-8, 1e-10])
def test_tolerance_proportionality(rtol):
    """Adaptive global error stays within 100x rtol on closed-form problems."""
    s = integrate(gauss, 0.0, [1.0], 2.0, rtol=rtol, atol=rtol)
    assert s.status == SUCCESS
    assert abs(s.y_stop[0] - gauss_exact(2.0)) <= 100 * rtol
    w = OSC_ARGS[0]
    s = integrate(oscillator, 0.0, [1.0, 0.0], 5.0, args=OSC_ARGS, rtol=rtol, atol=rtol)
    assert s.status == SUCCESS
    assert np.max(np.abs(s.y_stop - osc_exact(5.0, w))) <= 100 * rtol * w


def test_error_decreases_with_tolerance():
    """Tightening rtol by 1e4 reduces the global error by at least 1e2."""
    e = [abs(integrate(gauss, 0.0, [1.0], 2.0, rtol=r, atol=r).y_stop[0] - gauss_exact(2.0))
         for r in (1e-5, 1e-9)]
    assert e[1] < 1e-2 * e[0]


# ---------------------------------------------------------------------------
# 4.-5. Step clipping and events (the dense output itself: test_integrate_dense.py)
# ---------------------------------------------------------------------------
def test_steps_land_on_t_end_and_respect_h_max():
    """The last step is clipped onto t_end exactly and no step exceeds h_max."""
    s = integrate(decay, 0.0, [1.0], 3.0, rtol=1e-6, h_max=0.07)
    assert s.status == SUCCESS
    assert s.T[0] == 0.0 and s.T[-1] == 3.0 and s.t_stop == 3.0
    assert np.all(np.diff(s.T) > 0) and np.all(np.diff(s.T) <= 0.07 * (1 + 1e-15))
    assert s.y_stop[0] == pytest.approx(math.exp(-3.0), rel=1e-5)


def test_event_location_forward():
    """The crossing y = 1/2 of exp(-t^2) is located at sqrt(ln 2) to 1e-10."""
    s = integrate(gauss, 0.0, [1.0], 2.0, rtol=1e-11, atol=1e-13, event=y_half)
    assert s.status == EVENT
    assert abs(s.t_stop - math.sqrt(math.log(2.0))) <= 1e-10
    assert s.y_stop[0] == pytest.approx(0.5, abs=1e-10)
    # The last stored boundary is the end of the step containing the event.
    assert s.T[-2] <= s.t_stop <= s.T[-1]


def test_event_location_backward():
    """Backward integration from t=2 finds the upward crossing y = 1/2 at sqrt(ln 2)."""
    s = integrate(gauss, 2.0, [gauss_exact(2.0)], 0.0, rtol=1e-11, atol=1e-15, event=y_half)
    assert s.status == EVENT
    assert abs(s.t_stop - math.sqrt(math.log(2.0))) <= 1e-10
    assert s.T[-2] >= s.t_stop >= s.T[-1]


def test_jitted_driver_is_cacheable_and_locates_event():
    """A jitted driver around dopri5 finds the event and has no uncacheable dynamic globals."""
    T = np.empty(1001)
    Q = np.empty((1000, dense.N_DENSE, 1))
    stats = np.zeros(N_STATS, dtype=np.int64)
    status, nsteps, t_stop = gauss_event_driver(T, Q, stats)
    assert status == EVENT
    assert abs(t_stop - math.sqrt(math.log(2.0))) <= 1e-10
    assert stats[STAT_ACCEPTED] == nsteps
    (cres,) = gauss_event_driver.overloads.values()
    assert not cres.library.has_dynamic_globals


def test_event_exactly_at_step_end():
    """An event that is exactly zero at an accepted step end stops there."""
    s = integrate(const_one, 0.0, [0.0], 1.0, event=t_half, h0=0.25, h_max=0.25)
    assert s.status == EVENT
    assert s.t_stop == 0.5
    assert s.nsteps == 2 and s.T[-1] == 0.5
    assert s.y_stop[0] == pytest.approx(0.5, abs=1e-15)


def test_event_zero_at_start_is_ignored():
    """An event that vanishes exactly at t0 does not stop the integration."""
    s = integrate(const_one, 0.5, [0.0], 1.0, event=t_half)
    assert s.status == SUCCESS
    assert s.t_stop == 1.0
    assert s.y_stop[0] == pytest.approx(0.5, abs=1e-14)


# ---------------------------------------------------------------------------
# 6. Counters and failure modes
# ---------------------------------------------------------------------------
def test_fev_identity_automatic_h0():
    """n_fev = 1 + 1 (HINIT probe) + 6*(accepted + rejected)."""
    s = integrate(vdp, 0.0, [2.0, 0.0], 5.0, args=(5.0,), rtol=1e-6, atol=1e-9)
    assert s.status == SUCCESS
    assert s.n_rejected > 0
    assert s.n_accepted == s.nsteps
    assert s.n_fev == 2 + 6 * (s.n_accepted + s.n_rejected)


def test_fev_identity_given_h0():
    """With a user h0 there is no HINIT probe: n_fev = 1 + 6*(accepted + rejected)."""
    s = integrate(vdp, 0.0, [2.0, 0.0], 5.0, args=(5.0,), rtol=1e-6, atol=1e-9, h0=1.0)
    assert s.status == SUCCESS
    assert s.n_rejected > 0  # h0 = 1 is far too large for the first step
    assert s.n_fev == 1 + 6 * (s.n_accepted + s.n_rejected)


def test_max_steps_status():
    """A tiny step budget yields MAX_STEPS with the budget's worth of stored steps."""
    s = integrate(decay, 0.0, [1.0], 100.0, rtol=1e-10, max_steps=5)
    assert s.status == MAX_STEPS and "budget" in s.message
    assert s.nsteps == 5 and s.T.shape == (6,) and s.Q.shape == (5, dense.N_DENSE, 1)
    assert s.t_stop == s.T[-1] < 100.0


def test_blowup_returns_failure():
    """y' = y^2 from y(0)=1 blows up at t=1: a failure status, not a hang or raise."""
    s = integrate(blowup, 0.0, [1.0], 2.0, rtol=1e-6)
    assert s.status in (STEP_TOO_SMALL, NONFINITE)
    # The numerical blow-up time differs from 1 by the accumulated error.
    assert 0.99 < s.t_stop < 1.0 + 1e-4


def test_nonfinite_status():
    """An RHS that is NaN for every trial step gives NONFINITE after ~20 shrinks."""
    s = integrate(nan_after_t0, 0.0, [1.0], 1.0, h0=0.1)
    assert s.status == NONFINITE
    assert s.nsteps == 0 and s.t_stop == 0.0
    assert s.n_accepted == 0 and 15 <= s.n_rejected <= 25


def test_raw_dopri5_zero_length_and_stats_reset():
    """dopri5 zeroes stats and returns immediately for t_end == t0."""
    T = np.empty(11)
    Q = np.empty((10, dense.N_DENSE, 1))
    stats = np.full(N_STATS, 7, dtype=np.int64)
    status, nsteps, t_stop = dopri5(decay, no_event, 1.0, np.array([1.0]), 1.0, (), 1e-6,
                                    np.array([1e-9]), 0.0, 0.0, T, Q, stats)
    assert (status, nsteps, t_stop) == (SUCCESS, 0, 1.0)
    assert np.all(stats == 0) and T[0] == 1.0
    status, nsteps, t_stop = dopri5(decay, no_event, 0.0, np.array([1.0]), 1.0, (), 1e-6,
                                    np.array([1e-9]), 0.0, 0.0, T, Q, stats)
    assert status == SUCCESS and t_stop == 1.0
    assert stats[STAT_ACCEPTED] == nsteps and stats[STAT_REJECTED] == 0
    assert stats[STAT_FEV] == 2 + 6 * nsteps


def test_controller_accepts_rejects_and_bounds_growth():
    """err <= 1 accepts (growth at most 10x, capped by h_max); err > 1 rejects and shrinks."""
    accept, h, facold = control(0.0, 0.01, 1.0, rk45.FACOLD_MIN, False)
    assert accept and h == pytest.approx(0.1) and facold == rk45.FACOLD_MIN
    assert control(0.0, 0.01, 0.05, rk45.FACOLD_MIN, False)[1] == 0.05
    accept, h, facold = control(0.01, 0.01, 1.0, 0.3, False)
    assert accept and 0.01 < h < 0.1 and facold == 0.01
    accept, h, facold = control(50.0, 0.01, 1.0, 0.3, False)
    assert not accept and 0.002 <= h < 0.01 and facold == 0.3


def test_controller_after_rejection_and_nonfinite():
    """After a rejection the step does not grow; a non-finite trial shrinks it by 4."""
    accept, h, _ = control(1e-6, 0.01, 1.0, 0.3, True)
    assert accept and h == 0.01
    for err in (math.nan, math.inf):
        accept, h, facold = control(err, 0.01, 1.0, 0.3, False)
        assert not accept and h == 0.0025 and facold == 0.3


# ---------------------------------------------------------------------------
# 7. Stiffness detection
# ---------------------------------------------------------------------------
def test_stiffness_detected():
    """y' = -1000 (y - cos t) is flagged stiff but still integrated correctly."""
    # At moderate tolerance the step is pinned at the stability boundary
    # (h*lambda ~ 3.3); at very tight tolerance accuracy limits h instead.
    s = integrate(stiff, 0.0, [0.0], 5.0, rtol=1e-4, atol=1e-7)
    assert s.status == SUCCESS
    assert s.stiff
    assert s.n_stiff_steps > 0.5 * s.n_accepted
    # Quasi-steady solution y ~ cos t + 1e-3 sin t.
    assert s.y_stop[0] == pytest.approx(math.cos(5.0) + 1e-3 * math.sin(5.0), abs=1e-4)


@njit(cache=True)
def linear(t, y, args, out):
    out[0] = args[0] * y[0]


def test_steps_beyond_the_stability_boundary_are_rejected_given_rho0():
    """On y' = -1000 y from y = 0 every step is exact (error 0), so nothing but the stability
    check stops a step far beyond the boundary (what an error estimate that vanishes by accident
    lets through). Told |lambda| = 1000 at the start, no accepted step exceeds STABLE_FACTOR times
    the boundary; without it the steps grow to the end of the interval."""
    from cosserat_channel.integrate.stepping import STABLE_FACTOR

    free = integrate(linear, 0.0, [0.0], 1.0, args=(-1000.0,), rtol=1e-6, atol=1e-9, h0=0.1)
    assert free.status == SUCCESS and np.max(np.diff(free.T)) * 1000.0 > 10.0
    s = integrate(linear, 0.0, [0.0], 1.0, args=(-1000.0,), rtol=1e-6, atol=1e-9, h0=0.1,
                  rho0=1000.0)
    assert s.status == SUCCESS and np.all(s.Q == 0.0)
    assert np.max(np.diff(s.T)) * 1000.0 <= STABLE_FACTOR * rk45.STIFF_THRESHOLD * (1 + 1e-12)
    assert s.n_rejected >= 1


def test_nonstiff_not_flagged():
    """y' = -y is not flagged stiff."""
    s = integrate(decay, 0.0, [1.0], 20.0, rtol=1e-6, atol=1e-9)
    assert s.status == SUCCESS
    assert not s.stiff
    assert s.n_stiff_steps == 0


# ---------------------------------------------------------------------------
# 8. Agreement with scipy
# ---------------------------------------------------------------------------
def test_van_der_pol_agrees_with_scipy():
    """Van der Pol (mu=1) on [0, 5] at rtol 1e-8 agrees with DOP853 at 1e-12 to 1e-6."""
    mu = 1.0

    def f(t, y):
        return [y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]]

    ref = solve_ivp(f, (0.0, 5.0), [2.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12)
    s = integrate(vdp, 0.0, [2.0, 0.0], 5.0, args=(mu,), rtol=1e-8, atol=1e-10)
    assert s.status == SUCCESS
    assert np.max(np.abs(s.y_stop - ref.y[:, -1])) < 1e-6
