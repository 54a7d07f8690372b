"""The residual figure of a fit: it draws the fit's own residuals and needs no solver."""

import pathlib

import numpy as np
import pytest

import cosserat_channel
from cosserat_channel.calibrate import fit
from support import run_python

EXAMPLES = pathlib.Path(cosserat_channel.__file__).parent / "examples"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_residual_figure_draws_the_residuals(tmp_path):
    r = fit(EXAMPLES / "fit_profile.csv", "L,K", {"A": 1 / 3, "N": 1})
    path = tmp_path / "res.png"
    fig = r.plot(path)
    assert path.read_bytes().startswith(PNG_SIGNATURE)
    ax_r, ax_m = fig.axes[:2]
    drawn = np.concatenate([line.get_ydata() for line in ax_r.lines if line.get_marker() == "o"])
    np.testing.assert_array_equal(np.sort(drawn), np.sort(r.residuals))
    assert ax_m.get_xlabel().startswith("cross-channel position")


def test_scalar_fit_draws_measured_against_fitted(tmp_path):
    r = fit(EXAMPLES / "fit_table1.csv", "delta_w,Lambda,L", {"K": 0.5, "A": 1 / 3},
            start={"delta_w": 8.0})
    fig = r.plot(tmp_path / "t.png")
    ax_m = fig.axes[1]
    assert ax_m.get_ylabel() == "measured / fitted"
    # one point per row, each its measured value over its fitted one
    drawn = np.concatenate([line.get_ydata() for line in ax_m.lines if line.get_marker() == "o"])
    np.testing.assert_allclose(np.sort(drawn), np.sort(r.data.value / r.predictions), rtol=1e-14)


def test_plot_module_imports_no_solver():
    assert run_python("import sys, cosserat_channel.plot.fit; "
                      "print('numba' in sys.modules)") == "False"


def _result(estimates, covariance, names=("A", "N")):
    """A FitResult with the given estimates and covariance (the rest is not drawn)."""
    from cosserat_channel.calibrate import FitResult

    cov = np.asarray(covariance, dtype=float)
    se = np.sqrt(np.diag(cov))
    return FitResult(names=tuple(names), estimates=np.asarray(estimates, dtype=float),
                     std_errors=se, covariance=cov, correlation=cov / np.outer(se, se), chi2=0.0,
                     dof=1, residuals=np.zeros(0), predictions=np.zeros(0), status=[], data=None,
                     fixed={}, bounds={}, start=np.zeros(2), condition_number=1.0,
                     jacobian=np.zeros((0, 2)), jacobian_method="central differences",
                     success=True, message="", n_evaluations=0, n_solves=0)


def test_confidence_ellipse_is_the_chi2_contour():
    """Every point of the 95 % ellipse is at d^T C^-1 d = -2 ln(0.05) (C inverted here
    independently); its area is pi q sqrt(det C); the Mahalanobis distance of a point one
    standard error along an uncorrelated axis is 1."""
    cov = [[0.04, 0.018], [0.018, 0.01]]
    r = _result([0.3, 1.0], cov)
    ex, ey = r.ellipse("A", "N", 0.95, n=2001)
    d = np.stack([ex - 0.3, ey - 1.0])
    q = np.einsum("ik,ij,jk->k", d, np.linalg.inv(cov), d)
    np.testing.assert_allclose(q, -2 * np.log(0.05), rtol=1e-12)
    area = 0.5 * abs(np.dot(ex[:-1], ey[1:]) - np.dot(ey[:-1], ex[1:]))
    exact = np.pi * -2 * np.log(0.05) * np.sqrt(np.linalg.det(cov))
    assert abs(area - exact) < 1e-5 * exact  # polygon of 2000 sides: 1 - sin(x)/x ~ 1.6e-6
    np.testing.assert_allclose(r.mahalanobis("A", "N", ex, ey), np.sqrt(-2 * np.log(0.05)),
                               rtol=1e-12)
    diag = _result([0.3, 1.0], [[0.04, 0.0], [0.0, 0.01]])
    np.testing.assert_allclose(diag.mahalanobis("A", "N", [0.5, 0.3], [1.0, 0.9]), [1.0, 1.0],
                               rtol=1e-14)
    with pytest.raises(ValueError, match="'K' is not a free parameter"):
        r.ellipse("A", "K")
    with pytest.raises(ValueError, match="level must be in"):
        r.ellipse("A", "N", 1.0)


def test_confidence_region_figure_draws_the_regions_over_the_statuses(tmp_path):
    """The ellipses drawn are the fit's own; each status without a solution is in the legend;
    the distance in the title is that of the nearest node without a solution, found here by
    brute force with C inverted independently; the grid's shape is checked."""
    from cosserat_channel.plot.fit import confidence_region_figure

    cov = np.array([[0.04, 0.018], [0.018, 0.01]])
    r = _result([0.3, 1.0], cov)
    A = np.linspace(-1.0, 1.0, 41)
    N = np.linspace(0.6, 1.4, 33)
    AA, NN = np.meshgrid(A, N, indexing="ij")
    codes = np.zeros(AA.shape, dtype=np.int8)
    codes[AA < 1 - 2 * NN**2] = 1  # wall_inadmissible
    codes[(AA > 0.8) & (NN > 1.3)] = 3  # eps_too_large_path
    codes[(AA > 0.8) & (NN < 0.7)] = -1  # undecided
    path = tmp_path / "ci.png"
    fig = confidence_region_figure(r, "A", "N", (A, N, codes), truth=(1 / 3, 1.0),
                                   title="eps L = 1/3", path=path)
    assert path.read_bytes().startswith(PNG_SIGNATURE)
    ax = fig.axes[0]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    for label in ("no solution: wall_inadmissible", "no solution: eps_too_large_path",
                  "undecided (a solve would decide)", "95% confidence region",
                  "68% confidence region", "edge of the solvable region", "truth"):
        assert label in legend, legend
    drawn = [line for line in ax.lines if line.get_label() == "95% confidence region"][0]
    np.testing.assert_allclose(drawn.get_xdata(), r.ellipse("A", "N", 0.95)[0])
    bad = codes > 0
    d = np.stack([AA[bad] - 0.3, NN[bad] - 1.0])
    nearest = np.sqrt(np.min(np.einsum("ik,ij,jk->k", d, np.linalg.inv(cov), d)))
    assert f"nearest node without a solution: {nearest:.3g} standard deviations" in \
        fig._suptitle.get_text()
    with pytest.raises(ValueError, match="region: codes have shape"):
        confidence_region_figure(r, "A", "N", (A, N, codes.T))
