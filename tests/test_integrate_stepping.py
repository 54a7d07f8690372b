"""Tests for the helpers the integrators share, in ``cosserat_channel.integrate.stepping``."""

import math

import numpy as np
import pytest
from scipy.integrate._ivp.common import select_initial_step

from cosserat_channel.integrate.stepping import all_finite, error_norm, initial_step, rms_norm
from problems import vdp


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
