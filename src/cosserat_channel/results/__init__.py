"""Reading result files: selection, filtering and description of a sweep's NetCDF output.

Layer: beside the solver, not above it: reading a result never imports numba or compiles a
kernel. :mod:`.flags` decodes the CF flag variables (status, edge kinds) every other module
reads; :mod:`.selection` parses the clauses of a query and selects the points;
:mod:`.render` writes them as a table, CSV, JSON or a NetCDF subset; :mod:`.describe` is what
``info`` says of a file; :mod:`.light` reads a small query through netCDF4 alone.

May import: numpy, xarray, netCDF4, dask, :mod:`cosserat_channel.files` and the vocabulary
modules (parameters, status, outputs, netcdf_policy), and :mod:`cosserat_channel.plot` inside
the accessor's plotting methods. Never the solver, the physics or the integrators.
"""
