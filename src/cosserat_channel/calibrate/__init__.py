"""Calibration: fit the model's inputs to measurements by weighted least squares.

:func:`fit` takes a table of measurements (:func:`read_data`: a CSV file, a mapping of columns or
an xarray Dataset) and the inputs to fit, and returns a :class:`FitResult` (estimates, standard
errors, covariance, chi^2/dof, residuals, ``.plot()``). ``data`` reads and checks the table
(numpy only), ``model`` maps the free inputs to each row's point and prediction and holds the
one Jacobian function, ``estimate`` runs :func:`scipy.optimize.least_squares`.

Layer: above the solver and the sweeps (:mod:`cosserat_channel.sweep.arrays` solves the rows);
below the command line. May import :mod:`cosserat_channel.plot` (``FitResult.plot``) and the
vocabulary modules (parameters, status, outputs); never the regimes, the atlas or the CLI.
"""

from .data import CSV_EXAMPLE, DataError, Measurements, read_data
from .estimate import FitResult, FitWarning, fit
from .model import FitError

__all__ = ["fit", "FitResult", "FitError", "FitWarning", "DataError", "Measurements", "read_data",
           "CSV_EXAMPLE"]
