"""RODAS4: the L-stable Rosenbrock method of order 4(3), for the stiff scalar stage 1.

Why a second integrator
-----------------------
Stage 1 has the Jacobian ``-B - 2/xi`` (model.md): about ``-2/eta`` in the interior and
``-(beta + 2)/xi`` near the axis, with ``beta ~ 2N/eta``. For small ``eta = eps L`` an explicit
method pays O(1/eta) steps twice over: for stability (``h < 3.3/|lambda|``) and, even below that,
because following a slow manifold with an explicit method costs accuracy in proportion to
``(h lambda)^p``. A Rosenbrock method with the exact Jacobian is L-stable, needs no Newton
iteration (one scalar division per stage here) and its step size depends on the smoothness of the
solution only, so the work per point stays bounded as ``eta -> 0``.

The method is RODAS4 of Hairer & Wanner [HW96, IV.7] (6 stages, stiffly accurate, embedded
3rd-order error estimate, 3rd-order continuous extension), with the step-size controller of
Gustafsson as in Hairer's ``rodas``. The coefficients are the published ones, written in the
``(1/(gamma h) - J) k_i = f(...) + h d_i f_t + sum c_ij k_j / h`` form.

Like :mod:`.rk45` it knows no physics; it is written for a scalar state (``y`` of length 1, the
calling convention of :func:`.rk45.dopri5`), returns the status codes and fills the counters of
:mod:`.stepping`, and writes its dense output in the layout of :mod:`.dense` so that
:func:`.dense.dense_eval` and :func:`.dense.event_after_step` serve either method. The split follows
:mod:`.rk45`: one step (:func:`rodas_step`), the controller (:func:`control`), a short driver.

References
----------
[HW96] E. Hairer, G. Wanner, Solving Ordinary Differential Equations II, 2nd ed., Springer 1996,
       section IV.7, Table 7.? ("RODAS"), and the code ``rodas.f``.
"""

from __future__ import annotations

import math

from numba import njit
from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE

from .dense import event_after_step
from .stepping import (EVENT, MAX_STEPS, NONFINITE, NONFINITE_SHRINK, STAT_FEV, STEP_TOO_SMALL,
                       SUCCESS, begin_run, count_trial, initial_guess, step_too_small)

# A tableau is (gamma, c2, c3, c4, d1, d2, d3, d4, a21, a31, a32, a41, a42, a43, a51, a52, a53,
# a54, C21, C31, C32, C41, C42, C43, C51, C52, C53, C54, C61, C62, C63, C64, C65, h21, h22, h23,
# h24, h25, h31, h32, h33, h34, h35); stage 6 reuses row 5 of a (stiffly accurate), and the
# continuous extension is y(theta) = (1-theta) y0 + theta (y1 + (1-theta)(q3 + theta q4)) with
# q3 = sum h2j k_j, q4 = sum h3j k_j.

# Hairer & Wanner's RODAS4 [HW96, IV.7].
RODAS4 = (
    0.25, 0.386, 0.21, 0.63, 0.25, -0.1043, 0.1035, -0.3620000000000023e-01,
    1.544, 0.9466785280815826, 0.2557011698983284, 3.314825187068521, 2.896124015972201,
    0.9986419139977817, 1.221224509226641, 6.019134481288629, 12.53708332932087,
    -0.6878860361058950,
    -5.6688, -2.430093356833875, -0.2063599157091915, -0.1073529058151375, -9.594562251023355,
    -20.47028614809616, 7.496443313967647, -10.24680431464352, -33.99990352819905,
    11.70890893206160, 8.083246795921522, -7.981132988064893, -31.52159432874371,
    16.31930543123136, -6.058818238834054,
    10.12623508344586, -7.487995877610167, -34.80091861555747, -7.992771707568823,
    1.025137723295662, -0.6762803392801253, 6.087714651680015, 16.43084320892478,
    24.76722511418386, -6.594389125716872,
)
# Steinebach's RODASP ("Rodas4P"): order 4 also on Prothero-Robinson-type problems, where
# RODAS4 loses order for intermediate h*|lambda| (our stage 1 at small eta) [St95].
RODAS4P = (
    0.25, 0.75, 0.21, 0.63, 0.25, -0.5, -0.023504, -0.0362,
    3.0, 1.831036793486759, 0.4955183967433795, 2.304376582692669, -0.05249275245743001,
    -1.176798761832782, -7.170454962423024, -4.741636671481785, -16.31002631330971,
    -1.062004044111401,
    -12.0, -8.791795173947035, -2.207865586973518, 10.81793056857153, 6.780270611428266,
    19.53485944642410, 34.19095006749676, 15.49671153725963, 54.74760875964130,
    14.16005392148534, 34.62605830930532, 15.30084976114473, 56.99955578662667,
    18.40807009793095, -5.714285714285717,
    25.09876703708589, 11.62013104361867, 28.49148307714626, -5.664021568594133, 0.0,
    1.638054557396973, -0.7373619806678748, 8.477918219238990, 15.99253148779520,
    -1.882352941176471,
)
# Steinebach's Rodas4P2 [St20]: as RODAS4P, with a dense output that is stiffly accurate too.
RODAS4P2 = (
    0.25, 0.75, 0.321448134013046, 0.519745732277726, 0.25, -0.5, -0.189532918363016,
    0.085612108792769,
    3.0, 0.906377755268814, -0.189707390391685, 3.758617027739064, 1.161741776019525,
    -0.849258085312803, 7.089566927282776, 4.573591406461604, -8.423496976860259,
    -0.959280113459775,
    -12.0, -6.354581592719008, 0.338972550544623, -8.575016317114033, -7.606483992117508,
    12.224997650124820, -5.888975457523102, -8.157396617841821, 24.805546872612922,
    12.790401512796979, -4.408651676063871, -6.692003137674639, 24.625568527593117,
    16.627521966636085, -5.714285714285718,
    -5.323528268423303, -10.042123754867493, 17.175254928256965, -5.079931171878093,
    -0.016185991706112, 6.984505741529879, 6.914061169603662, -0.849178943070653,
    18.104410789349338, -3.516963011559032,
)
TABLEAU = RODAS4P2

# Gustafsson controller, as in rodas.f: the error estimate is O(h^4).
SAFETY = 0.9
MAX_GROWTH = 6.0
MAX_SHRINK = 5.0


@njit(**_JIT_INLINE)
def rodas_step(fun, jac, t, y, hs, args, tab, ys, ytmp):
    """One Rosenbrock step of signed size `hs` from ``(t, y)`` with the tableau `tab`.

    Parameters
    ----------
    fun, jac : numba-compiled callables
        As for :func:`rodas4`.
    t, y, hs : float
        Start time, scalar state and signed step size.
    args : any numba-typed object
        Passed through to `fun` and `jac`.
    tab : tuple of float
        One of ``RODAS4``, ``RODAS4P``, ``RODAS4P2``.
    ys, ytmp : ndarray of float64, shape (1,)
        Scratch for the stage argument and the stage derivative.

    Returns
    -------
    y_new : float
        The 4th-order solution at ``t + hs``.
    e : float
        Embedded error estimate (the last stage increment).
    k1, k2, k3, k4, k5 : float
        Stage increments, for the dense output (:func:`dense_coefficients`).
    """
    (GAMMA, C2, C3, C4, D1, D2, D3, D4, A21, A31, A32, A41, A42, A43, A51, A52, A53, A54,
     C21, C31, C32, C41, C42, C43, C51, C52, C53, C54, C61, C62, C63, C64, C65) = tab[:33]
    # The Jacobian and f_t at the step start, reused by every stage (Rosenbrock).
    ys[0] = y
    fun(t, ys, args, ytmp)
    f0 = ytmp[0]
    J, ft = jac(t, ys, args)
    den = 1.0 / (GAMMA * hs) - J
    k1 = (f0 + hs * D1 * ft) / den
    ys[0] = y + A21 * k1
    fun(t + C2 * hs, ys, args, ytmp)
    k2 = (ytmp[0] + hs * D2 * ft + C21 * k1 / hs) / den
    ys[0] = y + A31 * k1 + A32 * k2
    fun(t + C3 * hs, ys, args, ytmp)
    k3 = (ytmp[0] + hs * D3 * ft + (C31 * k1 + C32 * k2) / hs) / den
    ys[0] = y + A41 * k1 + A42 * k2 + A43 * k3
    fun(t + C4 * hs, ys, args, ytmp)
    k4 = (ytmp[0] + hs * D4 * ft + (C41 * k1 + C42 * k2 + C43 * k3) / hs) / den
    y5 = y + A51 * k1 + A52 * k2 + A53 * k3 + A54 * k4
    ys[0] = y5
    fun(t + hs, ys, args, ytmp)
    k5 = (ytmp[0] + (C51 * k1 + C52 * k2 + C53 * k3 + C54 * k4) / hs) / den
    y6 = y5 + k5
    ys[0] = y6
    fun(t + hs, ys, args, ytmp)
    e = (ytmp[0] + (C61 * k1 + C62 * k2 + C63 * k3 + C64 * k4 + C65 * k5) / hs) / den
    return y6 + e, e, k1, k2, k3, k4, k5


@njit(**_JIT)
def dense_coefficients(y, y_new, k1, k2, k3, k4, k5, tab, q):
    """Fill the dense-output coefficients of one accepted step, in :mod:`.dense`'s layout.

    RODAS's continuous extension ``(1-theta) y0 + theta (y1 + (1-theta)(q3 + theta q4))`` is
    that layout with ``q4 = 0``.

    Parameters
    ----------
    y, y_new : float
        Solution at the start and end of the step.
    k1, k2, k3, k4, k5 : float
        Stage increments from :func:`rodas_step`.
    tab : tuple of float
        The tableau of the step.
    q : ndarray of float64, shape (N_DENSE, 1)
        Output (rows 4-7 zero: :mod:`.dense`'s layout).
    """
    H21, H22, H23, H24, H25, H31, H32, H33, H34, H35 = tab[33:]
    q[0, 0] = y
    q[1, 0] = y_new - y
    q[2, 0] = H21 * k1 + H22 * k2 + H23 * k3 + H24 * k4 + H25 * k5
    q[3, 0] = H31 * k1 + H32 * k2 + H33 * k3 + H34 * k4 + H35 * k5
    q[4, 0] = 0.0
    q[5, 0] = 0.0
    q[6, 0] = 0.0
    q[7, 0] = 0.0


@njit(**_JIT)
def error_norm(e, y, y_new, atol, rtol):
    """The scalar case of :func:`.stepping.error_norm`, without its squaring (no overflow to inf).

    Not inlined, so that a zero scale gives inf whatever the caller's error model (see
    :mod:`.rk45`).

    Parameters
    ----------
    e, y, y_new : float
        Error estimate, states at the start and end of the step.
    atol, rtol : float
        Tolerances.

    Returns
    -------
    float
    """
    return abs(e) / (atol + rtol * max(abs(y), abs(y_new)))


@njit(**_JIT)
def control(err, h, h_max, h_old, err_old, rejected):
    """Gustafsson's predictive step-size controller, as in ``rodas.f``: accept or reject.

    Parameters
    ----------
    err : float
        Error norm of the trial step; NaN or inf when it produced non-finite values.
    h : float
        Magnitude of the trial step.
    h_max : float
        Largest allowed step magnitude.
    h_old, err_old : float
        Magnitude and error norm (at least 0.01) of the last accepted step; ``h_old = 0``
        before the first one.
    rejected : bool
        Whether the previous trial step was rejected: then the step must not grow.

    Returns
    -------
    accept : bool
    h_next : float
        Magnitude of the next trial step.
    h_old, err_old : float
        The updated memory.
    """
    if not math.isfinite(err):
        return False, h * NONFINITE_SHRINK, h_old, err_old
    fac = max(1.0 / MAX_GROWTH, min(MAX_SHRINK, err ** 0.25 / SAFETY))
    h_new = h / fac
    if err > 1.0:
        return False, h_new, h_old, err_old
    if h_old > 0.0:
        fac_pred = (h_old / h) * (err * err / err_old) ** 0.25 / SAFETY
        fac_pred = max(1.0 / MAX_GROWTH, min(MAX_SHRINK, fac_pred))
        fac = max(fac, fac_pred)
        h_new = h / fac
    if rejected:
        h_new = min(h_new, h)
    return True, min(h_new, h_max), h, max(0.01, err)


@njit(**_JIT)
def initial_step(y0, f0, atol, rtol, h_max, span):
    """First step magnitude: HINIT's first estimate only (:func:`.stepping.initial_guess`).

    HINIT's Euler probe would measure the fast (stiff) time scale, which an L-stable method
    need not resolve.

    Parameters
    ----------
    y0, f0 : ndarray of float64, shape (1,)
        Initial state and ``f(t0, y0)``.
    atol : ndarray of float64, shape (1,)
        Absolute tolerance.
    rtol : float
        Relative tolerance.
    h_max, span : float
        Largest allowed step and ``|t_end - t0|``.

    Returns
    -------
    float
    """
    h = initial_guess(y0, f0, atol, rtol)[0]
    return min(max(h, 1e-10 * span), h_max)


@njit(**_JIT_INLINE)
def rodas4(fun, jac, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats, tab=TABLEAU):
    """Integrate a scalar ODE ``y' = f(t, y)`` with RODAS4; same contract as :func:`.rk45.dopri5`.

    Parameters
    ----------
    fun : callable
        ``fun(t, y, args, out)`` writes ``f`` into ``out[0]``.
    jac : callable
        ``jac(t, y, args)`` returns ``(df/dy, df/dt)`` at ``(t, y[0])``, exact.
    event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats
        As for :func:`.rk45.dopri5` (``y0`` and ``atol`` of length 1). ``stats[STAT_FEV]`` counts
        right-hand-side evaluations (6 per trial step, plus one per Jacobian for ``f`` there).
    tab : tuple of float, optional
        The tableau.

    Returns
    -------
    (status, nsteps, t_stop)
        As for :func:`.rk45.dopri5`; the dense output in ``T``/``Q`` is read by
        :func:`.dense.dense_eval`.
    """
    direction, span, hmax = begin_run(t0, t_end, h_max, T, stats)
    if span == 0.0:
        return SUCCESS, 0, t0
    ys = y0.copy()
    ytmp = y0.copy()
    t = t0
    y = y0[0]
    fun(t, y0, args, ytmp)
    stats[STAT_FEV] += 1
    h = min(h0, hmax) if h0 > 0.0 else initial_step(y0, ytmp, atol, rtol, hmax, span)
    g_prev = event(t, y0, args)
    h_old, err_old, accept = 0.0, 1.0, True
    n_nonfinite = nsteps = 0
    while True:
        if nsteps >= Q.shape[0]:
            return MAX_STEPS, nsteps, t
        if (t_end - t) * direction <= 0.0:
            return SUCCESS, nsteps, t
        if step_too_small(h, t):
            return STEP_TOO_SMALL, nsteps, t
        # Clipped onto t_end without dopri5's 1.01 sliver guard: the too-small test above sees
        # the controller's step, before clipping, so a sliver last step is still taken.
        last = h >= abs(t_end - t)
        if last:
            h = abs(t_end - t)
        hs = direction * h
        y_new, e, k1, k2, k3, k4, k5 = rodas_step(fun, jac, t, y, hs, args, tab, ys, ytmp)
        stats[STAT_FEV] += 6
        err = error_norm(e, y, y_new, atol[0], rtol)
        if not math.isfinite(y_new):
            err = math.nan
        accept, h, h_old, err_old = control(err, h, hmax, h_old, err_old, not accept)
        n_nonfinite, give_up = count_trial(accept, err, n_nonfinite, stats)
        if give_up:
            return NONFINITE, nsteps, t
        if not accept:
            continue
        t_new = t + hs
        dense_coefficients(y, y_new, k1, k2, k3, k4, k5, tab, Q[nsteps])
        T[nsteps + 1] = t_new
        nsteps += 1
        ys[0] = y_new
        fired, t_event, g_prev = event_after_step(event, args, T, Q, nsteps, g_prev, ys, ytmp)
        if fired:
            return EVENT, nsteps, t_event
        t = t_new
        y = y_new
        if last:
            return SUCCESS, nsteps, t
