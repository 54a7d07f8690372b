"""Chebyshev-Lobatto cells: nodes, coefficients of a tensor interpolant, and its error estimate.
Imports numpy only."""

from __future__ import annotations

import math

import numpy as np

from .settings import PLATEAU_SAFETY, RATE_GEOMETRIC, ROUNDOFF, TAIL_SAFETY


def lobatto(degree):
    """Chebyshev-Lobatto nodes on [-1, 1], ascending, ends exact."""
    x = -np.cos(np.pi * np.arange(degree + 1) / degree)
    x[0], x[-1] = -1.0, 1.0
    if degree % 2 == 0:
        x[degree // 2] = 0.0
    return x


def _vandermonde(x, degree):
    """``T_k(x)`` for k = 0..degree, shape ``x.shape + (degree + 1,)``."""
    t = np.arccos(np.clip(x, -1.0, 1.0))
    return np.cos(t[..., None] * np.arange(degree + 1))


def _coefficients(values, degree_A, degree_N):
    """Tensor Chebyshev coefficients of node values ``(..., degree_A+1, degree_N+1)``."""
    ta = np.linalg.inv(_vandermonde(lobatto(degree_A), degree_A))
    tn = np.linalg.inv(_vandermonde(lobatto(degree_N), degree_N))
    return ta @ values @ tn.T


def _tail(coef):
    """The old estimate, kept as a reference: the coefficients of the two highest degrees."""
    p, q = coef.shape[-2] - 1, coef.shape[-1] - 1
    mask = np.zeros(coef.shape[-2:], dtype=bool)
    mask[p - 1:, :] = True
    mask[:, q - 1:] = True
    return np.abs(coef[..., mask]).sum(axis=-1)


def _direction_tail(S, plateau):
    """Tail of one direction from ``S[k]``, the summed magnitudes of the degree-k coefficients.

    Returns ``(tail, rate)``. Where the last six degrees decay geometrically (``rate`` per degree
    below :data:`RATE_GEOMETRIC`, the slower of two pairs of pairs of degrees, which an even or odd
    function would otherwise fool), the omitted coefficients sum to about ``S[p] rate / (1 -
    rate)``, or ``S[p-1] rate^2 / (1 - rate)`` where ``S[p]`` is small by parity (the larger is
    taken), and the interpolant's error (aliasing included) to twice that; the estimate is
    :data:`TAIL_SAFETY` times more, and never above the two-degree sum. Elsewhere (slow decay, or a
    plateau of noise in the traces) it is ``plateau`` times the two-degree sum
    ``S[p-1] + S[p]``.
    """
    p = S.size - 1
    last = S[p] + S[p - 1]
    if p < 3:
        return plateau * last, 1.0
    tiny = 1e-300
    rate = min(1.0, math.sqrt((last + tiny) / (S[p - 2] + S[p - 3] + tiny)))
    if p < 5:  # one pair of pairs: enough to ask for a higher degree, not to extrapolate
        return plateau * last, rate
    rate = max(rate, min(1.0, math.sqrt((S[p - 2] + S[p - 3] + tiny) / (S[p - 4] + S[p - 5] + tiny))))
    if rate >= RATE_GEOMETRIC:
        return plateau * last, rate
    fitted = TAIL_SAFETY * 2.0 * max(S[p], S[p - 1] * rate) * rate / (1.0 - rate)
    return min(fitted, last), rate


def _estimate(coef):
    """Error estimate of a cell's interpolants ``coef`` ``(k, p+1, q+1)`` in ``log eta``.

    Returns ``(error, tails, rates, raw)``: the largest over the transitions of the sum of the
    two directions' tails (:func:`_direction_tail`); per direction (A, N) the largest tail and
    rate; and the largest two-degree sum of both directions without any factor (what the
    refinement compares before and after, like with like).
    """
    tails = np.zeros(2)
    rates = np.zeros(2)
    err = 0.0
    raw = 0.0
    plateau = PLATEAU_SAFETY * (max(coef.shape[-2:]) - 1)
    for c in np.abs(coef):
        sa, sn = c.sum(axis=1), c.sum(axis=0)
        ta, ra = _direction_tail(sa, plateau)
        tn, rn = _direction_tail(sn, plateau)
        raw = max(raw, sa[-1] + sa[-2] + sn[-1] + sn[-2])
        err = max(err, ta + tn)
        tails = np.maximum(tails, (ta, tn))
        rates = np.maximum(rates, (ra, rn))
    return max(err, ROUNDOFF), tails, rates, raw
