"""panels: the Chebyshev-panel nested quadrature against closed forms and scipy quad."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from cosserat_channel.integrate import panels


def _panel(f, g, a, b, y_b=0.0, J_b=0.0):
    r = 0.5 * (b - a)
    x = 0.5 * (a + b) + r * panels.X
    Q = np.zeros((1, panels.N_ROWS, 2))
    y = np.empty(panels.N_NODES)
    err = panels.integrate_panel(f(x), g(x), y_b, J_b, r, Q, 0, y)
    return Q, y, err, r


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")  # quad at 1e-15
@pytest.mark.parametrize("a, b", [(0.3, 0.7), (-1.0, 0.0), (0.9, 1.0)])
def test_nested_integrals_against_closed_form_and_quad(a, b):
    """y = y_b - int_x^b cos, J = J_b + int_x^b exp(y): to round-off on a panel where the
    integrands are entire and the panel is short; the estimates bound the errors."""
    y_b, J_b = 0.5, 0.1
    Q, y_nodes, (err_y, err_J), r = _panel(np.cos, np.ones_like, a, b, y_b, J_b)
    x = 0.5 * (a + b) + r * panels.X

    def y_exact(t):
        return y_b - (math.sin(b) - math.sin(t))

    assert np.allclose(y_nodes, [y_exact(t) for t in x], rtol=0, atol=err_y + 1e-15)
    for u in (0.0, 1e-3, 0.3, 1.0, 1.7, 2.0):
        t = b - r * u
        J_ref = J_b + quad(lambda s: math.exp(y_exact(s)), t, b, epsabs=1e-16, epsrel=1e-15)[0]
        assert panels.panel_value(Q, 0, 0, u) == pytest.approx(y_exact(t), abs=err_y + 1e-15)
        # an estimate, not a bound: within 2x of it
        assert panels.panel_value(Q, 0, 1, u) == pytest.approx(J_ref, abs=2 * err_J + 1e-15)
        value, slope = panels.panel_value_d(Q, 0, 1, u)
        assert value == panels.panel_value(Q, 0, 1, u)
        # dJ/du = r exp(y) (J grows away from the upper end)
        assert slope == pytest.approx(r * math.exp(y_exact(t)), rel=1e-8)
    # a unit panel resolves cos to ~1e-11 at degree 8, a short one to round-off
    assert err_y < (1e-10 if b - a == 1.0 else 1e-14) and err_J < (1e-8 if b - a == 1.0 else 1e-10)


def test_error_estimate_bounds_the_error_where_it_is_not_negligible():
    """Where the degree does not resolve the integrand (poles near the panel) the estimate is
    above the true error, and not by orders of magnitude."""
    def f(x):
        return 1.0 / (1.0 + 25.0 * x * x)  # Runge: poles at +-i/5

    for a, b in ((-1.0, 1.0), (0.0, 1.0), (0.5, 1.0), (0.75, 1.0)):
        Q, _, (err_y, _), r = _panel(f, np.ones_like, a, b)
        exact = -(math.atan(5 * b) - math.atan(5 * a)) / 5
        true = abs(panels.panel_value(Q, 0, 0, 2.0) - exact)
        if b - a == 2.0:
            # slow decay (Bernstein radius 1.22): the extrapolation is rough but of the right size;
            # the march rejects such a panel by orders of magnitude either way
            assert 0.3 * true < err_y
        else:
            assert true <= err_y < 1e4 * max(true, 1e-16)


def test_increment_keeps_relative_precision_at_the_upper_end():
    """J - J_b at u down to 1e-14 is right to a few ulps: the difference recurrence, where a
    Chebyshev sum at x = 1 - u would lose everything below u ~ 1e-8."""
    a, b = 0.3, 0.7
    Q, _, _, r = _panel(np.cos, np.ones_like, a, b, 0.5, 0.0)
    for u in (1e-14, 1e-11, 1e-8, 1e-5):
        h = r * u
        ref = math.exp(0.5) * h * (1 - 0.5 * math.cos(b) * h)  # int_{b-h}^b exp(y), to O(h^3)
        assert panels.panel_value(Q, 0, 1, u) == pytest.approx(ref, rel=1e-15)
    assert panels.panel_value(Q, 0, 1, 0.0) == 0.0


def test_error_factor_is_bounded_and_monotone():
    assert panels.panel_error_factor(0.0, 1.0) == 4.0
    assert panels.panel_error_factor(1e6, 1.0) == 0.2
    fs = [panels.panel_error_factor(e, 1.0) for e in (1e-6, 1e-3, 1.0, 10.0)]
    assert fs == sorted(fs, reverse=True)


def test_partial_integrates_the_interpolant_between_the_nodes():
    from cosserat_channel.integrate.panels import DEGREE, X, cumulative, partial

    # a polynomial of degree DEGREE is its own interpolant: r int_(1-u)^1 is exact
    c = np.random.default_rng(1).normal(size=DEGREE + 1)
    v = np.polynomial.polynomial.polyval(X, c)
    prim = np.polynomial.polynomial.polyint(c)
    r = 0.37
    for u in (0.0, 1e-9, 0.3, 1.0, 1.7, 2.0):
        exact = r * (np.polynomial.polynomial.polyval(1.0, prim)
                     - np.polynomial.polynomial.polyval(1.0 - u, prim))
        assert abs(partial(v, r, u) - exact) <= 64 * np.finfo(float).eps * r * np.abs(c).sum()
    out = np.empty(DEGREE + 1)
    cumulative(v, r, out)
    for j, x in enumerate(X):
        assert abs(partial(v, r, 1.0 - x) - out[j]) <= 64 * np.finfo(float).eps * r * np.abs(c).sum()
