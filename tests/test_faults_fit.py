"""What scipy or numpy raise after the optimiser ends is one FitError line, and a row whose
derivative is not finite at the estimate is left out of the covariance with a warning, never a
traceback (a NaN Jacobian row made the SVD fail)."""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_channel.calibrate import FitError, FitWarning, estimate, fit


@pytest.fixture(scope="module")
def data():
    from cosserat_channel import solve_point

    eps = (0.01, 0.02, 0.05)
    return {"quantity": ["Delta"] * 3, "eps": list(eps), "std_error": [0.05] * 3,
            "value": [solve_point(e, 10.0, 5.0, 1 / 3, 1.0).Delta for e in eps]}


def test_a_row_without_a_finite_derivative_at_the_estimate_is_a_warning(data, monkeypatch):
    real = estimate.jacobian

    def nan_row(problem, x, base=None):
        J, info = real(problem, x, base)
        J = J.copy()
        J[0] = np.nan
        return J, info

    monkeypatch.setattr(estimate, "jacobian", nan_row)
    with pytest.warns(FitWarning, match="1 rows have no finite derivative"):
        r = fit(data, "L", {"K": 5.0, "A": 1 / 3, "N": 1.0})
    assert abs(r.params["L"] - 10.0) < 1e-3
    assert np.isfinite(r.errors["L"]) and r.errors["L"] > 0


def test_a_covariance_numpy_cannot_make_is_one_fit_error(data, monkeypatch):
    def failing(J):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(estimate, "_covariance", failing)
    with pytest.raises(FitError) as err:
        fit(data, "L", {"K": 5.0, "A": 1 / 3, "N": 1.0})
    assert "\n" not in str(err.value) and "SVD did not converge" in str(err.value)
