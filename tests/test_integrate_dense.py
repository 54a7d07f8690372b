"""Tests for the dense output and event location in ``cosserat_channel.integrate.dense``."""

import numpy as np
import pytest
from numba import njit
from scipy.optimize import brentq

from cosserat_channel.integrate import dense
from cosserat_channel.integrate.dense import (
    Solution,
    component_minus_level,
    dense_eval,
    dense_eval_many,
    dense_eval_step,
    event_after_step,
    find_step,
    locate_event,
)
from cosserat_channel.integrate.rk45 import dense_coefficients, dopri5_step, integrate
from cosserat_channel.integrate.stepping import N_STATS, SUCCESS, no_event
from problems import OSC_ARGS, const_one, gauss, gauss_exact, osc_exact, oscillator


# ---------------------------------------------------------------------------
# Right-hand sides and events (module level so that Numba can cache them)
# ---------------------------------------------------------------------------
@njit(cache=True)
def y_minus_level(t, y, args):
    # args = (level, sign): sign*(y - level), so that both crossing directions can be tested.
    level, sign = args
    return sign * (y[0] - level)



def one_step(fun, t0, y0, h, args=()):
    """T and Q of a single dopri5 step of size h from (t0, y0)."""
    y = np.array(y0, dtype=float)
    n = y.shape[0]
    k1, y_new, y_err, K = np.empty(n), np.empty(n), np.empty(n), np.empty((7, n))
    fun(t0, y, args, k1)
    dopri5_step(fun, t0, y, h, args, k1, y_new, y_err, K)
    Q = np.empty((1, dense.N_DENSE, n))
    dense_coefficients(y, y_new, h, K, Q[0])
    return np.array([t0, t0 + h]), Q, y_new


# ---------------------------------------------------------------------------
# Interpolation
# ---------------------------------------------------------------------------
def test_step_slope_is_the_interpolants_derivative():
    """At a step's ends the interpolant's slope is f there (rows 0-3 are Hermite's), and inside
    it matches a central difference of the interpolant, for both layouts (DOP853's CONTD8 and
    Dormand-Prince's CONTD5)."""
    from cosserat_channel.integrate import dop853

    T, Q, y_new = one_step(oscillator, 0.0, [1.0, 0.0], 0.3, OSC_ARGS)
    T8, Q8, st8 = np.empty(51), np.empty((50, dense.N_DENSE, 2)), np.zeros(N_STATS, np.int64)
    _, n8, _ = dop853.dop853(oscillator, no_event, 0.0, np.array([1.0, 0.0]), 0.6, OSC_ARGS,
                             1e-6, np.full(2, 1e-9), 0.3, 0.0, T8, Q8, st8)
    assert n8 >= 1
    f = np.empty(2)
    for TT, QQ in ((T, Q), (T8[:2], Q8[:1])):
        for i in range(2):
            oscillator(TT[0], QQ[0, 0], OSC_ARGS, f)
            assert dense.step_slope(TT, QQ, 0, i, TT[0]) == pytest.approx(f[i], rel=1e-12,
                                                                           abs=1e-12)
            for t in np.linspace(TT[0], TT[1], 7)[1:-1]:
                d = 1e-6 * (TT[1] - TT[0])
                fd = (dense.step_value(TT, QQ, 0, i, t + d)
                      - dense.step_value(TT, QQ, 0, i, t - d)) / (2 * d)
                assert dense.step_slope(TT, QQ, 0, i, t) == pytest.approx(fd, rel=1e-7, abs=1e-8)


def test_contd5_steps_read_the_same_bits_through_the_contd8_formula():
    """A Dormand-Prince step (rows 5-7 zero) evaluates to exactly CONTD5's own nesting."""
    T, Q, _ = one_step(oscillator, 0.0, [1.0, 0.0], 0.3, OSC_ARGS)
    assert np.all(Q[0, 5:] == 0.0)
    out = np.empty(2)
    for t in np.linspace(0.0, 0.3, 37):
        th = (t - T[0]) / (T[1] - T[0])
        th1 = 1.0 - th
        q = Q[0]
        contd5 = q[0] + th * (q[1] + th1 * (q[2] + th * (q[3] + th1 * q[4])))
        dense_eval_step(T, Q, 0, t, out)
        assert np.array_equal(out, contd5)


def test_dense_output_gauss():
    """Dense output at 1000 points matches exp(-t^2) to 1e-8 at rtol 1e-10."""
    s = integrate(gauss, 0.0, [1.0], 2.0, rtol=1e-10, atol=1e-12)
    assert s.status == SUCCESS
    ts = np.linspace(0.0, 2.0, 1000)
    ys = s.sol(ts)
    assert ys.shape == (1000, 1)
    assert np.max(np.abs(ys[:, 0] - gauss_exact(ts))) <= 1e-8
    assert s.sol(1.3).shape == (1,)
    assert s.sol(1.3)[0] == pytest.approx(gauss_exact(1.3), abs=1e-9)


def test_dense_output_oscillator_and_continuity():
    """Oscillator dense output is accurate and continuous at every step boundary."""
    w = OSC_ARGS[0]
    s = integrate(oscillator, 0.0, [1.0, 0.0], 4.0, args=OSC_ARGS, rtol=1e-10, atol=1e-12)
    assert s.status == SUCCESS
    ts = np.linspace(0.0, 4.0, 1000)
    assert np.max(np.abs(s.sol(ts) - osc_exact(ts, w))) <= 1e-8 * w
    out = np.empty(2)
    for k in range(s.nsteps):
        dense_eval_step(s.T, s.Q, k, s.T[k], out)
        np.testing.assert_allclose(out, s.Q[k, 0], rtol=0, atol=1e-14)
        dense_eval_step(s.T, s.Q, k, s.T[k + 1], out)
        y_end = s.Q[k + 1, 0] if k + 1 < s.nsteps else s.y_stop
        np.testing.assert_allclose(out, y_end, rtol=0, atol=1e-14)


def test_find_step_both_directions_and_clamps():
    """find_step brackets t in increasing and decreasing T and clamps outside."""
    T = np.array([0.0, 0.5, 1.5, 2.0, 4.0])
    assert find_step(T, 4, 0.7) == 1
    assert find_step(T, 4, 1.5) == 2
    assert find_step(T, 4, -1.0) == 0
    assert find_step(T, 4, 9.0) == 3
    assert find_step(T, 4, 4.0) == 3
    Td = -T
    assert find_step(Td, 4, -0.7) == 1
    assert find_step(Td, 4, 1.0) == 0
    assert find_step(Td, 4, -9.0) == 3


def test_backward_integration_dense():
    """Integrating exp(-t^2) backwards from t=2 to 0 recovers y(0)=1 and a good interpolant."""
    s = integrate(gauss, 2.0, [gauss_exact(2.0)], 0.0, rtol=1e-10, atol=1e-14)
    assert s.status == SUCCESS
    assert s.T[-1] == 0.0 and np.all(np.diff(s.T) < 0)
    assert s.y_stop[0] == pytest.approx(1.0, abs=1e-8)
    ts = np.linspace(2.0, 0.0, 500)
    out = np.empty(1)
    dense_eval(s.T, s.Q, s.nsteps, 0.9, out)
    assert out[0] == pytest.approx(gauss_exact(0.9), abs=1e-8)
    assert np.max(np.abs(s.sol(ts)[:, 0] - gauss_exact(ts))) <= 1e-8



def test_interpolant_local_error_is_fifth_order():
    """From the exact y, the mid-step interpolation error falls like h^5 (a 4th-order u)."""
    t0 = 0.3
    hs = np.array([0.1, 0.05, 0.025, 0.0125])
    errs = []
    out = np.empty(1)
    for h in hs:
        T, Q, _ = one_step(gauss, t0, [gauss_exact(t0)], h)
        dense_eval_step(T, Q, 0, t0 + 0.5 * h, out)
        errs.append(abs(out[0] - gauss_exact(t0 + 0.5 * h)))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 4.6 <= slope <= 5.4, (slope, errs)


def test_dense_eval_many_matches_dense_eval():
    """The many-points evaluator returns exactly what dense_eval returns point by point."""
    s = integrate(oscillator, 0.0, [1.0, 0.0], 4.0, args=OSC_ARGS, rtol=1e-8, atol=1e-10)
    ts = np.array([3.9, 0.0, 1.234, 4.0, 2.5])
    many = np.empty((ts.size, 2))
    dense_eval_many(s.T, s.Q, s.nsteps, ts, many)
    one = np.empty(2)
    for j, t in enumerate(ts):
        dense_eval(s.T, s.Q, s.nsteps, t, one)
        assert np.array_equal(many[j], one)


def test_component_minus_level():
    """component_minus_level is component i of the dense output minus the level."""
    s = integrate(oscillator, 0.0, [1.0, 0.0], 4.0, args=OSC_ARGS, rtol=1e-8, atol=1e-10)
    out = np.empty(2)
    v = component_minus_level(1.7, (s.T, s.Q, s.nsteps, 1, 0.25, out))
    assert v == out[1] - 0.25
    assert v == pytest.approx(osc_exact(1.7, OSC_ARGS[0])[1] - 0.25, abs=1e-6)


def test_solution_without_steps():
    """A run with no accepted step reports y0 and evaluates to y0 everywhere."""
    T, Q = np.zeros(3), np.zeros((2, dense.N_DENSE, 2))
    stats = np.zeros(N_STATS, np.int64)
    s = Solution.from_run(SUCCESS, 0, 1.0, np.array([2.0, 3.0]), T, Q, stats)
    assert s.nsteps == 0 and s.T.shape == (1,) and s.Q.shape == (0, dense.N_DENSE, 2)
    assert np.array_equal(s.y_stop, [2.0, 3.0])
    assert np.array_equal(s.sol([0.0, 5.0]), [[2.0, 3.0], [2.0, 3.0]])


# ---------------------------------------------------------------------------
# Events
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("h", [0.3, -0.3])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_locate_event_is_the_root_of_the_interpolant(h, sign):
    """locate_event finds the zero on one step's interpolant, either direction, either sign."""
    t0 = 0.5 if h > 0 else 0.8
    T, Q, _ = one_step(gauss, t0, [gauss_exact(t0)], h)
    level = gauss_exact(0.65)
    args = (level, sign)
    out = np.empty(1)

    def g(t):
        dense_eval_step(T, Q, 0, t, out)
        return y_minus_level(t, out, args)

    ga, gb = g(T[0]), g(T[1])
    assert ga * gb < 0
    t_event = locate_event(y_minus_level, args, T, Q, 0, ga, gb, out)
    t_ref = brentq(g, min(T), max(T), xtol=1e-16, rtol=1e-15)
    assert abs(t_event - t_ref) <= 2e-14
    assert t_event == pytest.approx(0.65, abs=1e-5)  # one step of 0.3: error ~3e-6


def test_event_after_step_cases():
    """Fires on a crossing or an exact zero at the step end; not on a zero at its start."""
    # y' = 1 from y(0) = 0 in one step of 1: the interpolant is y = t up to round-off.
    T, Q, y_new = one_step(const_one, 0.0, [0.0], 1.0)
    ytmp = np.empty(1)
    fired, t_event, g_new = event_after_step(y_minus_level, (0.25, 1.0), T, Q, 1, -0.25, y_new,
                                             ytmp)
    assert fired and t_event == pytest.approx(0.25, abs=1e-14)
    assert g_new == pytest.approx(0.75, abs=1e-14)
    fired, t_event, _ = event_after_step(y_minus_level, (y_new[0], 1.0), T, Q, 1, -1.0, y_new,
                                         ytmp)
    assert fired and t_event == 1.0
    fired, t_event, g_new = event_after_step(y_minus_level, (-1.0, 1.0), T, Q, 1, 1.0, y_new,
                                             ytmp)
    assert not fired and t_event == 1.0 and g_new == pytest.approx(2.0, abs=1e-14)
    # g_old == 0: the zero at the start of the step was already seen and is not a crossing.
    fired, _, _ = event_after_step(y_minus_level, (0.0, 1.0), T, Q, 1, 0.0, y_new, ytmp)
    assert not fired
