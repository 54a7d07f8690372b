"""The regimes of Appendix A that are decided without integrating: plain Python, no numba.

:mod:`cosserat_channel.physics.model` compiles these two functions with numba for the kernels; the
solvability atlas (:mod:`cosserat_channel.atlas`) calls them as they are, so that reading an atlas
and classifying points never imports numba. They are the one home of the analytic regime logic.
Both take scalars; :func:`axis_margin` also takes arrays, :func:`classify_margins` is
:func:`classify_margin` on arrays, :func:`classify_points` classifies arrays of points (the
atlas, the regime maps and a sweep's cost model call it), and :func:`axis_edge_eta` and :func:`node_focus_switch_N`
(the atlas and the figures need them without the solver) and :func:`wall_bound_eta` take
arrays.
"""

from __future__ import annotations

import numpy as np

from .. import status as st


def axis_margin(eta, A, N):
    """Axis existence condition of eq:20, ``(A-1) eta + 2(A+1) N``.

    The smaller root ``x`` of ``eps^2 x^2 - 2(A+1)(eps + N/L) x + 2(A+1) = 0`` exists and satisfies
    ``eps x <= A + 1`` (the root choice the paper prescribes) exactly when this is ``>= 0`` (derived
    in model.md; checked in the tests).
    """
    return (A - 1.0) * eta + 2.0 * (A + 1.0) * N


def classify_margin(margin, A, N):
    """Status decided before any integration from ``A``, ``N`` and the :func:`axis_margin`.

    Returns ``OK`` when stage 1 must be integrated (A > -1, axis series admissible) or when the
    A = -1 closed form applies. It takes the margin, not ``eta``, because numba cannot call a
    plain Python function from compiled code: ``model.classify`` composes the two compiled copies.
    """
    if A < 1.0 - 2.0 * N * N:
        return st.WALL_INADMISSIBLE
    if A < -1.0:
        return st.AXIS_SPIN_UNBOUNDED
    if A == -1.0:
        return st.OK
    # On the edge itself (margin exactly 0) the root of eq:20 is admissible but c0 = 0: sqrt(D)
    # vanishes to first order at the axis and the spin exponent beta is infinite, so no regular
    # solution leaves the axis; the edge belongs to the infeasible side.
    if margin <= 0.0:
        return st.EPS_TOO_LARGE_AXIS
    return st.OK


def classify_margins(margin, A, N):
    """:func:`classify_margin` on arrays (broadcast): the same tests in the same order, int8 codes.

    The atlas and the regime maps classify up to ~10^5 points at once, where calling the scalar
    function per point costs a large part of a figure's time.
    """
    margin, A, N = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (margin, A, N)))
    return np.select(
        [A < 1.0 - 2.0 * N * N, A < -1.0, A == -1.0, margin <= 0.0],
        [st.WALL_INADMISSIBLE, st.AXIS_SPIN_UNBOUNDED, st.OK, st.EPS_TOO_LARGE_AXIS],
        st.OK).astype(np.int8)


def classify_points(eta, A, N):
    """The status Appendix A decides at each ``(eta, A, N)``, else ``OK``: :func:`classify_margin`
    of :func:`axis_margin` on arrays (broadcast), int8 codes. ``model.classify`` is the same for
    one point, compiled for the kernels."""
    eta, A, N = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (eta, A, N)))
    if eta.size == 0:
        return np.zeros(eta.shape, dtype=np.int8)
    return classify_margins(axis_margin(eta, A, N), A, N)


def axis_edge_eta(A, N):
    """``eta`` of the axis condition, ``2(A+1) N / (1 - A)``, for ``-1 < A < 1``; ``inf`` for ``A >= 1``."""
    A = np.asarray(A, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = 2.0 * (A + 1.0) * np.asarray(N, dtype=float) / (1.0 - A)
    return np.where(A >= 1.0, np.inf, np.where(A > -1.0, e, np.nan))


def node_focus_switch_N(A):
    """The ``N`` above which the singular point at the wall is a node: ``sqrt((5 + 3A)/2)``.

    :func:`cosserat_channel.regimes.node_edge_eta`'s condition ``gamma^2 > 8 Phi`` at
    ``eta = eta_node``, solved for ``N``. ``eta_max(A, N)`` is not analytic across this curve:
    above it the edge is the node's closed form, below it a transversal zero of ``D(1)`` that
    becomes double on the curve. It rises with ``A``, from 1 at ``A = -1`` to 2 at ``A = 1``; NaN
    outside ``-1 <= A <= 1``, where there is no such singular point.
    """
    A = np.asarray(A, dtype=float)
    inside = (A >= -1.0) & (A <= 1.0)
    return np.sqrt(np.where(inside, 0.5 * (5.0 + 3.0 * A), np.nan))


def wall_bound_eta(A, N):
    """An ``eta`` above which no stress path reaches the wall, for ``-1 < A < 1`` outside the
    wall-inadmissible region: ``(A+1) / (2 q)`` with ``q = N - sqrt(N^2 - (1-A)/2)``.

    Why: ``D = (A+1) [(A-1) xi^2 + 2 delta (2N - delta)]`` (eq:a3 with eq:20 at the axis), and
    ``eta delta' = (A+1) xi - sqrt(D) <= (A+1) xi`` gives ``delta <= p xi^2``, ``p = (A+1)/(2 eta)``.
    ``delta (2N - delta)`` increases up to ``delta = N``, so where ``p <= N``, ``D(1) <= (A+1)
    [(A-1) + 2p (2N - p)]``, negative once ``p < q`` (the smaller root of ``2p(2N-p) = 1-A``).
    At the axis edge :func:`axis_edge_eta`, ``p = (1-A)/(4N) < q``: this bound lies strictly
    below it, so the axis edge has no point with a solution next to it. NaN outside the range.
    """
    A = np.asarray(A, dtype=float)
    N = np.asarray(N, dtype=float)
    inside = (A > -1.0) & (A < 1.0) & (A >= 1.0 - 2.0 * N * N)
    with np.errstate(invalid="ignore", divide="ignore"):
        h = 0.5 * (1.0 - A)
        q = h / (N + np.sqrt(N * N - h))  # N - sqrt(N^2 - h) without the cancellation
        return np.where(inside, (A + 1.0) / (2.0 * q), np.nan)
