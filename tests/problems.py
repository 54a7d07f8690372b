"""Test problems with closed-form solutions, shared by the integrator and dense-output tests.

Module level so that Numba can cache the right-hand sides.
"""

import numpy as np
from numba import njit


@njit(cache=True)
def gauss(t, y, args, out):
    # y = y0 * exp(-(t^2 - t0^2))
    out[0] = -2.0 * t * y[0]


@njit(cache=True)
def oscillator(t, y, args, out):
    # y'' = -w^2 y with w = args[0]
    w = args[0]
    out[0] = y[1]
    out[1] = -w * w * y[0]


@njit(cache=True)
def const_one(t, y, args, out):
    out[0] = 1.0


def gauss_exact(t, t0=0.0, y0=1.0):
    return y0 * np.exp(-(np.asarray(t) ** 2 - t0 * t0))


def osc_exact(t, w):
    t = np.asarray(t, dtype=float)
    return np.stack([np.cos(w * t), -w * np.sin(w * t)], axis=-1)


OSC_ARGS = (3.0,)
