"""The residual figure of a fit: it draws the fit's own residuals and needs no solver."""

import pathlib

import numpy as np

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
    assert fig.axes[1].get_xlabel() == "fitted"


def test_plot_module_imports_no_solver():
    assert run_python("import sys, cosserat_channel.plot.fit; "
                      "print('numba' in sys.modules)") == "False"
