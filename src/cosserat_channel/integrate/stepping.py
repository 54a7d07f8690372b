"""What the adaptive integrators of the package share, in the role of scipy's
``integrate/_ivp/common.py``: outcome codes and their messages, counter slots, the event function
that never fires, weighted RMS norms, a finiteness test, Hairer's initial-step heuristic
``HINIT``, his stiffness test, and the driver policy: how a run starts (:func:`begin_run`), when
a step is too small (:func:`step_too_small`), how trial steps are counted and when a run of
non-finite ones ends it (:func:`count_trial`, ``NONFINITE_MAX_TRIES``).

The explicit pairs (:mod:`.rk45`, :mod:`.dop853`, any ``n``, one driver loop in
:mod:`.explicit`) and RODAS (:mod:`.rosenbrock`, stiff, scalar) return the same outcome codes,
fill the same counters and write the same dense output (:mod:`.dense`), so that the solver can
run any of them for stage 1. What differs between them (step, error norm, step-size controller,
step clipping, the initial step of RODAS) stays in their modules.

Kernels that receive the right-hand side are ``inline="always"``; see :mod:`.rk45` for why, and
for why the norms are not. The small helpers that receive no function (:func:`begin_run`,
:func:`step_too_small`, :func:`clip_to_end`, the stiffness test, the counters) are plain kernels:
LLVM inlines them into the driver all the same, while every site inlined in Numba's IR is a copy
of the callee's IR that Numba makes and types again, seconds of a first run's compilation.

References
----------
.. [HNW93] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary Differential Equations I:
   Nonstiff Problems", 2nd ed., Springer (1993); Sec. II.4 (error norm, ``HINIT``).
"""

from __future__ import annotations

import math

from numba import njit
from .._jit import EPS, JIT as _JIT, JIT_INLINE as _JIT_INLINE

__all__ = [
    "SUCCESS",
    "EVENT",
    "MAX_STEPS",
    "STEP_TOO_SMALL",
    "NONFINITE",
    "MESSAGES",
    "message",
    "STAT_ACCEPTED",
    "STAT_REJECTED",
    "STAT_FEV",
    "STAT_STIFF_STEPS",
    "STAT_STIFF",
    "N_STATS",
    "STIFF_DECLARE",
    "NONSTIFF_RESET",
    "count_stiffness",
    "stiffness_ratio",
    "STABLE_FACTOR",
    "beyond_stability",
    "EPS",
    "step_limit",
    "clip_to_end",
    "first_step",
    "NONFINITE_SHRINK",
    "NONFINITE_MAX_TRIES",
    "begin_run",
    "step_too_small",
    "count_trial",
    "initial_guess",
    "no_event",
    "rms_norm",
    "error_norm",
    "all_finite",
    "initial_step",
]

# Outcome codes, the first value every integrator returns; MESSAGES says what each means.
SUCCESS = 0
EVENT = 1
MAX_STEPS = -1
STEP_TOO_SMALL = -2
NONFINITE = -3

MESSAGES = {
    SUCCESS: "reached the end of the interval",
    EVENT: "stopped where the event function reached zero",
    MAX_STEPS: "spent the budget of accepted steps before the end of the interval",
    STEP_TOO_SMALL: "the step size fell below the resolution of t (10 machine epsilons of |t|)",
    NONFINITE: "the right-hand side gave NaN or inf at the start, or on every trial step of a "
               "shrinking run",
}

# Slots of the counter array ``stats`` (int64, length N_STATS).
STAT_ACCEPTED = 0
STAT_REJECTED = 1
STAT_FEV = 2
STAT_STIFF_STEPS = 3
STAT_STIFF = 4
N_STATS = 5

# Stiffness detection of the explicit pairs [HNW93, IV.2], counted as in Hairer's DOPRI5 and
# DOP853 codes: this many accepted steps in a row limited by stability declare the problem stiff
# (stats[STAT_STIFF] = 1), and this many that are not, in a row, reset the run.
STIFF_DECLARE = 15
NONSTIFF_RESET = 6

# An explicit pair accepts a step only where |h lambda|, by the |lambda| known at its start, is
# within this many times the pair's real stability boundary (beyond_stability).
STABLE_FACTOR = 1.5

# Shrink factor after a trial step produced NaN/inf: the step most likely left the domain of f.
NONFINITE_SHRINK = 0.25
# A run gives up (NONFINITE) at this many non-finite trial steps in a row: the last of them is
# 0.25**19 ~ 4e-12 of the first, far below any step that could be taken on purpose.
NONFINITE_MAX_TRIES = 20


def message(code):
    """What the outcome code `code` of an integrator means, in a phrase.

    Parameters
    ----------
    code : int
        A status returned by :func:`.rk45.dopri5`, :func:`.dop853.dop853` or
        :func:`.rosenbrock.rodas4`.

    Returns
    -------
    str
        The phrase of :data:`MESSAGES`, or ``"unknown outcome code <code>"``.
    """
    return MESSAGES.get(int(code), f"unknown outcome code {code}")


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


@njit(**_JIT)
def stiffness_ratio(h, K, k_new, dy_weights):
    """Hairer's estimate of ``|h lambda|`` for a step of an explicit RK pair [HNW93, IV.2].

    ``|h| ||f(t+h, y_new) - f(t+h, Y)|| / ||y_new - Y||``, where ``Y`` is the argument of the last
    stage evaluated at ``t + h`` (``K[k_new - 1] = f(t+h, Y)``, ``K[k_new] = f(t+h, y_new)``).
    ``y_new - Y`` is formed from the stages, ``h sum_j dy_weights[j] K[j]``, because the two
    states agree to a few digits.

    Parameters
    ----------
    h : float
        Signed size of the step.
    K : ndarray of float64, shape (stages, n)
        Its stages.
    k_new : int
        Row of ``f(t+h, y_new)`` in ``K``.
    dy_weights : ndarray of float64
        The pair's weights minus the last stage's coefficients (``b_j - a_{k_new-1, j}``).

    Returns
    -------
    float
        The estimate; NaN where ``y_new - Y`` vanishes.
    """
    num = 0.0
    den = 0.0
    for i in range(K.shape[1]):
        d = K[k_new, i] - K[k_new - 1, i]
        num += d * d
        acc = 0.0
        for j in range(dy_weights.shape[0]):
            acc += dy_weights[j] * K[j, i]
        dy = h * acc
        den += dy * dy
    if not den > 0.0:
        return math.nan
    return abs(h) * math.sqrt(num / den)


@njit(**_JIT)
def count_stiffness(h_rho, threshold, iasti, nonsti, stats):
    """Hairer's stiffness test after an accepted step, on its :func:`stiffness_ratio` ``h_rho``.

    Against ``threshold``, the pair's real stability boundary (beyond it the step size is
    limited by stability), the step is counted as stiff or not: ``STAT_STIFF_STEPS`` counts the
    stiff steps, ``STAT_STIFF`` is set to 1 after a run of ``STIFF_DECLARE`` of them
    (``NONSTIFF_RESET`` non-stiff steps in a row reset the run). ``iasti, nonsti`` are the
    current run lengths; returns them updated (unchanged where ``h_rho`` is NaN).
    """
    if math.isnan(h_rho):
        return iasti, nonsti
    if h_rho > threshold:
        stats[STAT_STIFF_STEPS] += 1
        nonsti = 0
        iasti += 1
        if iasti >= STIFF_DECLARE:
            stats[STAT_STIFF] = 1
    else:
        nonsti += 1
        if nonsti >= NONSTIFF_RESET:
            iasti = 0
    return iasti, nonsti


@njit(**_JIT)
def beyond_stability(h, rho, threshold):
    """Whether a step of size ``h`` that passed its error test must be rejected all the same:
    ``|h| rho`` beyond ``STABLE_FACTOR`` times ``threshold``, the pair's real stability boundary.

    ``rho`` estimates ``|lambda|`` at the step's start: :func:`stiffness_ratio` of the last
    accepted step divided by its size, or for the first step what the caller knows of the
    Jacobian (0: nothing, no check). Why: an explicit pair's error estimate is a polynomial in
    ``h lambda`` with zeros far outside the stability region (DOP853's at ``h lambda ~ -23`` for
    ``y' = lambda y``), where a step whose result is useless passes the error test. The step's
    own estimate cannot stand in for ``rho``: its stages are as wrong as its result (on stage 1,
    next to such zeros, it came out below 1 for most of them). Steps that far out are rejected
    by the error test anyway unless they hit a zero, so the check leaves other runs as they were
    (docs/model.md, "Stiffness and the integrator", says what was measured).
    """
    return abs(h) * rho > STABLE_FACTOR * threshold


@njit(**_JIT)
def rms_norm(v, y, atol, rtol):
    """``sqrt(mean((v_i / (atol_i + rtol*|y_i|))**2))``: :func:`error_norm` of `v` with the
    scale of `y` alone (``y_new = y``), for ``HINIT``, which has no ``y_new`` yet."""
    return error_norm(v, y, y, atol, rtol)


@njit(**_JIT)
def error_norm(y_err, y, y_new, atol, rtol):
    """Hairer's error norm of a trial step [HNW93, II.4].

    ``sqrt(mean((err_i / (atol_i + rtol*max(|y_i|, |y_new_i|)))**2))``; a step is acceptable
    when it is at most 1.

    Parameters
    ----------
    y_err, y, y_new, atol : ndarray of float64, shape (n,)
        Error estimate, states at the start and end of the step, absolute tolerance.
    rtol : float
        Relative tolerance.

    Returns
    -------
    float
    """
    n = y.shape[0]
    s = 0.0
    for i in range(n):
        yi = abs(y[i])
        yn = abs(y_new[i])
        sc = atol[i] + rtol * (yi if yi > yn else yn)
        r = y_err[i] / sc
        s += r * r
    return math.sqrt(s / n)


@njit(**_JIT)
def all_finite(v):
    """Whether every entry of the 1-d array `v` is finite.

    Parameters
    ----------
    v : ndarray of float64, shape (n,)

    Returns
    -------
    bool
    """
    for i in range(v.shape[0]):
        if not math.isfinite(v[i]):
            return False
    return True


@njit(**_JIT)
def begin_run(t0, t_end, h_max, T, stats):
    """What every driver does first: zero ``stats``, set ``T[0] = t0``, and return
    ``(direction, span, hmax)``: the sign of ``t_end - t0``, ``|t_end - t0|`` and
    :func:`step_limit`'s largest step magnitude (the caller returns at once when ``span == 0``)."""
    stats[:] = 0
    T[0] = t0
    span = abs(t_end - t0)
    return (1.0 if t_end > t0 else -1.0), span, step_limit(h_max, span)


@njit(**_JIT)
def step_too_small(habs, t):
    """Whether a step of magnitude `habs` from `t` is below the resolution of `t`: Hairer's test
    ``0.1 |h| <= uround |t|`` [HNW93, II.4]; a run then stops with ``STEP_TOO_SMALL``."""
    return habs <= 10.0 * EPS * abs(t)


@njit(**_JIT)
def count_trial(accept, err, n_nonfinite, stats):
    """Count a trial step in ``stats`` and keep the run of non-finite ones.

    Parameters
    ----------
    accept : bool
        The controller's verdict (never True for a non-finite `err`).
    err : float
        The trial step's error norm; NaN or inf when it produced non-finite values.
    n_nonfinite : int
        Non-finite trial steps in a row before this one.
    stats : ndarray of int64, shape (N_STATS,)
        Counters: ``STAT_ACCEPTED`` or ``STAT_REJECTED`` grows by one.

    Returns
    -------
    n_nonfinite : int
        Non-finite trial steps in a row, this one included.
    give_up : bool
        Whether they reached ``NONFINITE_MAX_TRIES``: the run returns ``NONFINITE``.
    """
    if accept:
        stats[STAT_ACCEPTED] += 1
        return 0, False
    stats[STAT_REJECTED] += 1
    n_nonfinite = 0 if math.isfinite(err) else n_nonfinite + 1
    return n_nonfinite, n_nonfinite >= NONFINITE_MAX_TRIES


@njit(**_JIT)
def step_limit(h_max, span):
    """The largest step magnitude of a run over ``span``: `h_max` when it lies in ``(0, span]``,
    else ``span`` (``h_max <= 0``, inf or NaN mean no limit but the interval)."""
    return span if (not (h_max > 0.0) or h_max > span) else h_max


@njit(**_JIT)
def clip_to_end(t, habs, t_end, direction):
    """``(h, last)``: the signed trial step from `t`, and whether it is the run's last one.

    A step that would end within 1 % of its size before `t_end` is stretched onto it, as in
    Hairer's codes: the leftover sliver would trip the too-small test.
    """
    h = direction * habs
    last = (t + 1.01 * h - t_end) * direction >= 0.0
    if last:
        h = t_end - t
    return h, last


@njit(**_JIT_INLINE)
def first_step(fun, t0, y0, f0, args, direction, rtol, atol, h0, h_max, span, order, y1, f1,
               stats):
    """The first trial step's magnitude: `h0` (at most `h_max`) when positive, else
    :func:`initial_step` (its evaluation is counted in ``stats``); `y1`, `f1` are its scratch."""
    if h0 > 0.0:
        return min(h0, h_max)
    stats[STAT_FEV] += 1
    return initial_step(fun, t0, y0, f0, args, direction, rtol, atol, h_max, span, order, y1, f1)


@njit(**_JIT)
def initial_guess(y0, f0, atol, rtol):
    """The first estimate of ``HINIT`` [HNW93, II.4]: ``0.01 ||y0|| / ||f0||`` in :func:`rms_norm`.

    Parameters
    ----------
    y0, f0 : ndarray of float64, shape (n,)
        Initial state and ``f(t0, y0)``.
    atol : ndarray of float64, shape (n,)
        Absolute tolerance.
    rtol : float
        Relative tolerance.

    Returns
    -------
    h0 : float
        The estimate; ``1e-6`` where either norm is below ``1e-5`` or NaN.
    d1 : float
        ``||f0||``.
    """
    d0 = rms_norm(y0, y0, atol, rtol)
    d1 = rms_norm(f0, y0, atol, rtol)
    # Written as `not (...)` so that NaN norms fall into the cautious branch.
    if not (d0 >= 1e-5 and d1 >= 1e-5):
        return 1e-6, d1
    return 0.01 * d0 / d1, d1


@njit(**_JIT_INLINE)
def initial_step(fun, t0, y0, f0, args, direction, rtol, atol, h_max, span, order, y1, f1):
    """Hairer's ``HINIT`` [HNW93, II.4], in the form of scipy's ``select_initial_step``.

    From :func:`initial_guess`, an explicit Euler probe (one evaluation of `fun`) estimates the
    second derivative, and the step is sized so that the local error of order `order` meets
    the tolerance.

    Parameters
    ----------
    fun : numba-compiled callable
        ``fun(t, y, args, out)`` writes dy/dt into `out`.
    t0 : float
        Start time.
    y0, f0 : ndarray of float64, shape (n,)
        Initial state and ``fun(t0, y0)``.
    args : any numba-typed object
        Passed through to `fun`.
    direction : float
        +1.0 or -1.0, the direction of integration.
    rtol : float
        Relative tolerance.
    atol : ndarray of float64, shape (n,)
        Absolute tolerance.
    h_max, span : float
        Largest allowed step and ``|t_end - t0|``.
    order : int
        Order of the error estimator (the local error is ``O(h**(order + 1))``).
    y1, f1 : ndarray of float64, shape (n,)
        Scratch for the Euler probe (overwritten).

    Returns
    -------
    float
        The (positive) initial step size.
    """
    n = y0.shape[0]
    h0, d1 = initial_guess(y0, f0, atol, rtol)
    h0 = min(h0, span)
    for i in range(n):
        y1[i] = y0[i] + direction * h0 * f0[i]
    fun(t0 + direction * h0, y1, args, f1)
    for i in range(n):
        f1[i] -= f0[i]
    # The norm is taken in rms_norm, which is not inlined, so that a zero scale gives inf here
    # whatever the error model of the caller this kernel is inlined into.
    d2 = rms_norm(f1, y0, atol, rtol) / h0
    if not math.isfinite(d2):
        # The Euler probe already left the domain of f; let the integrator's non-finite
        # handling shrink from a cautious start.
        h1 = h0
    else:
        dmax = d1 if d1 > d2 else d2
        if dmax <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / dmax) ** (1.0 / (order + 1))
    return min(100.0 * h0, h1, span, h_max)
