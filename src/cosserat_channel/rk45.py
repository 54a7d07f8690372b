"""Adaptive Dormand–Prince 5(4) integrator written for Numba.

The integrator is generic over the right-hand side: it knows nothing about the
physics of the channel problem.  It is a transcription of the ideas of Hairer's
``DOPRI5`` code (step-size control, dense output ``CONTD5``, initial step
``HINIT``, stiffness detection) into ``@njit`` kernels that allocate their work
arrays once per call, so that the integrator can be called millions of times in
parameter sweeps on small (n = 1 or 2) systems.

All kernels are compiled with ``error_model="numpy"`` so that a division by zero
yields inf/NaN (which the integrator then handles as a non-finite trial step)
instead of raising a Python exception from inside a kernel.

The kernels that receive the right-hand side (``dopri5``, ``dopri5_step`` and
the private helpers) are additionally ``inline="always"`` (Numba-IR inlining
into jitted callers).  A jitted caller that passes a global ``@njit`` function
into a non-inlined kernel has to materialise the dispatcher object's address
in its machine code, which Numba refuses to cache ("uses dynamic globals").
With inlining the call to ``fun`` becomes a direct call, so a driver such as::

    @njit(cache=True)
    def run(y0, T, Q, stats):
        return dopri5(my_rhs, no_event, 0.0, y0, 1.0, (), 1e-8, atol, 0.0, 0.0,
                      T, Q, stats)

is cached across processes (and the step is about 30 % faster).  Calling
``dopri5`` directly from Python with a dispatcher argument still works, but
Numba keys that specialisation on the dispatcher's address, so it is
recompiled in every new process.

References
----------
.. [DP80] J. R. Dormand and P. J. Prince, "A family of embedded Runge-Kutta
   formulae", J. Comput. Appl. Math. 6(1), 19-26 (1980).
.. [HNW93] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary
   Differential Equations I: Nonstiff Problems", 2nd ed., Springer (1993);
   Sec. II.4 (automatic step size control, ``HINIT``), II.5 (``DOPRI5``),
   II.6 (dense output, ``CONTD5``), IV.2 (stiffness detection).
.. [Sh86] L. F. Shampine, "Some practical Runge-Kutta formulas",
   Math. Comp. 46(173), 135-150 (1986).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "SUCCESS",
    "EVENT",
    "MAX_STEPS",
    "STEP_TOO_SMALL",
    "NONFINITE",
    "STAT_ACCEPTED",
    "STAT_REJECTED",
    "STAT_FEV",
    "STAT_STIFF_STEPS",
    "STAT_STIFF",
    "N_STATS",
    "no_event",
    "dopri5",
    "dopri5_step",
    "dense_coefficients",
    "find_step",
    "dense_eval_step",
    "dense_eval",
    "Solution",
    "integrate",
]

# ---------------------------------------------------------------------------
# Status codes and statistics slots
# ---------------------------------------------------------------------------
SUCCESS = 0
EVENT = 1
MAX_STEPS = -1
STEP_TOO_SMALL = -2
NONFINITE = -3

STAT_ACCEPTED = 0
STAT_REJECTED = 1
STAT_FEV = 2
STAT_STIFF_STEPS = 3
STAT_STIFF = 4
N_STATS = 5

# ---------------------------------------------------------------------------
# Dormand–Prince 5(4) tableau [DP80], as printed in [HNW93, Table II.5.2].
# ---------------------------------------------------------------------------
C2 = 1 / 5
C3 = 3 / 10
C4 = 4 / 5
C5 = 8 / 9
C6 = 1.0
C7 = 1.0

A21 = 1 / 5
A31 = 3 / 40
A32 = 9 / 40
A41 = 44 / 45
A42 = -56 / 15
A43 = 32 / 9
A51 = 19372 / 6561
A52 = -25360 / 2187
A53 = 64448 / 6561
A54 = -212 / 729
A61 = 9017 / 3168
A62 = -355 / 33
A63 = 46732 / 5247
A64 = 49 / 176
A65 = -5103 / 18656
# The seventh row equals the weights B (first-same-as-last), so k7 = f(t+h, y_new).

B1 = 35 / 384
B2 = 0.0
B3 = 500 / 1113
B4 = 125 / 192
B5 = -2187 / 6784
B6 = 11 / 84
B7 = 0.0

# E = B - Bhat: the 5th-order minus the embedded 4th-order weights (Hairer's sign).
E1 = 71 / 57600
E2 = 0.0
E3 = -71 / 16695
E4 = 71 / 1920
E5 = -17253 / 339200
E6 = 22 / 525
E7 = -1 / 40

# Coefficients of the 4th-order continuous extension of Shampine [Sh86] in the
# form used by Hairer's CONTD5 [HNW93, II.6]; these are the optimal-c6 choice.
D1 = -12715105075 / 11282082432
D3 = 87487479700 / 32700410799
D4 = -10690763975 / 1880347072
D5 = 701980252875 / 199316789632
D6 = -1453857185 / 822651844
D7 = 69997945 / 29380423

# ---------------------------------------------------------------------------
# Step-size controller (Hairer's DOPRI5 defaults)
# ---------------------------------------------------------------------------
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
BETA = 0.04
ALPHA = 0.2 - 0.75 * BETA
FACOLD_MIN = 1e-4

# Shrink factor after a trial step produced NaN/inf, and how many such trials
# in a row we tolerate before giving up.
NONFINITE_SHRINK = 0.25
NONFINITE_MAX_TRIES = 20

# Stiffness detection [HNW93, IV.2]: h*rho beyond the real stability boundary
# of DOPRI5 (about 3.3) means the step size is limited by stability.
STIFF_THRESHOLD = 3.25
STIFF_DECLARE = 15
NONSTIFF_RESET = 6

EPS = 2.220446049250313e-16
EVENT_MAX_ITER = 200

_JIT = dict(nogil=True, cache=True, error_model="numpy")
# See the module docstring: inlining keeps jitted callers cacheable.
_JIT_INLINE = dict(_JIT, inline="always")


@njit(**_JIT)
def no_event(t, y, args):
    """Event function that never fires.

    Parameters
    ----------
    t : float
        Time.
    y : ndarray of float64, shape (n,)
        State.
    args : any
        Passed through, unused.

    Returns
    -------
    float
        Always 1.0, so no sign change can ever be observed.
    """
    return 1.0


@njit(**_JIT_INLINE)
def dopri5_step(fun, t, y, h, args, k1, y_new, y_err, K):
    """Take one Dormand–Prince 5(4) step of size `h` from ``(t, y)``.

    The controller (accept/reject, next step size) is the caller's business;
    this kernel only evaluates the stages [DP80], [HNW93, II.5].

    Parameters
    ----------
    fun : numba-compiled callable
        ``fun(t, y, args, out)`` writes dy/dt into `out`.
    t, h : float
        Start time and (signed) step size.
    y : ndarray of float64, shape (n,)
        State at `t`.
    args : any numba-typed object
        Passed through to `fun`.
    k1 : ndarray of float64, shape (n,)
        ``f(t, y)``; may alias ``K[0]``.
    y_new : ndarray of float64, shape (n,)
        Output: the 5th-order solution at ``t + h``.
    y_err : ndarray of float64, shape (n,)
        Output: embedded error estimate, 5th-order minus 4th-order solution.
    K : ndarray of float64, shape (7, n)
        Output: the stage derivatives; ``K[6] = f(t + h, y_new)`` (FSAL).
    """
    n = y.shape[0]
    # y_new doubles as the stage-argument scratch so that no allocation happens
    # per step; it is overwritten with the solution before stage 7.
    ys = y_new
    for i in range(n):
        K[0, i] = k1[i]
    for i in range(n):
        ys[i] = y[i] + h * (A21 * K[0, i])
    fun(t + C2 * h, ys, args, K[1])
    for i in range(n):
        ys[i] = y[i] + h * (A31 * K[0, i] + A32 * K[1, i])
    fun(t + C3 * h, ys, args, K[2])
    for i in range(n):
        ys[i] = y[i] + h * (A41 * K[0, i] + A42 * K[1, i] + A43 * K[2, i])
    fun(t + C4 * h, ys, args, K[3])
    for i in range(n):
        ys[i] = y[i] + h * (A51 * K[0, i] + A52 * K[1, i] + A53 * K[2, i]
                            + A54 * K[3, i])
    fun(t + C5 * h, ys, args, K[4])
    for i in range(n):
        ys[i] = y[i] + h * (A61 * K[0, i] + A62 * K[1, i] + A63 * K[2, i]
                            + A64 * K[3, i] + A65 * K[4, i])
    # Using t + h (not t + C6*h) keeps stages 6 and 7 at the same time value.
    fun(t + h, ys, args, K[5])
    for i in range(n):
        y_new[i] = y[i] + h * (B1 * K[0, i] + B3 * K[2, i] + B4 * K[3, i]
                               + B5 * K[4, i] + B6 * K[5, i])
    fun(t + h, y_new, args, K[6])
    for i in range(n):
        y_err[i] = h * (E1 * K[0, i] + E3 * K[2, i] + E4 * K[3, i]
                        + E5 * K[4, i] + E6 * K[5, i] + E7 * K[6, i])


@njit(**_JIT)
def dense_coefficients(y, y_new, h, K, q):
    """Fill the continuous-extension coefficients of one accepted step.

    The layout is Hairer's ``CONTD5`` [HNW93, II.6] (``rcont1..rcont5``), the
    4th-order interpolant of Shampine [Sh86]::

        u(theta) = q0 + theta*(q1 + (1-theta)*(q2 + theta*(q3 + (1-theta)*q4)))

    Parameters
    ----------
    y, y_new : ndarray of float64, shape (n,)
        Solution at the start and end of the step.
    h : float
        Signed step size.
    K : ndarray of float64, shape (7, n)
        Stage derivatives from :func:`dopri5_step` (``K[6]`` is f at `y_new`).
    q : ndarray of float64, shape (5, n)
        Output.
    """
    n = y.shape[0]
    for i in range(n):
        ydiff = y_new[i] - y[i]
        bspl = h * K[0, i] - ydiff
        q[0, i] = y[i]
        q[1, i] = ydiff
        q[2, i] = bspl
        q[3, i] = ydiff - h * K[6, i] - bspl
        q[4, i] = h * (D1 * K[0, i] + D3 * K[2, i] + D4 * K[3, i]
                       + D5 * K[4, i] + D6 * K[5, i] + D7 * K[6, i])


@njit(**_JIT)
def find_step(T, nsteps, t):
    """Index of the accepted step whose interval contains `t`.

    Parameters
    ----------
    T : ndarray of float64
        Step boundaries ``T[0..nsteps]``, strictly increasing or strictly
        decreasing (backward integration).
    nsteps : int
        Number of accepted steps.
    t : float
        Query time.

    Returns
    -------
    int
        ``k`` with `t` between ``T[k]`` and ``T[k+1]``; clamped to
        ``[0, nsteps-1]`` so that out-of-range queries extrapolate from the
        first or last step.
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


@njit(**_JIT)
def dense_eval_step(T, Q, k, t, out):
    """Evaluate the interpolant of accepted step `k` at time `t`.

    Parameters
    ----------
    T : ndarray of float64
        Step boundaries.
    Q : ndarray of float64, shape (M, 5, n)
        Dense-output coefficients, see :func:`dense_coefficients`.
    k : int
        Step index.
    t : float
        Time; ``theta = (t - T[k]) / (T[k+1] - T[k])``.
    out : ndarray of float64, shape (n,)
        Output.
    """
    theta = (t - T[k]) / (T[k + 1] - T[k])
    theta1 = 1.0 - theta
    n = out.shape[0]
    for i in range(n):
        out[i] = Q[k, 0, i] + theta * (
            Q[k, 1, i] + theta1 * (
                Q[k, 2, i] + theta * (Q[k, 3, i] + theta1 * Q[k, 4, i])))


@njit(**_JIT)
def dense_eval(T, Q, nsteps, t, out):
    """Evaluate the dense output of a whole run at time `t`.

    Parameters
    ----------
    T, Q, nsteps
        As filled by :func:`dopri5`; `nsteps` must be at least 1.
    t : float
        Time.
    out : ndarray of float64, shape (n,)
        Output.
    """
    k = find_step(T, nsteps, t)
    dense_eval_step(T, Q, k, t, out)


@njit(**_JIT)
def _dense_eval_many(T, Q, nsteps, ts, out):
    # Vectorised helper for `Solution.sol`, so that Python pays one call only.
    for j in range(ts.shape[0]):
        dense_eval(T, Q, nsteps, ts[j], out[j])


@njit(**_JIT)
def _rms_norm(v, y, atol, rtol):
    # Scale with |y| only: used by the initial-step heuristic, where no y_new exists.
    n = v.shape[0]
    s = 0.0
    for i in range(n):
        r = v[i] / (atol[i] + rtol * abs(y[i]))
        s += r * r
    return math.sqrt(s / n)


@njit(**_JIT_INLINE)
def _initial_step(fun, t0, y0, f0, args, direction, rtol, atol, h_max,
                  span, y1, f1):
    """Hairer's ``HINIT`` [HNW93, II.4], in the form of scipy's
    ``select_initial_step``; costs one RHS evaluation.

    Returns the (positive) initial step size.
    """
    n = y0.shape[0]
    d0 = _rms_norm(y0, y0, atol, rtol)
    d1 = _rms_norm(f0, y0, atol, rtol)
    # Written as `not (...)` so that NaN norms fall into the cautious branch.
    if not (d0 >= 1e-5 and d1 >= 1e-5):
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, span)
    for i in range(n):
        y1[i] = y0[i] + direction * h0 * f0[i]
    fun(t0 + direction * h0, y1, args, f1)
    s = 0.0
    for i in range(n):
        r = (f1[i] - f0[i]) / (atol[i] + rtol * abs(y0[i]))
        s += r * r
    d2 = math.sqrt(s / n) / h0
    if not math.isfinite(d2):
        # The Euler probe already left the domain of f; let the main loop's
        # non-finite handling shrink from a cautious start.
        h1 = h0
    else:
        dmax = d1 if d1 > d2 else d2
        if dmax <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / dmax) ** (1.0 / 5.0)
    return min(100.0 * h0, h1, span, h_max)


@njit(**_JIT_INLINE)
def _locate_event(event, args, T, Q, k, ga, gb, ytmp):
    """Zero of ``event`` on the dense output of step `k`.

    Illinois-modified regula falsi, safeguarded by bisection whenever two
    consecutive iterations fail to halve the bracket.  ``ga`` and ``gb`` are
    the event values at ``T[k]`` and ``T[k+1]`` and must have opposite signs.
    """
    a = T[k]
    b = T[k + 1]
    h = b - a
    s = 1.0 if h > 0.0 else -1.0
    tol = 4.0 * EPS * max(abs(a), abs(b), abs(h)) + 1e-14 * abs(h)
    fa = ga
    fb = gb
    # Illinois weights act on copies so that the true values stay available
    # for choosing the returned end point.
    wa = ga
    wb = gb
    side = 0
    w1 = abs(h)
    w2 = abs(h)
    for it in range(EVENT_MAX_ITER):
        width = abs(b - a)
        if width <= tol:
            break
        if it >= 2 and width > 0.5 * w2:
            c = 0.5 * (a + b)
        else:
            c = b - wb * (b - a) / (wb - wa)
            if not ((c - a) * s > 0.0 and (b - c) * s > 0.0):
                c = 0.5 * (a + b)
        # Keep the trial point at least tol/2 inside so the bracket always
        # shrinks by a resolvable amount near convergence.
        half = 0.5 * tol
        if abs(c - a) < half:
            c = a + s * half
        elif abs(b - c) < half:
            c = b - s * half
        w2 = w1
        w1 = width
        dense_eval_step(T, Q, k, c, ytmp)
        fc = event(c, ytmp, args)
        if fc == 0.0:
            return c
        if (fc > 0.0) == (fb > 0.0):
            b = c
            fb = fc
            wb = fc
            if side == -1:
                wa *= 0.5
            side = -1
        else:
            a = c
            fa = fc
            wa = fc
            if side == 1:
                wb *= 0.5
            side = 1
    if abs(fa) < abs(fb):
        return a
    return b


@njit(**_JIT_INLINE)
def dopri5(fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats):
    """Integrate ``y' = fun(t, y)`` from `t0` to `t_end` with adaptive DOPRI5.

    Dormand–Prince 5(4) pair [DP80] with local extrapolation, Hairer's
    PI step-size controller and initial-step heuristic, Shampine's dense
    output [Sh86] stored in Hairer's ``CONTD5`` layout, terminal event
    location on the dense output, and Hairer's stiffness detection
    [HNW93, II.4-II.6, IV.2].

    Parameters
    ----------
    fun : numba-compiled callable
        ``fun(t, y, args, out) -> None`` writes dy/dt into `out`.
    event : numba-compiled callable
        ``event(t, y, args) -> float``.  The integration stops at the first
        zero along the solution after `t0` (sign change across an accepted
        step in either direction, or an exact zero at a step end).  An exact
        zero at `t0` is ignored.  Use :func:`no_event` for none.
    t0, t_end : float
        Start and end times; ``t_end < t0`` integrates backwards.
    y0 : ndarray of float64, shape (n,)
        Initial state (not modified).
    args : any numba-typed object
        Passed untouched to `fun` and `event`.
    rtol : float
        Relative tolerance.
    atol : ndarray of float64, shape (n,)
        Componentwise absolute tolerance.
    h0 : float
        Initial step magnitude; ``h0 <= 0`` selects it automatically (HINIT).
    h_max : float
        Largest step magnitude; ``h_max <= 0`` or inf means ``|t_end - t0|``.
    T : ndarray of float64, shape (>= M + 1,)
        Output: ``T[0] = t0``, ``T[k+1]`` = end of accepted step `k`.
    Q : ndarray of float64, shape (M, 5, n)
        Output: dense-output coefficients of each accepted step.  ``M`` is
        the step budget.
    stats : ndarray of int64, shape (N_STATS,)
        Output counters, see the ``STAT_*`` constants.

    Returns
    -------
    status : int
        One of ``SUCCESS, EVENT, MAX_STEPS, STEP_TOO_SMALL, NONFINITE``.
    nsteps : int
        Number of accepted steps stored in `T` and `Q`.
    t_stop : float
        Where the integration stopped (`t_end`, the event location, or the
        last accepted time on failure).

    Notes
    -----
    The error norm is Hairer's RMS norm
    ``sqrt(mean((err_i / (atol_i + rtol*max(|y_i|, |y_new_i|)))**2))``.
    The number of RHS evaluations is ``1 + [h0 <= 0] + 6*(accepted +
    rejected)``: one for f(t0, y0), one for the HINIT probe, and six per trial
    step thanks to FSAL.  Trial steps that produce non-finite values count as
    rejected.
    """
    n = y0.shape[0]
    M = Q.shape[0]
    for j in range(stats.shape[0]):
        stats[j] = 0
    T[0] = t0
    if t_end == t0:
        return SUCCESS, 0, t0

    direction = 1.0 if t_end > t0 else -1.0
    span = abs(t_end - t0)
    hmax = h_max
    if not (hmax > 0.0) or hmax > span:
        hmax = span

    y = np.empty(n)
    y_new = np.empty(n)
    y_err = np.empty(n)
    ytmp = np.empty(n)
    K = np.empty((7, n))
    for i in range(n):
        y[i] = y0[i]

    fun(t0, y, args, K[0])
    stats[STAT_FEV] = 1
    for i in range(n):
        if not math.isfinite(K[0, i]):
            return NONFINITE, 0, t0
        if not math.isfinite(y[i]):
            return NONFINITE, 0, t0

    if h0 > 0.0:
        habs = min(h0, hmax)
    else:
        # ytmp and y_err are free here and serve as the Euler probe's scratch.
        habs = _initial_step(fun, t0, y, K[0], args, direction, rtol, atol,
                             hmax, span, ytmp, y_err)
        stats[STAT_FEV] += 1

    g_old = event(t0, y, args)

    t = t0
    nsteps = 0
    facold = FACOLD_MIN
    reject = False
    n_nonfinite = 0
    iasti = 0
    nonsti = 0
    k1 = K[0]

    while True:
        if nsteps >= M:
            return MAX_STEPS, nsteps, t
        if habs <= 10.0 * EPS * abs(t):
            return STEP_TOO_SMALL, nsteps, t
        h = direction * habs
        # The 1.01 avoids a leftover sliver step that would trip the
        # too-small test, as in Hairer's code.
        last = (t + 1.01 * h - t_end) * direction >= 0.0
        if last:
            h = t_end - t

        dopri5_step(fun, t, y, h, args, k1, y_new, y_err, K)
        stats[STAT_FEV] += 6

        s = 0.0
        finite = True
        for i in range(n):
            yi = abs(y[i])
            yn = abs(y_new[i])
            sc = atol[i] + rtol * (yi if yi > yn else yn)
            r = y_err[i] / sc
            s += r * r
            if not (math.isfinite(y_new[i]) and math.isfinite(K[6, i])):
                finite = False
        err = math.sqrt(s / n)
        if not (finite and math.isfinite(err)):
            stats[STAT_REJECTED] += 1
            n_nonfinite += 1
            if n_nonfinite >= NONFINITE_MAX_TRIES:
                return NONFINITE, nsteps, t
            habs = abs(h) * NONFINITE_SHRINK
            reject = True
            continue
        n_nonfinite = 0

        # PI (Lund-stabilised) controller of DOPRI5, written with 1/factor so
        # that err = 0 needs no special case.
        fac11 = err ** ALPHA
        fac = fac11 / facold ** BETA
        fac = max(1.0 / MAX_FACTOR, min(1.0 / MIN_FACTOR, fac / SAFETY))

        if err <= 1.0:
            stats[STAT_ACCEPTED] += 1
            facold = max(err, FACOLD_MIN)

            # Stiffness estimate h*||k7-k6||/||y_new - y_stage6|| [HNW93 IV.2];
            # the denominator is formed from the stages to avoid cancellation.
            num = 0.0
            den = 0.0
            for i in range(n):
                d = K[6, i] - K[5, i]
                num += d * d
                dy = h * ((B1 - A61) * K[0, i] + (B2 - A62) * K[1, i]
                          + (B3 - A63) * K[2, i] + (B4 - A64) * K[3, i]
                          + (B5 - A65) * K[4, i] + B6 * K[5, i])
                den += dy * dy
            if den > 0.0:
                hlamb = abs(h) * math.sqrt(num / den)
                if hlamb > STIFF_THRESHOLD:
                    stats[STAT_STIFF_STEPS] += 1
                    nonsti = 0
                    iasti += 1
                    if iasti >= STIFF_DECLARE:
                        stats[STAT_STIFF] = 1
                else:
                    nonsti += 1
                    if nonsti >= NONSTIFF_RESET:
                        iasti = 0

            t_new = t_end if last else t + h
            T[nsteps + 1] = t_new
            dense_coefficients(y, y_new, h, K, Q[nsteps])
            nsteps += 1

            g_new = event(t_new, y_new, args)
            if g_new == 0.0:
                return EVENT, nsteps, t_new
            if (g_old < 0.0 and g_new > 0.0) or (g_old > 0.0 and g_new < 0.0):
                t_ev = _locate_event(event, args, T, Q, nsteps - 1, g_old,
                                     g_new, ytmp)
                return EVENT, nsteps, t_ev
            g_old = g_new

            if last:
                return SUCCESS, nsteps, t_end

            for i in range(n):
                y[i] = y_new[i]
                K[0, i] = K[6, i]
            t = t_new

            hnew = abs(h) / fac
            if hnew > hmax:
                hnew = hmax
            if reject and hnew > abs(h):
                # After a rejection the step must not grow [HNW93, II.4].
                hnew = abs(h)
            reject = False
            habs = hnew
        else:
            stats[STAT_REJECTED] += 1
            reject = True
            habs = abs(h) / min(1.0 / MIN_FACTOR, fac11 / SAFETY)


class Solution(NamedTuple):
    """Result of :func:`integrate`.

    Attributes
    ----------
    status : int
        Status code (``SUCCESS``, ``EVENT``, ...).
    t_stop : float
        Where the integration stopped.
    y_stop : ndarray, shape (n,)
        Dense-output value at `t_stop`.
    nsteps : int
        Number of accepted steps.
    T : ndarray, shape (nsteps + 1,)
        Step boundaries.
    Q : ndarray, shape (nsteps, 5, n)
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
            _dense_eval_many(self.T, self.Q, self.nsteps, ts, out)
        return out[0] if scalar else out


def integrate(fun, t0, y0, t_end, args=(), rtol=1e-6, atol=1e-9, event=None,
              h0=0.0, h_max=0.0, max_steps=100000):
    """Convenience wrapper around :func:`dopri5` for tests and interactive use.

    Parameters
    ----------
    fun : numba-compiled callable
        ``fun(t, y, args, out)``.
    t0, t_end : float
        Integration interval (``t_end < t0`` integrates backwards).
    y0 : array_like
        Initial state.
    args : tuple, optional
        Extra arguments for `fun` and `event`.
    rtol : float, optional
        Relative tolerance.
    atol : float or array_like, optional
        Absolute tolerance, broadcast to the state size.
    event : numba-compiled callable, optional
        Terminal event ``event(t, y, args) -> float``.
    h0, h_max : float, optional
        Initial and maximal step magnitude (``<= 0``: automatic / unbounded).
    max_steps : int, optional
        Budget of accepted steps.

    Returns
    -------
    Solution
    """
    y0 = np.ascontiguousarray(np.atleast_1d(np.asarray(y0, dtype=np.float64)).ravel())
    n = y0.shape[0]
    atol_arr = np.ascontiguousarray(
        np.broadcast_to(np.asarray(atol, dtype=np.float64), (n,)).copy())
    if event is None:
        event = no_event
    T = np.empty(max_steps + 1)
    Q = np.empty((max_steps, 5, n))
    stats = np.zeros(N_STATS, dtype=np.int64)
    status, nsteps, t_stop = dopri5(fun, event, float(t0), y0, float(t_end),
                                    args, float(rtol), atol_arr, float(h0),
                                    float(h_max), T, Q, stats)
    T = T[:nsteps + 1].copy()
    Q = Q[:nsteps].copy()
    if nsteps == 0:
        y_stop = y0.copy()
    else:
        y_stop = np.empty(n)
        dense_eval(T, Q, nsteps, t_stop, y_stop)
    return Solution(
        status=int(status),
        t_stop=float(t_stop),
        y_stop=y_stop,
        nsteps=int(nsteps),
        T=T,
        Q=Q,
        n_accepted=int(stats[STAT_ACCEPTED]),
        n_rejected=int(stats[STAT_REJECTED]),
        n_fev=int(stats[STAT_FEV]),
        n_stiff_steps=int(stats[STAT_STIFF_STEPS]),
        stiff=bool(stats[STAT_STIFF]),
    )
