"""Reading result files: selection, filtering and description of a sweep's NetCDF output.

Layer: beside the solver, not above it: reading a result never imports numba or compiles a
kernel. :mod:`.query` parses selections, reads through netCDF4 directly where it can and
renders tables.

May import: numpy, xarray, netCDF4, dask, :mod:`cosserat_channel.files` and the vocabulary
modules (parameters, status, outputs). Never the solver or the integrators.
"""
