"""Reading stage 1's solution, the stress path, where stage 2 and the profiles need it.

Lookups in stage 1's dense output that go mostly from the wall towards the axis, the axis series
below where the march started, and ``D`` next to the wall as ``D(1)`` plus an increment built
from increments (:func:`_wall_form`), so that ``B ~ 1/sqrt(D)`` stays smooth where ``D(1)`` is tiny.
"""

from __future__ import annotations

import math


import numpy as np
from numba import njit

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE
from ..integrate import dense
from .._jit import EPS as _EPS
from ..physics import model
from ..physics.model import AX_C0

# The stage-2 rates and the lookups in stage 1's dense output are inlined into the stage-2 panels:
# as separate functions, each call passing the dense-output arrays cost reference-count updates.

# Slots of the small work vector kept about the stage-1 solution while reading it in order.
W_STEP = 0  # the stage-1 step of the last lookup
N_W = 1
# Above this xi stage 2 evaluates D as D(1) + [D(xi) - D(1)] (see _wall_form).
XI_WALL_FORM = 0.5


@njit(**_JIT_INLINE)
def xi_of_log(t):
    """``(xi, s)`` with ``xi = exp(t)`` and ``s = 1 - xi``, each from one exponential and to full
    relative precision where it is small (``s`` next to the wall, where the wall form needs it)."""
    if t > -0.5:
        s = -math.expm1(t)
        return 1.0 - s, s
    xi = math.exp(t)
    return xi, 1.0 - xi


@njit(**_JIT_INLINE)
def _stage1_step(xi, T1, n1, work):
    """The stage-1 step that holds ``xi``; stage 2 asks for nearby, mostly decreasing xi, so the
    search starts at the step of the previous lookup (kept in ``work``)."""
    k = dense.find_step_from(T1, n1, xi, int(work[W_STEP]))
    work[W_STEP] = k
    return k


@njit(**_JIT_INLINE)
def _delta_at(xi, xi1, ax, T1, Q1, n1, buf, work):
    """Stage-1 solution anywhere in [0, 1]: the axis series below ``xi1``, the dense output above."""
    if xi <= xi1:
        return model.delta_axis_series(xi, ax)
    k = _stage1_step(xi, T1, n1, work)
    dense.dense_eval_step(T1, Q1, k, xi, buf)
    return xi * xi * buf[0]


@njit(**_JIT)
def _delta_wall(T1, Q1, n1, buf):
    """``delta(1)``: the wall ends the last stage-1 step, so no search and no axis series."""
    dense.dense_eval_step(T1, Q1, max(n1 - 1, 0), 1.0, buf)
    return buf[0]


@njit(**_JIT)
def _stage1_work(n1):
    work = np.empty(N_W)
    work[W_STEP] = n1 - 1
    return work


@njit(**_JIT)
def _wall_increments(T1, Q1, n1):
    """``C[k] = w(T1[k+1]) - w(1)`` for the stage-1 steps that reach above ``XI_WALL_FORM``.

    Summed from the wall over the steps' own increments (the second dense-output row), so that
    :func:`_wall_form` gets ``w(xi) - w(1)`` without subtracting two O(1) values. Entries below
    are not filled.
    """
    C = np.empty(max(n1, 1))
    acc = 0.0
    for k in range(n1 - 1, -1, -1):
        C[k] = acc
        if T1[k] < XI_WALL_FORM:
            break
        acc -= Q1[k, 1, 0]
    return C


@njit(**_JIT_INLINE)
def _wall_form(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1):
    """``(delta, D, noise)`` at ``xi = 1 - s`` (in stage-1 step ``k``, ``xi >= XI_WALL_FORM``), with
    ``D`` as ``D(1)`` plus an increment computed from increments, and a bound on the rounding noise
    of that increment.

    Next to the edge of solvability ``D`` is tiny at the wall (down to ~1e-14) and is the difference
    of O(1) terms: evaluated directly its rounding noise is ~1e-16, so near the wall
    ``B ~ 1/sqrt(D)`` became a noisy function of xi and stage 2 spent its whole budget (20,000 steps)
    on it. Here ``D(xi) - D(1)`` is built from ``delta(xi) - delta(1)`` and ``xi^2 - 1 = -s(2 - s)``,
    each with a relative error of a few ulps: the rounding of ``D(1)`` itself is then a constant,
    and ``D`` is smooth in xi down to the wall.
    """
    s_end = 1.0 - T1[k + 1]  # exact (Sterbenz): T1[k + 1] >= 1/2
    om = (s - s_end) / (T1[k + 1] - T1[k])  # 1 - theta in the step
    th = 1.0 - om
    # w(xi) - w(T1[k+1]) on the step's polynomial (dense.dense_eval_step's layout), as a multiple
    # of 1 - theta: no cancellation at the step's end.
    dw = C[k] - om * (Q1[k, 1, 0] - th * (Q1[k, 2, 0] + th * (Q1[k, 3, 0] + om * (
        Q1[k, 4, 0] + th * (Q1[k, 5, 0] + om * (Q1[k, 6, 0] + th * Q1[k, 7, 0]))))))
    x2m1 = -s * (2.0 - s)  # xi^2 - 1
    ddelta = x2m1 * (delta1 + dw) + dw  # xi^2 w(xi) - w(1)
    delta = delta1 + ddelta
    c0 = ax[AX_C0]
    a2 = 2.0 * (A + 1.0)
    half_yx = 0.5 * ax[model.AX_Y] * x2m1
    dD = c0 * c0 * x2m1 + a2 * (2.0 * N * (ddelta - half_yx) - ddelta * (delta + delta1))
    # Rounding of dD (the rounding of D(1) is a constant, not noise): of its terms, and of ddelta
    # carried through dD/d(delta).
    noise_ddelta = _EPS * (abs(x2m1) * (abs(delta1) + abs(dw)) + abs(C[k]) + 2.0 * abs(dw))
    noise = _EPS * (c0 * c0 * abs(x2m1) + abs(a2) * (2.0 * N * (abs(ddelta) + abs(half_yx))
                                                     + abs(ddelta * (delta + delta1)))) \
        + abs(a2) * (2.0 * N + abs(delta + delta1)) * noise_ddelta
    return delta, D1 + dD, noise



@njit(**_JIT_INLINE)
def delta_D_at(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1):
    """``(delta, D, noise)`` at ``xi = 1 - s`` in stage-1 step ``k`` (``k < 0``: below the march's
    start, on the axis series): :func:`_wall_form` above ``XI_WALL_FORM``, else the step's
    polynomial or the series, with ``D`` and its rounding bound from :mod:`model` (``C``,
    ``delta1``, ``D1`` as for :func:`_wall_form`)."""
    if k >= 0 and xi >= XI_WALL_FORM:
        return _wall_form(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1)
    if k >= 0:
        delta = xi * xi * dense.step_value(T1, Q1, k, 0, xi)
    else:
        delta = model.delta_axis_series(xi, ax)
    return delta, model.yield_D(xi, delta, A, N, ax), model.yield_D_rounding(xi, delta, A, N, ax)
