"""The one driver loop of the explicit Runge-Kutta pairs: Dormand-Prince 5(4) and DOP853.

:func:`explicit_rk` is Hairer's driver [HNW93, II.4-II.6, IV.2]: ``HINIT`` for the first step,
trial steps clipped onto the end, acceptance by the pair's controller and a stability check
(:func:`.stepping.beyond_stability`), the stiffness test, one dense-output record per accepted
step, terminal events, and the outcome codes and counters of :mod:`.stepping`. The pairs differ
in their step, error norm, controller and dense rows, so a method is passed in as those pieces
(:func:`.rk45.dopri5`, :func:`.dop853.dop853`):

``trial(fun, t, y, h, args, K, y_new, w, atol, rtol) -> err``
    One trial step of signed size ``h`` from ``(t, y)``: with ``K[0] = f(t, y)`` on entry, the
    stages into ``K[1..k_new]`` (``K[k_new] = f(t + h, y_new)``, first-same-as-last), the
    solution into ``y_new``, and the error norm returned (at most 1 accepts). ``w`` is the
    method's own work vector.
``control(err, h_abs, h_max, memory, reject) -> (accept, h_next, memory)``
    The step-size controller; ``memory`` is what it keeps between steps.
``dense(fun, t, y, y_new, h, args, K, w, q)``
    The accepted step's rows of :mod:`.dense`'s layout into ``q``, with the further stages
    ``K[k_new + 1..]`` where the method's interpolant needs them.

The driver and the pieces that receive ``fun`` are ``inline="always"``: a jitted caller then
compiles each method's loop with direct calls and stays cacheable (see :mod:`.rk45`).

References
----------
.. [HNW93] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary Differential Equations I:
   Nonstiff Problems", 2nd ed., Springer (1993).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE
from .dense import event_after_step
from .stepping import (EVENT, MAX_STEPS, NONFINITE, STAT_FEV, STEP_TOO_SMALL, SUCCESS, all_finite,
                       begin_run, beyond_stability, clip_to_end, count_stiffness, count_trial,
                       first_step, step_too_small, stiffness_ratio)

__all__ = ["explicit_rk"]


@njit(**_JIT)
def _work_arrays(y0, n_rows):
    # The run's state and scratch, allocated once: y (a copy of y0), y_new, the method's work
    # vector w, ytmp, and the stages K.
    n = y0.shape[0]
    return y0.copy(), np.empty(n), np.empty(n), np.empty(n), np.empty((n_rows, n))


@njit(**_JIT_INLINE)
def explicit_rk(trial, control, dense, n_rows, k_new, order, memory0, stiff_dy, stiff_threshold,
                fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats, rho0):
    """Integrate ``y' = fun(t, y)`` from `t0` to `t_end` with the explicit pair given by its pieces.

    Parameters
    ----------
    trial, control, dense : numba-compiled callables
        The method's step with its error norm, its controller and its dense output (module
        docstring).
    n_rows : int
        Rows of the stage array ``K``; ``n_rows - k_new - 1`` of them are evaluated by `dense`.
    k_new : int
        Row of ``f(t + h, y_new)`` in ``K``: also the evaluations of a trial step.
    order : int
        Order of the error estimate, for ``HINIT``.
    memory0 : float
        The controller's memory before the first step.
    stiff_dy, stiff_threshold
        The pair's weights and stability boundary for :func:`.stepping.stiffness_ratio`,
        :func:`.stepping.count_stiffness` and :func:`.stepping.beyond_stability`.
    fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats, rho0
        As for :func:`.rk45.dopri5`.

    Returns
    -------
    status, nsteps, t_stop
        As for :func:`.rk45.dopri5`. Evaluations: ``1 + [h0 <= 0] + (n_rows - 1) * accepted
        + k_new * rejected``.
    """
    direction, span, hmax = begin_run(t0, t_end, h_max, T, stats)
    if span == 0.0:
        return SUCCESS, 0, t0
    y, y_new, w, ytmp, K = _work_arrays(y0, n_rows)
    fun(t0, y, args, K[0])
    stats[STAT_FEV] = 1
    if not (all_finite(K[0]) and all_finite(y)):
        return NONFINITE, 0, t0
    # ytmp and w are free here and serve as HINIT's scratch.
    habs = first_step(fun, t0, y, K[0], args, direction, rtol, atol, h0, hmax, span, order, ytmp,
                      w, stats)
    g_old = event(t0, y, args)
    # `accept` holds the last trial's verdict: the controller must not grow a step after a
    # rejection.
    t, memory, accept = t0, memory0, True
    # Counters start as int64, not the literal 0: Numba would compile the counter helpers once
    # for the literal and once for int64.
    nsteps = n_nonfinite = iasti = nonsti = np.int64(0)
    rho = rho0  # |lambda| at the start of the next step (0: unknown)
    while True:
        if nsteps >= Q.shape[0]:
            return MAX_STEPS, nsteps, t
        if step_too_small(habs, t):
            return STEP_TOO_SMALL, nsteps, t
        h, last = clip_to_end(t, habs, t_end, direction)
        err = trial(fun, t, y, h, args, K, y_new, w, atol, rtol)
        stats[STAT_FEV] += k_new
        if not (all_finite(y_new) and all_finite(K[k_new])):
            err = math.nan
        accept, habs_next, memory_next = control(err, abs(h), hmax, memory, not accept)
        if accept and beyond_stability(h, rho, stiff_threshold):
            # Passed the error test far outside the stability region: see beyond_stability.
            accept = False
            habs_next = stiff_threshold / rho
        else:
            memory = memory_next
        habs = habs_next
        n_nonfinite, give_up = count_trial(accept, err, n_nonfinite, stats)
        if give_up:
            return NONFINITE, nsteps, t
        if not accept:
            continue
        h_rho = stiffness_ratio(h, K, k_new, stiff_dy)
        iasti, nonsti = count_stiffness(h_rho, stiff_threshold, iasti, nonsti, stats)
        # An estimate of 0 (f unchanged across the last stage) replaces the last one too: kept,
        # a stiff stretch's |lambda| pins every later step at that stretch's boundary.
        if h_rho >= 0.0:
            rho = h_rho / abs(h)
        dense(fun, t, y, y_new, h, args, K, w, Q[nsteps])
        stats[STAT_FEV] += n_rows - k_new - 1
        T[nsteps + 1] = t_end if last else t + h
        nsteps += 1
        fired, t_event, g_old = event_after_step(event, args, T, Q, nsteps, g_old, y_new, ytmp)
        if fired:
            return EVENT, nsteps, t_event
        if last:
            return SUCCESS, nsteps, t_end
        # Element loops, not slice assignments: those compile Numba's shape-mismatch error
        # message (string formatting), seconds of the first run's compilation.
        for i in range(y.size):
            y[i] = y_new[i]
            K[0, i] = K[k_new, i]
        t = T[nsteps]
