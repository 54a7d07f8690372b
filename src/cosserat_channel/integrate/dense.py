"""Dense output of the integrators, and event location on it.

The integrators store one interpolant per accepted step in Hairer's ``CONTD8`` layout
[HNW93, II.6, II.10]: step boundaries ``T[0..nsteps]`` and coefficients ``Q[k, 0..7, :]`` with::

    u(theta) = q0 + theta*(q1 + (1-theta)*(q2 + theta*(q3 + (1-theta)*(q4
                 + theta*(q5 + (1-theta)*(q6 + theta*q7))))))
    theta = (t - T[k]) / (T[k+1] - T[k])

:mod:`.dop853` fills all eight rows (its 7th-order interpolant). ``CONTD5`` is the same layout
with ``q5 = q6 = q7 = 0`` (the formula then gives the same bits as CONTD5's own):
:func:`.rk45.dense_coefficients` fills it for Dormand–Prince (Shampine's 4th-order interpolant
[Sh86]); :mod:`.rosenbrock` with RODAS's 3rd-order extension (``q4 = 0`` too). Each
integrator keeps its own coefficients; the rows 0-3 they share are :func:`hermite_rows`. Every step of a
run writes all ``N_DENSE`` rows, so one array can hold steps of different integrators. Everything
else here reads any of them: :func:`find_step`, :func:`dense_eval_step` (and :func:`step_value`, one
component as a scalar), :func:`dense_eval`, :func:`dense_eval_many`, :func:`locate_event` and
:func:`event_after_step`, and :func:`component_minus_level` (a level crossing of one component,
for :func:`.roots.find_root`).
:class:`Solution` is the Python-side view of a finished run.

Kernels that receive the event function are ``inline="always"``; see :mod:`.rk45` for why.

References
----------
.. [HNW93] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary Differential Equations I:
   Nonstiff Problems", 2nd ed., Springer (1993); Sec. II.6 (dense output, ``CONTD5``).
.. [Sh86] L. F. Shampine, "Some practical Runge-Kutta formulas", Math. Comp. 46(173), 135-150
   (1986).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE

from .roots import find_root
from .._jit import EPS
from .stepping import (STAT_ACCEPTED, STAT_FEV, STAT_REJECTED, STAT_STIFF, STAT_STIFF_STEPS,
                       message)

__all__ = [
    "N_DENSE",
    "find_step",
    "dense_eval_step",
    "step_value",
    "step_slope",
    "dense_eval",
    "dense_eval_many",
    "locate_event",
    "event_after_step",
    "component_minus_level",
    "Solution",
]

EVENT_MAX_ITER = 200

# Rows of a step's dense output (the CONTD8 layout of the module docstring).
N_DENSE = 8


@njit(**_JIT)
def hermite_rows(y, y_new, h, f0, f1, q, i):
    """Rows 0-3 of component `i` of a step's dense output (Hairer's ``rcont1..4``), which both
    CONTD5 and CONTD8 share: the values at the step's ends and, through ``f0 = f(t, y)`` and
    ``f1 = f(t + h, y_new)``, the slopes there."""
    ydiff = y_new - y
    bspl = h * f0 - ydiff
    q[0, i] = y
    q[1, i] = ydiff
    q[2, i] = bspl
    q[3, i] = ydiff - h * f1 - bspl


@njit(**_JIT)
def find_step(T, nsteps, t):
    """Index of the accepted step whose interval contains `t`.

    Parameters
    ----------
    T : ndarray of float64
        Step boundaries ``T[0..nsteps]``, strictly increasing or strictly decreasing (backward
        integration).
    nsteps : int
        Number of accepted steps.
    t : float
        Query time.

    Returns
    -------
    int
        ``k`` with `t` between ``T[k]`` and ``T[k+1]``; clamped to ``[0, nsteps-1]`` so that
        out-of-range queries extrapolate from the first or last step.
    """
    if nsteps <= 1:
        return 0
    lo = 0
    hi = nsteps - 1
    if T[nsteps] >= T[0]:
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if T[mid] <= t:
                lo = mid
            else:
                hi = mid - 1
    else:
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if T[mid] >= t:
                lo = mid
            else:
                hi = mid - 1
    return lo


@njit(**_JIT_INLINE)
def find_step_from(T, nsteps, t, k):
    """:func:`find_step` for a caller whose queries move slowly: walk from step `k` (the answer of
    its previous query) instead of bisecting; the same index, in O(1) for a nearby `t`.

    Only for increasing `T` (a forward run).
    """
    if nsteps <= 1:
        return 0
    k = min(max(k, 0), nsteps - 1)
    while k > 0 and T[k] > t:
        k -= 1
    while k < nsteps - 1 and T[k + 1] <= t:
        k += 1
    return k


@njit(**_JIT)
def dense_eval_step(T, Q, k, t, out):
    """Evaluate the interpolant of accepted step `k` at time `t`.

    Parameters
    ----------
    T : ndarray of float64
        Step boundaries.
    Q : ndarray of float64, shape (M, N_DENSE, n)
        Dense-output coefficients.
    k : int
        Step index.
    t : float
        Time; ``theta = (t - T[k]) / (T[k+1] - T[k])``.
    out : ndarray of float64, shape (n,)
        Output.
    """
    theta = (t - T[k]) / (T[k + 1] - T[k])
    for i in range(out.shape[0]):
        out[i] = _step_polynomial(Q, k, i, theta)


@njit(**_JIT)
def _step_polynomial(Q, k, i, theta):
    # The layout of the module docstring, at theta in step k, component i.
    theta1 = 1.0 - theta
    return Q[k, 0, i] + theta * (
        Q[k, 1, i] + theta1 * (
            Q[k, 2, i] + theta * (
                Q[k, 3, i] + theta1 * (
                    Q[k, 4, i] + theta * (
                        Q[k, 5, i] + theta1 * (Q[k, 6, i] + theta * Q[k, 7, i]))))))


@njit(**_JIT_INLINE)
def step_slope(T, Q, k, i, t):
    """The derivative by `t` of component `i` of step `k`'s interpolant at `t` (the nested form
    of :func:`_step_polynomial` differentiated from the inside out): with :func:`step_value`,
    what a defect ``u' - f(t, u)`` of the dense output is made of."""
    h = T[k + 1] - T[k]
    theta = (t - T[k]) / h
    theta1 = 1.0 - theta
    g6 = Q[k, 6, i] + theta * Q[k, 7, i]
    d6 = Q[k, 7, i]
    g5 = Q[k, 5, i] + theta1 * g6
    d5 = -g6 + theta1 * d6
    g4 = Q[k, 4, i] + theta * g5
    d4 = g5 + theta * d5
    g3 = Q[k, 3, i] + theta1 * g4
    d3 = -g4 + theta1 * d4
    g2 = Q[k, 2, i] + theta * g3
    d2 = g3 + theta * d3
    g1 = Q[k, 1, i] + theta1 * g2
    d1 = -g2 + theta1 * d2
    return (g1 + theta * d1) / h


@njit(**_JIT_INLINE)
def step_value(T, Q, k, i, t):
    """Component `i` of :func:`dense_eval_step` at `t`, as a scalar (no output array)."""
    return _step_polynomial(Q, k, i, (t - T[k]) / (T[k + 1] - T[k]))


@njit(**_JIT)
def dense_eval(T, Q, nsteps, t, out):
    """Evaluate the dense output of a whole run at time `t`.

    Parameters
    ----------
    T, Q, nsteps
        As filled by :func:`.rk45.dopri5` or :func:`.rosenbrock.rodas4`; `nsteps` must be at
        least 1.
    t : float
        Time.
    out : ndarray of float64, shape (n,)
        Output.
    """
    k = find_step(T, nsteps, t)
    dense_eval_step(T, Q, k, t, out)


@njit(**_JIT)
def dense_eval_many(T, Q, nsteps, ts, out):
    """Evaluate the dense output at many times in one call.

    Parameters
    ----------
    T, Q, nsteps
        As for :func:`dense_eval`.
    ts : ndarray of float64, shape (m,)
        Times, in any order.
    out : ndarray of float64, shape (m, n)
        Output; row ``j`` is the solution at ``ts[j]``.
    """
    for j in range(ts.shape[0]):
        dense_eval(T, Q, nsteps, ts[j], out[j])


@njit(**_JIT_INLINE)
def _event_on_step(t, packed):
    # The event function composed with one step's interpolant, in find_root's f(x, args) form.
    # `event` is not the tuple's first item: Numba would then try (and fail) to type the tuple
    # as a tuple of first-class functions, with an "experimental feature" warning.
    T, Q, k, ytmp, event, args = packed
    dense_eval_step(T, Q, k, t, ytmp)
    return event(t, ytmp, args)


@njit(**_JIT_INLINE)
def locate_event(event, args, T, Q, k, ga, gb, ytmp):
    """Zero of `event` along the dense output of accepted step `k`.

    Parameters
    ----------
    event : numba-compiled callable
        ``event(t, y, args) -> float``.
    args : any numba-typed object
        Passed through to `event`.
    T, Q : ndarray of float64
        Dense output (module docstring).
    k : int
        Step index; the zero is sought between ``T[k]`` and ``T[k+1]``.
    ga, gb : float
        Event values at ``T[k]`` and ``T[k+1]``, of opposite signs.
    ytmp : ndarray of float64, shape (n,)
        Scratch for the interpolated state.

    Returns
    -------
    float
        The event time, to a few ulps of the step's end points (:func:`.roots.find_root`).
    """
    a = T[k]
    b = T[k + 1]
    h = b - a
    tol = 4.0 * EPS * max(abs(a), abs(b), abs(h)) + 1e-14 * abs(h)
    t_event, _ = find_root(_event_on_step, (T, Q, k, ytmp, event, args), a, b, ga, gb, tol,
                           EVENT_MAX_ITER)
    return t_event


@njit(**_JIT_INLINE)
def event_after_step(event, args, T, Q, nsteps, g_old, y_new, ytmp):
    """Test the terminal event at the end of the last accepted step and locate it if it fired.

    The event fires at an exact zero at the step end, or at a sign change across the step
    (an exact zero at the start of the step was seen, and ignored, before).

    Parameters
    ----------
    event, args
        As for :func:`locate_event`.
    T, Q : ndarray of float64
        Dense output with `nsteps` accepted steps.
    nsteps : int
        Number of accepted steps, at least 1.
    g_old : float
        Event value at ``T[nsteps - 1]``.
    y_new : ndarray of float64, shape (n,)
        State at ``T[nsteps]``.
    ytmp : ndarray of float64, shape (n,)
        Scratch.

    Returns
    -------
    fired : bool
        Whether the event fired in the step.
    t_event : float
        Where it fired (``T[nsteps]`` if it did not).
    g_new : float
        Event value at ``T[nsteps]``: the next step's `g_old`.
    """
    t_new = T[nsteps]
    g_new = event(t_new, y_new, args)
    if g_new == 0.0:
        return True, t_new, g_new
    if (g_old < 0.0 and g_new > 0.0) or (g_old > 0.0 and g_new < 0.0):
        return True, locate_event(event, args, T, Q, nsteps - 1, g_old, g_new, ytmp), g_new
    return False, t_new, g_new


@njit(**_JIT)
def component_minus_level(t, packed):
    """Component ``i`` of a dense output at `t`, minus `level`: ``f(x, args)`` for find_root.

    Parameters
    ----------
    t : float
        Time.
    packed : tuple
        ``(T, Q, nsteps, i, level, out)``: a run's dense output, the component, the level, and
        scratch `out` of shape (n,) that receives the whole interpolated state.

    Returns
    -------
    float
        ``u_i(t) - level``.
    """
    T, Q, nsteps, i, level, out = packed
    dense_eval(T, Q, nsteps, t, out)
    return out[i] - level


class Solution(NamedTuple):
    """A finished run of an integrator: status, counters and dense output.

    Attributes
    ----------
    status : int
        Outcome code (:mod:`.stepping`'s ``SUCCESS``, ``EVENT``, ...); :attr:`message` says it in
        words.
    t_stop : float
        Where the integration stopped.
    y_stop : ndarray, shape (n,)
        Dense-output value at `t_stop`.
    nsteps : int
        Number of accepted steps.
    T : ndarray, shape (nsteps + 1,)
        Step boundaries.
    Q : ndarray, shape (nsteps, N_DENSE, n)
        Dense-output coefficients.
    n_accepted, n_rejected, n_fev, n_stiff_steps : int
        Counters from ``stats``.
    stiff : bool
        Whether stiffness was declared.
    """

    status: int
    t_stop: float
    y_stop: np.ndarray
    nsteps: int
    T: np.ndarray
    Q: np.ndarray
    n_accepted: int
    n_rejected: int
    n_fev: int
    n_stiff_steps: int
    stiff: bool

    @classmethod
    def from_run(cls, status, nsteps, t_stop, y0, T, Q, stats):
        """Collect what an integrator left in its output arrays (copies, trimmed to `nsteps`).

        Parameters
        ----------
        status, nsteps, t_stop
            The integrator's return values.
        y0 : ndarray of float64, shape (n,)
            Initial state, the value at `t_stop` when no step was taken.
        T, Q, stats : ndarray
            The integrator's output arrays.

        Returns
        -------
        Solution
        """
        T = T[:nsteps + 1].copy()
        Q = Q[:nsteps].copy()
        if nsteps == 0:
            y_stop = np.array(y0, dtype=np.float64)
        else:
            y_stop = np.empty(Q.shape[2])
            dense_eval(T, Q, nsteps, t_stop, y_stop)
        return cls(
            status=int(status), t_stop=float(t_stop), y_stop=y_stop, nsteps=int(nsteps),
            T=T, Q=Q,
            n_accepted=int(stats[STAT_ACCEPTED]),
            n_rejected=int(stats[STAT_REJECTED]),
            n_fev=int(stats[STAT_FEV]),
            n_stiff_steps=int(stats[STAT_STIFF_STEPS]),
            stiff=bool(stats[STAT_STIFF]),
        )

    @property
    def message(self):
        """What :attr:`status` means (:func:`.stepping.message`)."""
        return message(self.status)

    def sol(self, t):
        """Evaluate the dense output.

        Parameters
        ----------
        t : float or array_like
            Time(s).

        Returns
        -------
        ndarray
            Shape ``(n,)`` for scalar `t`, ``(len(t), n)`` otherwise.
        """
        n = self.y_stop.shape[0]
        ts = np.asarray(t, dtype=np.float64)
        scalar = ts.ndim == 0
        ts = np.atleast_1d(ts).ravel()
        if self.nsteps == 0:
            out = np.tile(self.y_stop, (ts.shape[0], 1))
        else:
            out = np.empty((ts.shape[0], n))
            dense_eval_many(self.T, self.Q, self.nsteps, ts, out)
        return out[0] if scalar else out
