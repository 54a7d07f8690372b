"""Tests for the Numba DOP853 integrator in ``cosserat_channel.integrate.dop853``.

The independent references are scipy's own DOP853 (the same method and controller, written
separately in numpy: same steps, same evaluations, same dense output to rounding) and closed forms.
"""

import math

import numpy as np
import pytest
from numba import njit
from scipy.integrate import solve_ivp

from cosserat_channel.integrate import dense, dop853, rk45
from cosserat_channel.integrate.stepping import (EVENT, N_STATS, NONFINITE, STAT_ACCEPTED, STAT_FEV,
                                       STAT_REJECTED, STAT_STIFF, STAT_STIFF_STEPS, SUCCESS,
                                       no_event)
from problems import (OSC_ARGS, gauss, gauss_exact, nan_after_t0, osc_exact, oscillator, stiff,
                      y_half)


@njit(cache=True)
def growth(t, y, args, out):
    # y = exp(sin t)
    out[0] = math.cos(t) * y[0]


@njit(cache=True)
def linear(t, y, args, out):
    out[0] = args[0] * y[0]


@njit(cache=True)
def _run(fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats, rho0):
    return dop853.dop853(fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats,
                         rho0)


def run(fun, t0, y0, t_end, args=(), rtol=1e-8, atol=1e-12, event=no_event, h0=0.0, max_steps=10_000,
        rho0=0.0):
    y0 = np.asarray(y0, dtype=float)
    T = np.empty(max_steps + 1)
    Q = np.empty((max_steps, dense.N_DENSE, y0.size))
    stats = np.zeros(N_STATS, np.int64)
    status, n, t_stop = _run(fun, event, float(t0), y0, float(t_end), args, rtol,
                             np.full(y0.size, atol), h0, 0.0, T, Q, stats, float(rho0))
    return status, n, t_stop, T[:n + 1], Q[:n], stats


def _dense(T, Q, n, ts):
    out = np.empty((ts.size, 1))
    dense.dense_eval_many(T, Q, n, ts, out)
    return out[:, 0]


@pytest.mark.parametrize("rtol", [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12])
def test_same_controller_and_values_as_scipy(rtol):
    """The step sizes, step count, end value and dense output of scipy's DOP853.

    The two codes round the error estimate differently (scipy sums it with the BLAS of the
    machine), and a step whose error lies within that rounding of 1 is accepted by one code and
    rejected by the other; from there the step sequences part. So the sequences are compared as a
    whole: as many steps to one (a change of the controller's safety factor from 0.9 to 0.8, or of
    its exponent, moves the count by 10 % and more), and the values to the accuracy both codes
    promise.
    """
    status, n, _, T, Q, stats = run(growth, 0.0, [1.0], 10.0, rtol=rtol, atol=1e-14)
    ref = solve_ivp(lambda t, y: np.cos(t) * y, [0.0, 10.0], [1.0], method="DOP853", rtol=rtol,
                    atol=1e-14, dense_output=True)
    assert status == SUCCESS
    n_ref = ref.t.size - 1
    assert abs(n - n_ref) <= 1
    # 12 evaluations a trial step and 3 more for an accepted step's dense output in both codes
    assert stats[STAT_FEV] == 1 + 1 + 12 * (stats[STAT_ACCEPTED] + stats[STAT_REJECTED]) + 3 * n
    ts = np.linspace(0.0, 10.0, 777)
    exact = np.exp(np.sin(ts))
    ours = _dense(T, Q, n, ts)
    # the 7th-order interpolants of both codes err by a multiple of their steps' error
    assert np.max(np.abs(ours - ref.sol(ts)[0]) / exact) <= 20 * rtol
    assert abs(Q[-1, 0, 0] + Q[-1, 1, 0] - ref.y[0, -1]) <= 2 * rtol * exact[-1]


@pytest.mark.parametrize("rtol", [1e-6, 1e-9, 1e-12])
def test_accuracy_against_closed_forms(rtol):
    """End values and dense output of exp(sin t) and a harmonic oscillator within a few rtol."""
    status, n, _, T, Q, _ = run(growth, 0.0, [1.0], 10.0, rtol=rtol, atol=1e-15)
    ts = np.linspace(0.0, 10.0, 501)
    exact = np.exp(np.sin(ts))
    ours = _dense(T, Q, n, ts)
    assert status == SUCCESS
    assert abs(Q[-1, 0, 0] + Q[-1, 1, 0] - exact[-1]) <= 10 * rtol * exact[-1]
    # the 7th-order interpolant: within 100 rtol (its error is a multiple of the step's)
    assert np.max(np.abs(ours - exact) / exact) <= 100 * rtol
    status, n, _, T, Q, _ = run(oscillator, 0.0, [1.0, 0.0], 5.0, OSC_ARGS, rtol=rtol, atol=1e-15)
    y_end = Q[-1, 0] + Q[-1, 1]
    assert status == SUCCESS
    assert np.max(np.abs(y_end - osc_exact(5.0, OSC_ARGS[0]))) <= 30 * rtol * OSC_ARGS[0]


def test_cheaper_than_dopri5_at_a_tight_rtol():
    """The reason it is here: at a tight rtol it needs far fewer evaluations than DOPRI5, both
    within the tolerance (exp(-t^2) over [0, 3])."""
    status, n, _, T, Q, stats = run(gauss, 0.0, [1.0], 3.0, rtol=1e-10, atol=1e-16)
    s5 = rk45.integrate(gauss, 0.0, [1.0], 3.0, rtol=1e-10, atol=1e-16)
    err = abs(Q[-1, 0, 0] + Q[-1, 1, 0] - gauss_exact(3.0))
    err5 = abs(s5.y_stop[0] - gauss_exact(3.0))
    assert status == SUCCESS and s5.status == SUCCESS
    assert stats[STAT_FEV] < 0.5 * s5.n_fev
    assert max(err, err5) <= 1e-10


def test_event_location_forward():
    """The crossing y = 1/2 of exp(-t^2) is located at sqrt(ln 2) to 1e-10 on the dense output."""
    status, n, t_stop, T, Q, _ = run(gauss, 0.0, [1.0], 2.0, rtol=1e-11, atol=1e-13, event=y_half)
    assert status == EVENT
    assert abs(t_stop - math.sqrt(math.log(2.0))) <= 1e-10
    assert T[-2] <= t_stop <= T[-1]


def test_counters_and_evaluation_identity():
    """Evaluations: 1 + 1 (HINIT) + 15 per accepted + 12 per rejected step."""
    status, n, _, _, _, stats = run(gauss, 0.0, [1.0], 3.0, rtol=1e-9, atol=1e-14)
    assert status == SUCCESS and stats[STAT_ACCEPTED] == n
    assert stats[STAT_FEV] == 2 + 15 * n + 12 * stats[STAT_REJECTED]
    status, n, _, _, _, stats = run(gauss, 0.0, [1.0], 3.0, rtol=1e-9, atol=1e-14, h0=0.01)
    assert stats[STAT_FEV] == 1 + 15 * n + 12 * stats[STAT_REJECTED]


def test_nonfinite_right_hand_side_is_a_status():
    status, n, t_stop, *_ = run(nan_after_t0, 0.0, [1.0], 1.0)
    assert status == NONFINITE and n == 0 and t_stop == 0.0


def test_stiffness_detected_on_a_stiff_linear_problem():
    """y' = -1000 (y - cos t) at rtol 1e-4: the steps sit at DOP853's stability boundary, so the
    test counts as stiff exactly the accepted steps with 1000 |h| > 6.1 (the true |h lambda|,
    read off the step ends, within rounding), and a run of 15 declares the problem stiff."""
    status, n, _, T, Q, stats = run(stiff, 0.0, [0.0], 5.0, rtol=1e-4, atol=1e-7, max_steps=5000)
    assert status == SUCCESS
    hlamb = 1000.0 * np.diff(T)
    assert np.sum(hlamb > 6.1 * (1 + 1e-9)) <= stats[STAT_STIFF_STEPS] <= np.sum(hlamb > 6.1 * (1 - 1e-9))
    assert stats[STAT_STIFF_STEPS] > 0.5 * n
    assert stats[STAT_STIFF] == 1
    assert abs(Q[-1, 0, 0] + Q[-1, 1, 0] - (math.cos(5.0) + 1e-3 * math.sin(5.0))) < 1e-4


@pytest.mark.parametrize("rtol", [1e-3, 1e-6, 1e-10])
def test_nonstiff_problem_not_flagged(rtol):
    """exp(-t^2) over [0, 3] is not stiff at any tolerance: no step counts, no flag."""
    status, _, _, _, _, stats = run(gauss, 0.0, [1.0], 3.0, rtol=rtol, atol=1e-14)
    assert status == SUCCESS
    assert stats[STAT_STIFF_STEPS] == 0 and stats[STAT_STIFF] == 0


def _linear_step(z):
    """``(R(z), E5 part, E3 part)`` of one DOP853 step on y' = lambda y from y = 1, z = h lambda,
    from the stage polynomials of the module's tableau."""
    k = np.zeros(dop853.N_STAGES + 1)
    for s in range(dop853.N_STAGES):
        k[s] = 1.0 + z * (dop853.A[s, :s] @ k[:s])
    k[dop853.N_STAGES] = 1.0 + z * (dop853.B @ k[:dop853.N_STAGES])
    return k[dop853.N_STAGES], z * (dop853.E5 @ k), z * (dop853.E3 @ k)


def test_first_step_on_a_zero_of_the_error_estimate_is_rejected_given_rho0():
    """Hairer's blended error estimate vanishes with its 5th-order part: on y' = lambda y at a
    z = h lambda near -23, where the step multiplies y by |R(z)| ~ 3e3 instead of e^z. A first
    step of that size passes the error test (as stage 1's first step of half its stretch did,
    next to such a zero, on a clipped right-hand side). Told |lambda| at the start, the
    integrator rejects it, and the solution is exp(lambda t) to the tolerance."""
    from cosserat_channel.integrate.stepping import STABLE_FACTOR

    zs = np.linspace(-40.0, -10.0, 301)
    e5 = np.array([_linear_step(z)[1] for z in zs])
    k = int(np.flatnonzero(np.sign(e5[1:]) != np.sign(e5[:-1]))[0])
    lo, hi = zs[k], zs[k + 1]
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.sign(_linear_step(mid)[1]) == np.sign(e5[k]):
            lo = mid
        else:
            hi = mid
    R = _linear_step(lo)[0]
    assert abs(R) > 1e3
    lam, rtol, atol = -100.0, 1e-8, 1e-12
    h0 = lo / lam
    # Unchecked, the first step is taken as it is, with the useless factor R.
    _, n, _, T, Q, _ = run(linear, 0.0, [1.0], 1.0, args=(lam,), rtol=rtol, atol=atol, h0=h0)
    assert T[1] == h0 and abs(Q[0, 0, 0] + Q[0, 1, 0]) > 1e3
    status, n, _, T, Q, stats = run(linear, 0.0, [1.0], 1.0, args=(lam,), rtol=rtol, atol=atol,
                                    h0=h0, rho0=-lam)
    assert status == SUCCESS and stats[STAT_REJECTED] >= 1
    assert np.max(np.diff(T)) * -lam <= STABLE_FACTOR * dop853.STIFF_THRESHOLD * (1 + 1e-12)
    # Steps at the stability boundary (|R| <= 1) do not amplify the errors of earlier ones: the
    # global error is at most the sum of the n local ones, each within rtol |y| + atol, |y| <= 1.
    ts = np.linspace(0.0, 1.0, 401)
    assert np.max(np.abs(_dense(T, Q, n, ts) - np.exp(lam * ts))) <= n * (rtol + atol)
