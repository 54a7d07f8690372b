"""Tests for the root finders of ``cosserat_channel.integrate.roots``: safeguarded Illinois and Newton."""

import math

import numpy as np
import pytest
from numba import njit

from cosserat_channel.integrate.dense import component_minus_level
from cosserat_channel.integrate.rk45 import integrate
from cosserat_channel.integrate.stepping import SUCCESS
from cosserat_channel.integrate.roots import find_root, newton_root


# ---------------------------------------------------------------------------
# Functions f(x, args) (module level so that Numba can cache them)
# ---------------------------------------------------------------------------
@njit(cache=True)
def square_minus(x, args):
    # x^2 - c, times a sign so that both orderings of f(a), f(b) can be tested.
    c, sign = args
    return sign * (x * x - c)


@njit(cache=True)
def cos_minus_x(x, args):
    return math.cos(x) - x


@njit(cache=True)
def triple_root(x, args):
    # A root of multiplicity three: plain regula falsi keeps one end fixed and crawls.
    r = args[0]
    return (x - r) ** 3


@njit(cache=True)
def kink(x, args):
    # Slope 1e-6 left of the root, 1 right of it: Illinois alone needs ~150 evaluations here.
    r = args[0]
    return (x - r) * (1e-6 if x < r else 1.0)


@njit(cache=True)
def plug_edge_root(T, Q, nsteps, target, out, tol):
    # The plug-edge problem of solve.one_minus_xi_p: J = component 1 of a dense output that
    # runs from t = 0 downwards, with J increasing; J(t) = target on a bracket of step ends.
    lo = 0
    hi = nsteps
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if component_minus_level(T[mid], (T, Q, nsteps, 1, target, out)) < 0.0:
            lo = mid
        else:
            hi = mid
    packed = (T, Q, nsteps, 1, target, out)
    a = T[lo]
    b = T[hi]
    fa = component_minus_level(a, packed)
    fb = component_minus_level(b, packed)
    return find_root(component_minus_level, packed, a, b, fa, fb, tol, 100)


@njit(cache=True)
def square_minus_d(x, args):
    c, sign = args
    return sign * (x * x - c), sign * 2.0 * x


@njit(cache=True)
def arctan_d(x, args):
    # Newton from far out overshoots and diverges on arctan: the safeguard must bisect.
    return math.atan(x - args[0]), 1.0 / (1.0 + (x - args[0]) ** 2)


@njit(cache=True)
def newton(f, args, a, b, x0, tol, n):
    return newton_root(f, args, a, b, f(a, args)[0], f(b, args)[0], x0, tol, n)


@njit(cache=True)
def stage2_like(t, y, args, out):
    # (log omega, J) with J = 1 - exp(t): J(0) = 0, increasing towards 1 as t decreases.
    out[0] = 2.0
    out[1] = y[1] - 1.0


def halving_bound(width, tol):
    """Evaluations after which the safeguard guarantees a bracket of at most `tol`.

    The bracket at least halves every three evaluations (a bisection follows two iterations
    that did not halve it), plus the two start-up iterations.
    """
    return 3 * math.ceil(math.log2(width / tol)) + 3


# ---------------------------------------------------------------------------
# Closed-form roots
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("reverse", [False, True])
def test_sqrt2_all_sign_and_bracket_orders(sign, reverse):
    """x^2 = 2 is solved to 1e-15 whichever sign f(a) has and whichever end comes first."""
    a, b = (2.0, 0.0) if reverse else (0.0, 2.0)
    args = (2.0, sign)
    x, n = find_root(square_minus, args, a, b, square_minus(a, args), square_minus(b, args),
                     1e-15, 100)
    assert x == pytest.approx(math.sqrt(2.0), abs=2e-15)
    assert n <= 12  # superlinear on a smooth simple root


def test_cos_minus_x():
    """cos x = x (the Dottie number) is found to the tolerance."""
    x, n = find_root(cos_minus_x, (), 0.0, 1.0, 1.0, math.cos(1.0) - 1.0, 1e-14, 100)
    assert x == pytest.approx(0.7390851332151607, abs=1e-14)
    assert 0 < n <= 12


def test_exact_zero_at_an_end_is_returned_without_iterating():
    """f(a) == 0 or f(b) == 0 returns that end with no evaluation."""
    assert find_root(cos_minus_x, (), 3.0, 1.0, 0.0, -1.0, 1e-14, 100) == (3.0, 0)
    assert find_root(cos_minus_x, (), 3.0, 1.0, 1.0, 0.0, 1e-14, 100) == (1.0, 0)


def test_exact_zero_at_a_trial_point_stops():
    """A trial point where f is exactly zero is returned at once."""
    # x^2 - 1 on [0, 2]: the first secant point is (0*3 - 2*(-1))/(3 + 1) = 0.5, then 1 is hit
    # exactly at some trial (1 is exactly representable and every iterate is a dyadic).
    x, n = find_root(square_minus, (1.0, 1.0), 0.0, 2.0, -1.0, 3.0, 0.0, 200)
    assert x == 1.0
    assert n < 200


# ---------------------------------------------------------------------------
# Where plain regula falsi stalls
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("f, r", [(triple_root, 1 / 3), (kink, 0.3)])
def test_stalling_functions_converge_within_the_halving_bound(f, r):
    """A triple root and a kinked f converge in at most 3 evaluations per halving."""
    tol = 1e-12
    a, b = 0.0, 2.0 if f is triple_root else 1.0
    x, n = find_root(f, (r,), a, b, f(a, (r,)), f(b, (r,)), tol, 10_000)
    assert abs(x - r) <= tol
    # Plain regula falsi needs > 10000 evaluations on both; Illinois alone ~150 on the kink.
    assert n <= halving_bound(b - a, tol)


def test_budget_exhaustion_is_reported():
    """With too small a budget n_eval == max_iter and the result still lies in the bracket."""
    x, n = find_root(triple_root, (1 / 3,), 0.0, 2.0, -1 / 27, (5 / 3) ** 3, 1e-15, 5)
    assert n == 5
    assert 0.0 <= x <= 2.0


# ---------------------------------------------------------------------------
# The plug-edge problem: a level crossing on a dopri5 dense output
# ---------------------------------------------------------------------------
def test_plug_edge_level_crossing_on_dense_output():
    """J(t) = 3/4 with J = 1 - exp(t) from a backward dopri5 run: t = ln(1/4) to 1e-9."""
    s = integrate(stage2_like, 0.0, [0.0, 0.0], -10.0, rtol=1e-10, atol=1e-12)
    assert s.status == SUCCESS
    out = np.empty(2)
    target = 0.75
    x, n = plug_edge_root(s.T, s.Q, s.nsteps, target, out, 1e-15)
    assert x == pytest.approx(math.log(0.25), abs=1e-9)
    # The root of the interpolant itself is resolved to round-off, in few evaluations.
    assert abs(component_minus_level(x, (s.T, s.Q, s.nsteps, 1, target, out))) <= 1e-15
    assert 0 < n <= 10


def test_jitted_caller_stays_cacheable():
    """A jitted caller passing a global f to find_root has no uncacheable dynamic globals."""
    s = integrate(stage2_like, 0.0, [0.0, 0.0], -10.0, rtol=1e-8, atol=1e-10)
    plug_edge_root(s.T, s.Q, s.nsteps, 0.5, np.empty(2), 1e-15)
    (cres,) = plug_edge_root.overloads.values()
    assert not cres.library.has_dynamic_globals


# ---------------------------------------------------------------------------
# Safeguarded Newton
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("x0", [1.4, 1.0, 3.0, -5.0])
def test_newton_sqrt2_converges_quadratically_from_inside(sign, x0):
    """From a start inside the bracket (or outside: the midpoint), sqrt(2) to round-off; from 1.4
    in a few evaluations, as Newton's quadratic convergence allows."""
    x, n = newton(square_minus_d, (2.0, sign), 0.0, 3.0, x0, 1e-15, 100)
    assert x == pytest.approx(math.sqrt(2.0), abs=4e-16)
    if x0 == 1.4:
        assert n <= 5


def test_newton_safeguard_bisects_where_newton_diverges():
    """arctan from 10 units away: plain Newton diverges; the safeguarded search still converges."""
    x, n = newton(arctan_d, (0.3,), -20.0, 30.0, 25.0, 1e-14, 200)
    assert x == pytest.approx(0.3, abs=1e-13)
    assert n < 100
