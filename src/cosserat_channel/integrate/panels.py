"""Chebyshev panels: a nested quadrature marched panel by panel, for Numba.

On a panel ``[a, b]`` with ``x`` in ``[-1, 1]`` (``xi = m + r x``, ``m = (a+b)/2``, ``r = (b-a)/2``)
the module integrates, from the panel's upper end ``b`` downwards,

    y(x) = y(1) - r int_x^1 f,        J(x) = J(1) + r int_x^1 g exp(y),

from the values of ``f`` and ``g`` at the ``DEGREE + 1`` Chebyshev-Lobatto nodes ``X`` (``X[0] = 1``,
``X[DEGREE] = -1``): the interpolant of ``f`` through the nodes is integrated exactly
(Clenshaw-Curtis, here indefinitely), which gives ``y`` at the nodes, hence ``g exp(y)`` there,
which is integrated the same way. Both results are kept as their values at the upper end plus
Chebyshev series of degree ``DEGREE + 1`` of the increments (the panel's dense output), and the
error of each integral is estimated from the last Chebyshev coefficients of its integrand.

The dense output is evaluated in ``u = 1 - x``, the distance from the upper end, as the value there
plus ``sum_k c_k (T_k(1 - u) - 1)``, with ``T_k - 1`` from a recurrence of its own
(:func:`panel_value`): the increment keeps its relative precision however small ``u`` is, where
a Chebyshev sum at ``x = 1 - u`` would lose it once ``u`` is below ~1e-8 (a shear layer that is
a tiny fraction of the first panel).

For an integrand analytic on the panel the coefficients fall geometrically, so the error falls
like ``r^(DEGREE+1)`` as panels shrink: order 9 with 9 evaluations per panel, against order 5 with
6 for a Runge-Kutta step. Panels must not straddle a kink of the integrand (a step boundary of a
piecewise-polynomial input): the caller cuts them there.

The tables are computed once, at import, from :mod:`numpy.polynomial.chebyshev`; the kernels
take plain arrays and floats (no physics here; :mod:`cosserat_channel.solver.stage2` supplies ``f`` and ``g``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.polynomial import chebyshev as _cheb

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE

__all__ = ["DEGREE", "N_NODES", "N_COEF", "TOP", "N_ROWS", "X", "integrate_panel", "panel_value",
           "panel_value_d", "panel_value_d2", "panel_error_factor", "cumulative", "partial"]

DEGREE = 8
N_NODES = DEGREE + 1
N_COEF = DEGREE + 2  # the integrals are one degree above the interpolants
TOP = N_COEF  # the row of a panel's dense output that holds the values at its upper end
N_ROWS = N_COEF + 1


def _tables(n):
    x = np.cos(np.pi * np.arange(n + 1) / n)
    to_coef = np.linalg.inv(_cheb.chebvander(x, n))  # values at x -> Chebyshev coefficients
    int_coef = np.empty((n + 2, n + 1))
    for i in range(n + 1):
        # coefficients of int_x^1 p, p the interpolant of the i-th unit vector
        int_coef[:, i] = -_cheb.chebint(to_coef[:, i], lbnd=1.0)
    int_val = _cheb.chebvander(x, n + 1) @ int_coef  # values at x -> int_x^1 p at x
    return x, to_coef, int_coef, int_val


X, _TO_COEF, _INT_COEF, _INT_VAL = _tables(DEGREE)
_TAIL = np.ascontiguousarray(_TO_COEF[DEGREE - 3:DEGREE + 1])  # rows of the last four coefficients


@njit(**_JIT)
def panel_error_factor(err, tol):
    """Factor for the next panel's length from this one's error estimate (order ``DEGREE + 1``),
    between 1/5 and 4."""
    if not err > 0.0:
        return 4.0
    fac = 0.9 * (tol / err) ** (1.0 / (DEGREE + 1))
    return min(4.0, max(0.2, fac))


@njit(**_JIT)
def _tail_estimate(v):
    # The interpolant's error from its last coefficients: the last pair's size times the ratio
    # of the last pair to the one before (geometric decay extrapolated one pair further), or the
    # last pair itself where the coefficients do not decay.
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    t3 = 0.0
    for i in range(N_NODES):
        t0 += _TAIL[0, i] * v[i]
        t1 += _TAIL[1, i] * v[i]
        t2 += _TAIL[2, i] * v[i]
        t3 += _TAIL[3, i] * v[i]
    before = abs(t0) + abs(t1)
    last = abs(t2) + abs(t3)
    if last < before:
        return last * last / before
    return last


@njit(**_JIT)
def integrate_panel(f, g, y_b, J_b, r, Q, p, y_nodes):
    """One panel of the nested quadrature (module docstring), from its upper end.

    Parameters
    ----------
    f, g : ndarray of float64, shape (N_NODES,)
        The integrands at the nodes ``X``; ``g`` is overwritten with ``g exp(y)``.
    y_b, J_b : float
        ``y`` and ``J`` at the panel's upper end.
    r : float
        Half the panel's length.
    Q : ndarray of float64, shape (M, N_ROWS, 2)
        Receives, in ``Q[p, :, 0]`` and ``Q[p, :, 1]``, the dense output of ``y`` and ``J`` on the
        panel: the Chebyshev coefficients of their increments from the upper end (rows
        ``0..N_COEF-1``) and the values there (row ``TOP``); :func:`panel_value` evaluates it.
    p : int
        The panel's row in ``Q``.
    y_nodes : ndarray of float64, shape (N_NODES,)
        Receives ``y`` at the nodes.

    Returns
    -------
    err_y, err_J : float
        Error estimates of the two integrals over the panel: ``r`` times the tail of the
        integrand's Chebyshev series, extrapolated from its last four coefficients
        (``err_J`` adds what the error of ``y`` does to ``J``).
    """
    n = N_NODES
    # y's increments from the upper end, r int f, and their error estimate: the same sums, in the
    # same order, as every other integral over the panel
    _, err_y = cumulative(f, r, y_nodes)
    for j in range(n):
        y_nodes[j] = y_b - y_nodes[j]
        g[j] *= math.exp(y_nodes[j])
    # Each coefficient summed in a local, not in Q: the compiler cannot tell Q from f and g, so
    # a sum in Q would be stored and loaded again at every term.
    for k in range(N_COEF):
        cy = 0.0
        cJ = 0.0
        for i in range(n):
            cy += _INT_COEF[k, i] * f[i]
            cJ += _INT_COEF[k, i] * g[i]
        Q[p, k, 0] = cy * -r
        Q[p, k, 1] = cJ * r
    Q[p, TOP, 0] = y_b
    Q[p, TOP, 1] = J_b
    eg = _tail_estimate(g)
    # J at the lower end minus J_b is the panel's increment; an error e in y is e * that in J
    dJ = 0.0
    for i in range(n):
        dJ += _INT_VAL[n - 1, i] * g[i]
    return err_y, r * eg + err_y * abs(r * dJ)


@njit(**_JIT)
def cumulative(v, r, out):
    """``out[j] = r int_(X[j])^1 v`` for the interpolant of ``v`` through the nodes (one integral
    of :func:`integrate_panel`, without a dense output). Returns ``(out[DEGREE], err)``: the
    whole panel's integral and its error estimate, ``r`` times the tail of ``v``'s Chebyshev series."""
    n = N_NODES
    # Each sum in a local (as in integrate_panel): nine independent chains of additions, which
    # the processor runs side by side.
    for j in range(n):
        acc = 0.0
        for i in range(n):
            acc += _INT_VAL[j, i] * v[i]
        out[j] = acc * r
    return out[n - 1], r * _tail_estimate(v)


@njit(**_JIT)
def partial(v, r, u):
    """``r int_(1-u)^1 v`` for the interpolant of ``v`` through the nodes, at any ``u`` in
    ``[0, 2]``: :func:`cumulative` between the nodes, evaluated as :func:`panel_value` does."""
    x2 = 2.0 * (1.0 - u)
    d_prev = 0.0
    d = -u
    acc = 0.0
    for k in range(1, N_COEF):
        if k > 1:
            d, d_prev = x2 * d - d_prev - 2.0 * u, d
        c = 0.0
        for i in range(N_NODES):
            c += _INT_COEF[k, i] * v[i]
        acc += c * d
    return r * acc


@njit(**_JIT_INLINE)
def panel_value(Q, p, comp, u):
    """Component ``comp`` of panel ``p``'s dense output at ``u = 1 - x`` (``u`` in ``[0, 2]``).

    ``T_k(1 - u) - 1 = d_k`` by ``d_(k+1) = 2 x d_k - d_(k-1) - 2u`` (``d_0 = 0``, ``d_1 = -u``), the
    Chebyshev recurrence written for the differences: each ``d_k`` is O(k^2 u) and computed to
    a few ulps of itself.
    """
    x2 = 2.0 * (1.0 - u)
    d_prev = 0.0
    d = -u
    acc = Q[p, 1, comp] * d
    for k in range(2, N_COEF):
        d, d_prev = x2 * d - d_prev - 2.0 * u, d
        acc += Q[p, k, comp] * d
    return Q[p, TOP, comp] + acc


@njit(**_JIT)
def panel_value_d(Q, p, comp, u):
    """``(value, d value/du)`` of :func:`panel_value`, in one pass."""
    x2 = 2.0 * (1.0 - u)
    d_prev = 0.0
    d = -u
    e_prev = 0.0
    e = -1.0  # d d_k / du
    acc = Q[p, 1, comp] * d
    dacc = Q[p, 1, comp] * e
    for k in range(2, N_COEF):
        e, e_prev = x2 * e - 2.0 * d - e_prev - 2.0, e
        d, d_prev = x2 * d - d_prev - 2.0 * u, d
        acc += Q[p, k, comp] * d
        dacc += Q[p, k, comp] * e
    return Q[p, TOP, comp] + acc, dacc


@njit(**_JIT)
def panel_value_d2(Q, p, comp, u):
    """``(value, d value/du, d2 value/du2)`` of :func:`panel_value`, in one pass (the value and
    the first derivative are those of :func:`panel_value_d`, bit for bit)."""
    x2 = 2.0 * (1.0 - u)
    d_prev = 0.0
    d = -u
    e_prev = 0.0
    e = -1.0  # d d_k / du
    g_prev = 0.0
    g = 0.0  # d2 d_k / du2
    acc = Q[p, 1, comp] * d
    dacc = Q[p, 1, comp] * e
    d2acc = 0.0
    for k in range(2, N_COEF):
        g, g_prev = x2 * g - 4.0 * e - g_prev, g
        e, e_prev = x2 * e - 2.0 * d - e_prev - 2.0, e
        d, d_prev = x2 * d - d_prev - 2.0 * u, d
        acc += Q[p, k, comp] * d
        dacc += Q[p, k, comp] * e
        d2acc += Q[p, k, comp] * g
    return Q[p, TOP, comp] + acc, dacc, d2acc
