"""Assertions shared by the sweep-store and fault-injection tests."""

import numpy as np
import xarray as xr


def assert_identical(path, ds):
    """The result file at ``path`` holds exactly the variables and values of ``ds`` (NaN = NaN)."""
    with xr.open_dataset(path) as f:
        f.load()
        assert set(f.data_vars) == set(ds.data_vars)
        for v in ds.data_vars:
            assert np.array_equal(f[v].values, ds[v].values, equal_nan=True), v
