"""Partial derivatives of the model's equations, for the sensitivities of the outputs.

The equations are those of :mod:`~cosserat_channel.physics.model` (stage 1
``eta delta' = (A+1) xi - sqrt(D)``, the rates ``B`` and ``h`` of e-60 / e-59, ``D`` of eq:a3),
differentiated by hand with respect to the state ``delta`` and the parameters ``(eta, A, N)`` of
the exact similarity (docs/model.md, section 7):

    D_delta = 4 (A+1) (N - delta),   D_A = 2 A xi^2 + 2 delta (2N - delta),   D_N = 4 (A+1) delta,
    f = ((A+1) xi - sqrt(D)) / eta,  B = 2 (A+1) (N - delta) / (eta sqrt(D)),
    h = (A+1) (1 - (A-1) xi / sqrt(D)).

Where a partial is a difference of near-equal terms on the slow manifold ``sqrt(D) ~ (A+1) xi``
of small eta, it is written in ``gap = (A+1) xi - sqrt(D) = eta f`` (with ``D_A = (A+1) xi^2 +
D/(A+1)``), so that the cancellation is exact (see :func:`rate_partials`).

``D`` itself is passed in (evaluated cancellation-free by the caller); ``r = 1/sqrt(D)``.
"""

from __future__ import annotations

import math

from numba import njit

from .._jit import JIT_INLINE as _JIT_INLINE
from . import model

# Rows of the partials array filled by `rate_partials` (``p`` runs over eta, A, N).
Q_B = 0  # B (e-60)
Q_H = 1  # h (e-59)
Q_B_DELTA = 2  # dB/d delta
Q_H_DELTA = 3  # dh/d delta
Q_F = 4  # df/dp of the stage-1 right-hand side, rows 4..6
Q_BP = 7  # dB/dp, rows 7..9
Q_HP = 10  # dh/dp, rows 10..12 (h does not depend on eta: row 10 is 0)
N_Q = 13


@njit(**_JIT_INLINE)
def yield_D_partials(xi, delta, A, N):
    """``(dD/d delta, dD/dA, dD/dN)`` of eq:a3 (``D`` does not depend on eta)."""
    a1 = A + 1.0
    return 4.0 * a1 * (N - delta), 2.0 * A * xi * xi + 2.0 * delta * (2.0 * N - delta), 4.0 * a1 * delta


@njit(**_JIT_INLINE)
def rate_partials(xi, delta, D, eta, A, N, out, j):
    """``B``, ``h`` and their partials at ``(xi, delta)`` into column ``j`` of ``out`` (rows ``Q_*``).

    ``df/d delta = -B`` (model.md), so the stage-1 Jacobian needs no row of its own.
    """
    r = 1.0 / math.sqrt(D)
    a1 = A + 1.0
    q = N - delta
    D_d, _, D_N = yield_D_partials(xi, delta, A, N)
    r3 = r * r * r
    B = model.spin_rate_B(delta, r, eta, A, N)
    c = 2.0 * a1 / eta
    out[Q_B, j] = B
    out[Q_H, j] = model.shear_rate_h(xi, r, A)
    out[Q_B_DELTA, j] = -c * (r + 0.5 * q * r3 * D_d)
    hd = 0.5 * a1 * (A - 1.0) * xi * r3
    out[Q_H_DELTA, j] = hd * D_d
    sq = 1.0 / r
    gap = a1 * xi - sq  # eta f: on the slow manifold of small eta a difference of near equals
    out[Q_F, j] = -gap / (eta * eta)
    # The A partials written with D_A = (A+1) xi^2 + D/(A+1), so that the cancellation of
    # xi - D_A/(2 sqrt(D)) (second order in gap) and of 1 - (A+1) xi/sqrt(D) (first order) is
    # exact: the plain forms leave their rounding ~eps xi^2/gap^2 relative, which no panel of
    # the sensitivity march can resolve below at small eta.
    out[Q_F + 1, j] = -gap * gap * r / (2.0 * a1 * eta)
    out[Q_F + 2, j] = -0.5 * D_N * r / eta
    out[Q_BP, j] = -B / eta
    out[Q_BP + 1, j] = q / eta * (-gap) * (sq + a1 * xi) * r3
    out[Q_BP + 2, j] = c * (r - 0.5 * q * r3 * D_N)
    out[Q_HP, j] = 0.0
    out[Q_HP + 1, j] = -gap * r * (1.0 - 0.5 * (A - 1.0) * xi * r * (1.0 + a1 * xi * r))
    out[Q_HP + 2, j] = hd * D_N
