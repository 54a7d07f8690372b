"""Tests for the helpers the integrators share, in ``cosserat_channel.integrate.stepping``."""

import math

import numpy as np
import pytest
from scipy.integrate._ivp.common import select_initial_step

from numba import njit

from cosserat_channel.integrate import dense, dop853, rk45, rosenbrock, stepping
from cosserat_channel.integrate.stepping import (all_finite, count_trial, error_norm, initial_guess,
                                                 initial_step, rms_norm, step_too_small)
from problems import nan_after_t0, stiff_then_flat, vdp


def test_error_norm_closed_form():
    """The error norm scales each component with max(|y|, |y_new|) and takes the RMS."""
    y_err = np.array([1e-6, -2e-6])
    y = np.array([1.0, -2.0])
    y_new = np.array([3.0, 1.0])
    atol = np.array([1e-8, 1e-7])
    rtol = 1e-3
    sc = atol + rtol * np.array([3.0, 2.0])
    expected = math.sqrt(np.mean((y_err / sc) ** 2))
    assert error_norm(y_err, y, y_new, atol, rtol) == pytest.approx(expected, rel=1e-15)


def test_rms_norm_scales_with_y_only():
    """rms_norm uses |y| alone for the relative scale."""
    v = np.array([2.0, 0.0])
    y = np.array([-4.0, 100.0])
    atol = np.array([1.0, 1.0])
    assert rms_norm(v, y, atol, 0.25) == pytest.approx(math.sqrt((2.0 / 2.0) ** 2 / 2))


def test_all_finite():
    """all_finite is False as soon as one entry is NaN or infinite."""
    assert all_finite(np.array([0.0, -1e308]))
    assert not all_finite(np.array([0.0, np.nan]))
    assert not all_finite(np.array([-np.inf, 1.0]))


@pytest.mark.parametrize("direction", [1.0, -1.0])
@pytest.mark.parametrize("rtol", [1e-3, 1e-9])
def test_initial_step_agrees_with_scipy(direction, rtol):
    """HINIT gives scipy's select_initial_step, forward and backward, for the same order."""
    y0 = np.array([2.0, 0.5])
    atol = np.array([1e-9, 1e-6])
    f0 = np.empty(2)
    vdp(0.0, y0, (5.0,), f0)
    y1, f1 = np.empty(2), np.empty(2)
    h = initial_step(vdp, 0.0, y0, f0, (5.0,), direction, rtol, atol, 0.7, 3.0, 4, y1, f1)

    def fun(t, y):
        out = np.empty(2)
        vdp(t, y, (5.0,), out)
        return out

    ref = select_initial_step(fun, 0.0, y0, 3.0 * direction, 0.7, f0, direction, 4, rtol, atol)
    assert h == pytest.approx(ref, rel=1e-14)
    assert 0.0 < h <= 0.7


def test_every_outcome_code_has_one_name_and_its_own_message():
    """The five outcome codes are distinct, and each has a message that no other code shares."""
    codes = [stepping.SUCCESS, stepping.EVENT, stepping.MAX_STEPS, stepping.STEP_TOO_SMALL,
             stepping.NONFINITE]
    assert len(set(codes)) == len(codes) == len(stepping.MESSAGES)
    texts = [stepping.message(c) for c in codes]
    assert all(texts) and len(set(texts)) == len(texts)
    assert stepping.message(np.int64(stepping.EVENT)) == stepping.MESSAGES[stepping.EVENT]
    assert stepping.message(7) == "unknown outcome code 7"


@njit(cache=True)
def _unit_jac(t, y, args):
    return -1.0, 0.0


@njit(cache=True)
def _nan_runs(h0, T, Q, stats):
    # The three drivers on a right-hand side that is NaN at every trial step.
    y0 = np.ones(1)
    atol = np.full(1, 1e-9)
    a = rk45.dopri5(nan_after_t0, stepping.no_event, 0.0, y0, 1.0, (), 1e-6, atol, h0, 0.0, T, Q,
                    stats[0])
    b = dop853.dop853(nan_after_t0, stepping.no_event, 0.0, y0, 1.0, (), 1e-6, atol, h0, 0.0, T, Q,
                      stats[1])
    c = rosenbrock.rodas4(nan_after_t0, _unit_jac, stepping.no_event, 0.0, y0, 1.0, (), 1e-6, atol,
                          h0, 0.0, T, Q, stats[2])
    return a, b, c


@pytest.mark.parametrize("h0", [0.0, 0.1])
def test_every_driver_gives_up_after_the_same_run_of_nonfinite_trial_steps(h0):
    """dopri5, dop853 and rodas4 stop with NONFINITE at the NONFINITE_MAX_TRIES-th non-finite
    trial step in a row, having stored no step."""
    T, Q = np.empty(11), np.empty((10, dense.N_DENSE, 1))
    stats = np.zeros((3, stepping.N_STATS), np.int64)
    for status, n, t_stop in _nan_runs(h0, T, Q, stats):
        assert (status, n, t_stop) == (stepping.NONFINITE, 0, 0.0)
    assert np.all(stats[:, stepping.STAT_REJECTED] == stepping.NONFINITE_MAX_TRIES)
    assert np.all(stats[:, stepping.STAT_ACCEPTED] == 0)


def test_count_trial_gives_up_only_on_a_run_of_nonfinite_steps():
    """A finite rejection or an acceptance ends the run; the give-up comes at its
    NONFINITE_MAX_TRIES-th step, and every trial is counted once."""
    stats = np.zeros(stepping.N_STATS, np.int64)
    n = 0
    for _ in range(stepping.NONFINITE_MAX_TRIES - 1):
        n, give_up = count_trial(False, math.nan, n, stats)
        assert not give_up
    assert n == stepping.NONFINITE_MAX_TRIES - 1
    assert count_trial(True, 0.5, n, stats) == (0, False)
    n, give_up = count_trial(False, 2.0, n, stats)
    assert (n, give_up) == (0, False)
    for _ in range(stepping.NONFINITE_MAX_TRIES):
        n, give_up = count_trial(False, math.inf, n, stats)
    assert give_up and n == stepping.NONFINITE_MAX_TRIES
    assert stats[stepping.STAT_ACCEPTED] == 1
    assert stats[stepping.STAT_REJECTED] == 2 * stepping.NONFINITE_MAX_TRIES


def test_step_too_small_is_relative_to_t():
    """Hairer's test: a step is too small at ten machine epsilons of |t|, either sign of t."""
    for t in (1.0, -3.0, 1e8):
        tiny = 10.0 * stepping.EPS * abs(t)
        assert step_too_small(tiny, t) and not step_too_small(1.5 * tiny, t)
    assert step_too_small(0.0, 0.0) and not step_too_small(1e-300, 0.0)


def test_initial_guess_is_hinit_first_estimate():
    """0.01 ||y0|| / ||f0|| in the scaled RMS norm; 1e-6 where a norm is below 1e-5 or NaN."""
    y0, f0 = np.array([2.0, 0.5]), np.array([-1.0, 4.0])
    atol, rtol = np.array([1e-9, 1e-6]), 1e-3
    h, d1 = initial_guess(y0, f0, atol, rtol)
    assert d1 == rms_norm(f0, y0, atol, rtol)
    assert h == pytest.approx(0.01 * rms_norm(y0, y0, atol, rtol) / d1, rel=1e-15)
    assert initial_guess(np.zeros(2), f0, atol, rtol)[0] == 1e-6
    assert initial_guess(y0, np.array([math.nan, 0.0]), atol, rtol)[0] == 1e-6


@pytest.mark.parametrize("pair", ["dopri5", "dop853"])
def test_a_stiffness_estimate_of_zero_replaces_the_last_one(pair):
    """Past a stiff stretch (y' = -1000 y up to t = 0.01, then y' = t: Jacobian 0) the steps grow
    again: each step's estimate of |lambda| (0 there) replaces the last, so the stability check
    does not keep the steps at the stiff stretch's boundary (~3000 of them over [0.01, 10])."""
    t_s, t_end = 0.01, 10.0
    T, Q = np.empty(100_001), np.empty((100_000, dense.N_DENSE, 1))
    stats = np.zeros(stepping.N_STATS, np.int64)
    march = rk45.dopri5 if pair == "dopri5" else dop853.dop853
    status, n, _ = march(stiff_then_flat, stepping.no_event, 0.0, np.array([1.0]), t_end,
                         (t_s,), 1e-8, np.array([1e-10]), 0.0, 0.0, T, Q, stats)
    assert status == stepping.SUCCESS
    # at the stiff stretch's boundary the rest would take 1000 (t_end - t_s) / (1.5 x 3.3) steps
    assert np.count_nonzero(T[1:n + 1] > 2 * t_s) < 100
    y = np.empty(1)
    dense.dense_eval_step(T, Q, n - 1, t_end, y)
    # y(t_s) = exp(-10) up to the tolerance, then y grows by (t_end^2 - t_s^2) / 2
    assert y[0] == pytest.approx(math.exp(-1000.0 * t_s) + 0.5 * (t_end**2 - t_s**2), rel=1e-6)
