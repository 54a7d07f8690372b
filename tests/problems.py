"""Test problems shared by the integrator, stepping and dense-output tests: right-hand sides with
closed-form solutions or a known behaviour (stiff, non-finite), and events.

Module level so that Numba can cache the right-hand sides.
"""

import math

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


@njit(cache=True)
def stiff(t, y, args, out):
    # Jacobian -1000: |h lambda| = 1000 |h| exactly; quasi-steady solution cos t + 1e-3 sin t.
    out[0] = -1000.0 * (y[0] - math.cos(t))


@njit(cache=True)
def nan_after_t0(t, y, args, out):
    # Finite only at t = 0, so every trial step sees NaN.
    out[0] = -y[0] if t == 0.0 else np.nan


@njit(cache=True)
def vdp(t, y, args, out):
    # Van der Pol with mu = args[0].
    mu = args[0]
    out[0] = y[1]
    out[1] = mu * (1.0 - y[0] * y[0]) * y[1] - y[0]


@njit(cache=True)
def y_half(t, y, args):
    # Event: y crosses 1/2.
    return y[0] - 0.5


def gauss_exact(t, t0=0.0, y0=1.0):
    return y0 * np.exp(-(np.asarray(t) ** 2 - t0 * t0))


def osc_exact(t, w):
    t = np.asarray(t, dtype=float)
    return np.stack([np.cos(w * t), -w * np.sin(w * t)], axis=-1)


OSC_ARGS = (3.0,)


@njit(cache=True)
def stiff_then_flat(t, y, args, out):
    # y' = -1000 y up to t = args[0], then y' = t: the Jacobian is -1000, then exactly 0, so the
    # stiffness estimate of every step past args[0] is exactly 0.
    out[0] = -1000.0 * y[0] if t < args[0] else t
