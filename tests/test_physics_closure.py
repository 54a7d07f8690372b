"""The critical-state closure (eq:24) and the wall-friction condition for nu (eq:35)."""

import numpy as np
import pytest

from cosserat_channel.physics import closure
from cosserat_channel.parameters import check_material

RNG = np.random.default_rng(35)
PAPER = check_material({"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0})  # eq:24's constants by default


def test_defaults_are_the_papers_closure():
    """The closure's defaults are the paper's: Lambda 817 Pa, nu 0.5..0.65, p 2.5, q 2.2."""
    assert (PAPER["Lambda"], PAPER["nu_min"], PAPER["nu_max"], PAPER["p"], PAPER["q"]) == (
        817.0, 0.5, 0.65, 2.5, 2.2)


def test_sigma_c_closed_form():
    """sigma_c = Lambda (nu - nu_min)^p / (nu_max - nu)^q, and 0 at or below nu_min."""
    assert closure.sigma_c(0.6, PAPER) == pytest.approx(817.0 * 0.1**2.5 / 0.05**2.2, rel=1e-13)
    assert closure.sigma_c(0.5, PAPER) == 0.0
    assert closure.sigma_c(0.4, PAPER) == 0.0


def test_solids_fraction_root_is_unique_and_solves_eq35():
    """eq:35 has one root in (nu_min, nu_max); the bisection finds it to round-off."""
    for _ in range(200):
        rho_g_W = 10 ** RNG.uniform(1, 6)
        tan_delta = 10 ** RNG.uniform(-2, 1)
        nu = closure.solids_fraction(rho_g_W, tan_delta, PAPER)
        assert 0.5 < nu < 0.65
        lhs = rho_g_W * nu
        rhs = tan_delta * closure.sigma_c(nu, PAPER)
        assert rhs == pytest.approx(lhs, rel=1e-9)
        grid = np.linspace(0.5 + 1e-9, 0.65 - 1e-9, 2001)
        resid = np.array([tan_delta * closure.sigma_c(v, PAPER) - rho_g_W * v for v in grid])
        assert np.count_nonzero(np.diff(np.sign(resid)) != 0) == 1


def test_solids_fraction_of_an_overflowing_channel_is_nan():
    """A channel so wide that rho_p g W overflows has no finite nu: NaN, not a wrong number."""
    assert np.isnan(closure.solids_fraction(float("inf"), 0.5, PAPER))
