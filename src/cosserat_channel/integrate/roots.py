"""The one bracketing root finder of the package, written for Numba.

:func:`find_root` solves ``f(x, args) = 0`` on a bracket ``[a, b]`` with ``f(a)`` and ``f(b)``
of opposite signs: Illinois-modified regula falsi [DB71], safeguarded by a bisection step
whenever two consecutive iterations have not halved the bracket. Regula falsi alone converges
superlinearly on smooth simple roots but can stall with one end fixed (convex ``f``, kinks,
multiple roots); the Illinois weight halving removes most stalls and the bisection safeguard
bounds the rest, so the bracket shrinks by at least a factor two every three evaluations.

Users: event location on a dense output (:func:`.dense.locate_event`).

:func:`newton_root` is the same kind of bracketed search for a function whose derivative comes
almost free with its value: Newton's step, replaced by bisection whenever it would leave the
bracket or not halve it (``rtsafe`` of [NR07]). :func:`newton_root_d2` also takes the second
derivative and stops as soon as the curvature predicts the step's error below the tolerance, which
saves the evaluation that would only confirm convergence. It finds the plug edge of
:mod:`cosserat_channel.solver.plug_edge`: on a stage-2 panel's Chebyshev series, from the inverse
Hermite cubic through the panel's ends, and where stage 2 is closed form, from a quintic Hermite of
the root over the levels eq:13 can ask for: 1-2 evaluations either way.

The kernel receives ``f`` as an argument and is therefore ``inline="always"``: a jitted caller
that passes a global ``@njit`` function then calls it directly and stays cacheable (see
:mod:`.rk45`). ``f`` must be a Numba-compiled function ``f(x, args) -> float``; ``args`` is any
Numba-typed value (typically a tuple of floats and arrays), passed through untouched.

References
----------
.. [DB71] M. Dowell and P. Jarratt, "A modified regula falsi method for computing the root of
   an equation", BIT 11, 168-174 (1971).
.. [NR07] W. H. Press et al., Numerical Recipes, 3rd ed., section 9.4 (``rtsafe``).
"""

from __future__ import annotations

import math

from numba import njit
from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE

__all__ = ["find_root", "newton_root", "newton_root_d2"]


@njit(**_JIT_INLINE)
def find_root(f, args, a, b, fa, fb, tol, max_iter):
    """Root of ``f(x, args)`` in the bracket between `a` and `b`.

    Parameters
    ----------
    f : numba-compiled callable
        ``f(x, args) -> float``.
    args : any numba-typed object
        Passed untouched to `f`.
    a, b : float
        Bracket ends, in either order (``b < a`` is allowed).
    fa, fb : float
        ``f(a, args)`` and ``f(b, args)``, of opposite signs or one of them zero.
    tol : float
        Absolute tolerance on `x`: the iteration stops once the bracket is at most `tol` wide.
        Trial points stay at least ``tol/2`` inside the bracket, so each evaluation shrinks it
        by a resolvable amount.
    max_iter : int
        Budget of evaluations of `f`.

    Returns
    -------
    x : float
        A point where `f` is exactly zero, or else the end of the final bracket with the
        smaller ``|f|``.
    n_eval : int
        Evaluations of `f` made; ``n_eval == max_iter`` means the budget ran out (the final
        bracket may then be wider than `tol`).
    """
    if fa == 0.0:
        return a, 0
    if fb == 0.0:
        return b, 0
    h = b - a
    s = 1.0 if h > 0.0 else -1.0
    # Illinois weights act on copies so that the true values stay available for choosing the
    # returned end point.
    wa = fa
    wb = fb
    side = 0
    # Bracket widths one and two iterations ago, for the bisection safeguard.
    w1 = abs(h)
    w2 = abs(h)
    n_eval = 0
    for it in range(max_iter):
        width = abs(b - a)
        if width <= tol:
            break
        if it >= 2 and width > 0.5 * w2:
            c = 0.5 * (a + b)
        else:
            c = b - wb * (b - a) / (wb - wa)
            # Also catches wb == wa (c = inf or NaN) and round-off landing on an end.
            if not ((c - a) * s > 0.0 and (b - c) * s > 0.0):
                c = 0.5 * (a + b)
        half = 0.5 * tol
        if abs(c - a) < half:
            c = a + s * half
        elif abs(b - c) < half:
            c = b - s * half
        w2 = w1
        w1 = width
        fc = f(c, args)
        n_eval += 1
        if fc == 0.0:
            return c, n_eval
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
        return a, n_eval
    return b, n_eval


@njit(**_JIT)
def _newton_start(a, b, fa, fb, x0):
    """``(at_end, lo, hi, x, width)`` of a safeguarded Newton search: whether `a` or `b` is
    already a root (then it is `x`), the bracket's ends with ``f(lo) < 0 < f(hi)``, the first
    iterate (`x0`, or the midpoint when `x0` is not inside) and the bracket's width."""
    lo, hi = (a, b) if fa < 0.0 else (b, a)
    left, right = min(a, b), max(a, b)
    x = x0 if left < x0 < right else 0.5 * (a + b)
    if fa == 0.0:
        x = a
    elif fb == 0.0:
        x = b
    return fa == 0.0 or fb == 0.0, lo, hi, x, right - left


@njit(**_JIT)
def _narrow(x, f, lo, hi):
    # The bracket (lo, hi), f(lo) < 0 < f(hi), with the iterate x in place of the end of f's sign.
    return (x, hi) if f < 0.0 else (lo, x)


@njit(**_JIT)
def _needs_bisection(x_new, lo, hi, f, df, dx_old):
    # The Newton iterate left the bracket, or the step did not halve against the one before.
    return not (min(lo, hi) < x_new < max(lo, hi)) or abs(2.0 * f) > abs(dx_old * df)


@njit(**_JIT_INLINE)
def newton_root(fdf, args, a, b, fa, fb, x0, tol, max_iter):
    """Root of ``f`` in the bracket between `a` and `b` by safeguarded Newton steps from `x0`.

    Parameters
    ----------
    fdf : numba-compiled callable
        ``fdf(x, args) -> (f, df/dx)``.
    args : any numba-typed object
        Passed untouched to `fdf`.
    a, b, fa, fb : float
        As for :func:`find_root`.
    x0 : float
        First iterate; the midpoint is used when it is not inside the bracket.
    tol : float
        Absolute tolerance on `x`: stops once a step is at most `tol`.
    max_iter : int
        Budget of evaluations of `fdf`.

    Returns
    -------
    x : float
    n_eval : int
        Evaluations made; ``n_eval == max_iter`` means the budget ran out.
    """
    at_end, lo, hi, x, dx_old = _newton_start(a, b, fa, fb, x0)
    if at_end:
        return x, 0
    dx = dx_old
    for it in range(max_iter):
        f, df = fdf(x, args)
        if f == 0.0:
            return x, it + 1
        lo, hi = _narrow(x, f, lo, hi)
        x_new = x - f / df if df != 0.0 else math.nan
        if abs(x_new - x) <= tol:
            # Converged, also when the step is below the resolution of x (x_new == x == one end
            # of the bracket, which the test below would take for a step outside it and bisect).
            return x_new, it + 1
        if _needs_bisection(x_new, lo, hi, f, df, dx_old):
            dx_old = dx
            dx = 0.5 * (hi - lo)
            x_new = lo + dx
        else:
            dx_old = dx
            dx = x - x_new
        if abs(x_new - x) <= tol:
            return x_new, it + 1
        x = x_new
    return x, max_iter


@njit(**_JIT_INLINE)
def newton_root_d2(fdf, args, a, b, fa, fb, x0, tol, max_iter, curvature_stop=True):
    """:func:`newton_root` for an ``fdf(x, args) -> (f, df/dx, d2f/dx2)``, which also stops once
    the error that Newton's step leaves, ``|f''/(2 f')| step^2``, is predicted below `tol`.

    The curvature term is the leading error of a Newton iterate, so the evaluation that would
    only confirm a step below `tol` is saved: from a start within ``~sqrt(tol)`` one evaluation
    suffices, from one within ``~tol^(1/4)`` two. A step that the safeguard replaces by bisection
    never stops the search. Where ``f`` carries rounding noise far above ``tol / |f'|`` that
    prediction is void (the step is as noisy as ``f``): ``curvature_stop=False`` then stops as
    :func:`newton_root` does, once Newton and bisection steps have shrunk the bracket around a
    sign change of ``f``.
    """
    at_end, lo, hi, x, dx_old = _newton_start(a, b, fa, fb, x0)
    if at_end:
        return x, 0
    dx = dx_old
    for it in range(max_iter):
        f, df, d2f = fdf(x, args)
        if f == 0.0:
            return x, it + 1
        lo, hi = _narrow(x, f, lo, hi)
        step = -f / df if df != 0.0 else math.nan
        x_new = x + step
        if abs(step) <= tol:
            return x_new, it + 1
        if _needs_bisection(x_new, lo, hi, f, df, dx_old):
            dx_old = dx
            dx = 0.5 * (hi - lo)
            x_new = lo + dx
            if abs(x_new - x) <= tol:
                return x_new, it + 1
        else:
            dx_old = dx
            dx = -step
            if curvature_stop and abs(0.5 * d2f / df) * step * step <= tol:
                return x_new, it + 1
        x = x_new
    return x, max_iter
