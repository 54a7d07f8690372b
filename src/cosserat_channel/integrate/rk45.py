"""Adaptive Dormand–Prince 5(4) integrator written for Numba.

The integrator is generic over the right-hand side: it knows nothing about the physics of the
channel problem. It is a transcription of Hairer's ``DOPRI5`` code (step-size control, dense
output ``CONTD5``, initial step ``HINIT``, stiffness detection) into ``@njit`` kernels that
allocate their work arrays once per call, so that it can be called millions of times in
parameter sweeps on small (n = 1 or 2) systems. It is split the way scipy splits a solver
(``integrate/_ivp/rk.py`` + ``common.py``): the tableau as module constants, one step
(:func:`dopri5_step`) and the controller (:func:`control`) here, which :func:`dopri5` hands to
the driver loop it shares with DOP853 (:func:`.explicit.explicit_rk`); the error norm,
``HINIT``, the stiffness test, outcome codes and counters in :mod:`.stepping`; the dense output's
coefficients here (:func:`dense_coefficients`), its evaluation and event location in :mod:`.dense`.

All kernels are compiled with ``error_model="numpy"`` so that a division by zero yields inf/NaN
(which the integrator then handles as a non-finite trial step) instead of raising a Python
exception from inside a kernel. An ``inline="always"`` kernel (below) is compiled with the error
model of the jitted caller it is inlined into, so the divisions that can meet a zero scale for
legitimate input (the error norms, the controller) are kept in kernels that are not inlined.

The kernels that receive the right-hand side (``dopri5``, ``dopri5_step``, the driver, and the
helpers in :mod:`.stepping`, :mod:`.dense` and :mod:`.roots` that receive ``fun`` or ``event``) are
additionally ``inline="always"`` (Numba-IR inlining into jitted callers). A jitted caller that
passes a global ``@njit`` function into a non-inlined kernel has to materialise the dispatcher
object's address in its machine code, which Numba refuses to cache ("uses dynamic globals").
With inlining the call to ``fun`` becomes a direct call, so a driver such as::

    @njit(cache=True)
    def run(y0, T, Q, stats):
        return dopri5(my_rhs, no_event, 0.0, y0, 1.0, (), 1e-8, atol, 0.0, 0.0,
                      T, Q, stats)

is cached across processes (and the step is about 30 % faster). Calling ``dopri5`` directly
from Python with a dispatcher argument still works, but Numba keys that specialisation on the
dispatcher's address, so it is recompiled in every new process.

References
----------
.. [DP80] J. R. Dormand and P. J. Prince, "A family of embedded Runge-Kutta formulae",
   J. Comput. Appl. Math. 6(1), 19-26 (1980).
.. [HNW93] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary Differential Equations I:
   Nonstiff Problems", 2nd ed., Springer (1993); Sec. II.4 (automatic step size control,
   ``HINIT``), II.5 (``DOPRI5``), II.6 (dense output, ``CONTD5``), IV.2 (stiffness detection).
.. [Sh86] L. F. Shampine, "Some practical Runge-Kutta formulas", Math. Comp. 46(173), 135-150
   (1986).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE

from .dense import N_DENSE, Solution, hermite_rows
from .explicit import explicit_rk
from .stepping import N_STATS, NONFINITE_SHRINK, error_norm, no_event

# The outcome codes, counter slots and no_event of dopri5's calling convention are stepping's.
__all__ = ["dopri5", "dopri5_step", "dense_coefficients", "control", "integrate"]

# ---------------------------------------------------------------------------------------------
# Dormand–Prince 5(4) tableau [DP80], as printed in [HNW93, Table II.5.2]; exact fractions.
# ---------------------------------------------------------------------------------------------
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

# Order of the embedded error estimate: the local error is O(h**5).

# Coefficients of the 4th-order continuous extension of Dormand–Prince by Shampine [Sh86], in
# the form of Hairer's CONTD5 [HNW93, II.6] (the optimal-c6 choice); they weigh the stages K of
# :func:`dopri5_step` (K[1] has weight 0).
D1 = -12715105075 / 11282082432
D3 = 87487479700 / 32700410799
D4 = -10690763975 / 1880347072
D5 = 701980252875 / 199316789632
D6 = -1453857185 / 822651844
D7 = 69997945 / 29380423


@njit(**_JIT)
def dense_coefficients(y, y_new, h, K, q):
    """Fill the dense-output coefficients of one accepted Dormand–Prince step.

    Parameters
    ----------
    y, y_new : ndarray of float64, shape (n,)
        Solution at the start and end of the step.
    h : float
        Signed step size.
    K : ndarray of float64, shape (7, n)
        Stage derivatives from :func:`dopri5_step` (``K[6]`` is f at `y_new`).
    q : ndarray of float64, shape (N_DENSE, n)
        Output, in the layout of the module docstring (rows 5-7 zero).
    """
    n = y.shape[0]
    for i in range(n):
        hermite_rows(y[i], y_new[i], h, K[0, i], K[6, i], q, i)
        q[4, i] = h * (D1 * K[0, i] + D3 * K[2, i] + D4 * K[3, i]
                       + D5 * K[4, i] + D6 * K[5, i] + D7 * K[6, i])
        q[5, i] = 0.0
        q[6, i] = 0.0
        q[7, i] = 0.0

ERROR_ORDER = 4

# ---------------------------------------------------------------------------------------------
# Step-size controller (Hairer's DOPRI5 defaults)
# ---------------------------------------------------------------------------------------------
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
BETA = 0.04
ALPHA = 0.2 - 0.75 * BETA
FACOLD_MIN = 1e-4

# Stiffness detection [HNW93, IV.2]: h*rho beyond the real stability boundary of DOPRI5 (about
# 3.3) means the step size is limited by stability (the run lengths STIFF_DECLARE and
# NONSTIFF_RESET are stepping's, shared with DOP853).
STIFF_THRESHOLD = 3.25
# y_new minus the 6th stage's argument (both at t + h) is h * sum_j STIFF_DY[j] K[j]
# (stepping.stiffness_ratio).
STIFF_DY = np.array([B1 - A61, B2 - A62, B3 - A63, B4 - A64, B5 - A65, B6])


@njit(**_JIT_INLINE)
def dopri5_step(fun, t, y, h, args, k1, y_new, y_err, K):
    """Take one Dormand–Prince 5(4) step of size `h` from ``(t, y)``.

    Accepting or rejecting it is :func:`control`'s business; this kernel only evaluates the
    stages [DP80], [HNW93, II.5].

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
    # y_new doubles as the stage-argument scratch so that no allocation happens per step; it is
    # overwritten with the solution before stage 7.
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
def control(err, h_abs, h_max, facold, reject):
    """Accept or reject a trial step, and choose the next step magnitude.

    The PI (Lund-stabilised) controller of DOPRI5 [HNW93, II.4], written with ``1/factor`` so
    that ``err = 0`` needs no special case.

    Parameters
    ----------
    err : float
        Error norm of the trial step (:func:`.stepping.error_norm`); NaN or inf when the step
        produced non-finite values.
    h_abs : float
        Magnitude of the trial step.
    h_max : float
        Largest allowed step magnitude.
    facold : float
        The controller's memory: the error norm of the last accepted step (at least
        ``FACOLD_MIN``).
    reject : bool
        Whether the previous trial step was rejected: then the step must not grow.

    Returns
    -------
    accept : bool
        Whether the step is accepted.
    h_next : float
        Magnitude of the next trial step.
    facold : float
        The updated memory.
    """
    if not math.isfinite(err):
        return False, h_abs * NONFINITE_SHRINK, facold
    fac11 = err ** ALPHA
    fac = fac11 / facold ** BETA
    fac = max(1.0 / MAX_FACTOR, min(1.0 / MIN_FACTOR, fac / SAFETY))
    if err > 1.0:
        # The memory term is left out after a rejection, as in Hairer's code.
        return False, h_abs / min(1.0 / MIN_FACTOR, fac11 / SAFETY), facold
    h_next = h_abs / fac
    if h_next > h_max:
        h_next = h_max
    if reject and h_next > h_abs:
        h_next = h_abs
    return True, h_next, max(err, FACOLD_MIN)


@njit(**_JIT_INLINE)
def _trial(fun, t, y, h, args, K, y_new, y_err, atol, rtol):
    # explicit_rk's trial step: the stages, y_new, and the error norm of the estimate y_err.
    dopri5_step(fun, t, y, h, args, K[0], y_new, y_err, K)
    return error_norm(y_err, y, y_new, atol, rtol)


@njit(**_JIT_INLINE)
def _dense(fun, t, y, y_new, h, args, K, y_err, q):
    # explicit_rk's dense output: CONTD5 needs no further stage.
    dense_coefficients(y, y_new, h, K, q)


@njit(**_JIT_INLINE)
def dopri5(fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats, rho0=0.0):
    """Integrate ``y' = fun(t, y)`` from `t0` to `t_end` with adaptive DOPRI5.

    Dormand–Prince 5(4) pair [DP80] with local extrapolation, Hairer's PI step-size controller,
    initial-step heuristic and stiffness detection, Shampine's dense output in Hairer's
    ``CONTD5`` layout (:mod:`.dense`), and terminal event location on the dense output
    [HNW93, II.4-II.6, IV.2].

    Parameters
    ----------
    fun : numba-compiled callable
        ``fun(t, y, args, out) -> None`` writes dy/dt into `out`.
    event : numba-compiled callable
        ``event(t, y, args) -> float``. The integration stops at the first zero along the
        solution after `t0` (sign change across an accepted step in either direction, or an
        exact zero at a step end). An exact zero at `t0` is ignored. Use
        :func:`.stepping.no_event` for none.
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
    Q : ndarray of float64, shape (M, N_DENSE, n)
        Output: dense-output coefficients of each accepted step (:mod:`.dense`'s layout).
        ``M`` is the step budget.
    stats : ndarray of int64, shape (N_STATS,)
        Output counters, see the ``STAT_*`` constants.
    rho0 : float, optional
        ``|lambda|`` of the Jacobian at ``(t0, y0)`` where the caller knows it (its spectral
        radius; 0: unknown). A step that passes its error test is still rejected where ``|h|``
        times the ``|lambda|`` at its start (``rho0``, then Hairer's estimate from the last
        accepted step) lies beyond ``STABLE_FACTOR`` times the stability boundary
        (:func:`.stepping.beyond_stability`); the next trial is the boundary.

    Returns
    -------
    status : int
        One of ``SUCCESS, EVENT, MAX_STEPS, STEP_TOO_SMALL, NONFINITE``.
    nsteps : int
        Number of accepted steps stored in `T` and `Q`.
    t_stop : float
        Where the integration stopped (`t_end`, the event location, or the last accepted time
        on failure).

    Notes
    -----
    The number of RHS evaluations is ``1 + [h0 <= 0] + 6*(accepted + rejected)``: one for
    f(t0, y0), one for the HINIT probe, and six per trial step thanks to FSAL. Trial steps that
    produce non-finite values count as rejected.
    """
    return explicit_rk(_trial, control, _dense, 7, 6, ERROR_ORDER, FACOLD_MIN, STIFF_DY,
                       STIFF_THRESHOLD, fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T,
                       Q, stats, rho0)


def integrate(fun, t0, y0, t_end, args=(), rtol=1e-6, atol=1e-9, event=None,
              h0=0.0, h_max=0.0, max_steps=100000, rho0=0.0):
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
    rho0 : float, optional
        ``|lambda|`` of the Jacobian at the start, if known (see :func:`dopri5`).

    Returns
    -------
    .dense.Solution
    """
    y0 = np.ascontiguousarray(np.atleast_1d(np.asarray(y0, dtype=np.float64)).ravel())
    n = y0.shape[0]
    atol_arr = np.ascontiguousarray(
        np.broadcast_to(np.asarray(atol, dtype=np.float64), (n,)).copy())
    if event is None:
        event = no_event
    T = np.empty(max_steps + 1)
    Q = np.empty((max_steps, N_DENSE, n))
    stats = np.zeros(N_STATS, dtype=np.int64)
    status, nsteps, t_stop = dopri5(fun, event, float(t0), y0, float(t_end),
                                    args, float(rtol), atol_arr, float(h0),
                                    float(h_max), T, Q, stats, float(rho0))
    return Solution.from_run(status, nsteps, t_stop, y0, T, Q, stats)
