"""The NetCDF encoding policy: one codec rule for every file, and files other readers open.

The readers are the ones a user meets first: netCDF-C's ``ncdump`` (Debian's 4.9.0 has no
Zstandard filter) and h5netcdf (h5py, no netCDF-C at all). Each reader test skips, saying why,
when that reader is not installed.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from cosserat_channel import cli, netcdf_policy
from cosserat_channel.sweep import run_sweep

SWEEP = {"grid": {"eps": {"logspace": [-3, -1, 8]}, "L": [2.0, 10.0], "K": {"linspace": [0, 3, 200]},
                  "A": [0.3333333333333333, 1.0], "N": [1.0, 1.5]},
         "output": {"variables": ["Delta", "slip", "m_wall"]}}


def test_codec_spellings():
    assert netcdf_policy.codec(True) == netcdf_policy.DEFAULT_CODEC == "zlib"
    assert netcdf_policy.codec(False) == netcdf_policy.codec(None) == "none"
    for name in ("zlib", "zstd", "none"):
        assert netcdf_policy.codec(name) == name
    for bad in ("gzip", 1, "ZLIB"):
        with pytest.raises(ValueError, match="zlib, zstd, none"):
            netcdf_policy.codec(bad)


def test_variable_encoding_rules():
    """Checksums on every array, no fill on coordinates and integers, NaN on float data, and a
    codec only on data arrays large enough to gain from it."""
    big, small = (10, 20, 30), (10, 10)
    e = netcdf_policy.variable_encoding(big, np.float64, chunks=(5, 10, 30))
    assert e == {"_FillValue": e["_FillValue"], "zlib": True, "complevel": 1, "shuffle": True,
                 "chunksizes": (5, 10, 30), "fletcher32": True}
    assert np.isnan(e["_FillValue"])
    e = netcdf_policy.variable_encoding(big, np.int8, compress="zstd")
    assert e == {"_FillValue": None, "compression": "zstd", "complevel": -1, "fletcher32": True}
    assert netcdf_policy.variable_encoding(small, np.float64)["fletcher32"]
    assert "zlib" not in netcdf_policy.variable_encoding(small, np.float64)
    coord = netcdf_policy.variable_encoding((5000,), np.float64, coordinate=True)
    assert coord == {"_FillValue": None, "fletcher32": True}
    scalar = netcdf_policy.variable_encoding((), np.float64)
    assert list(scalar) == ["_FillValue"] and np.isnan(scalar["_FillValue"])
    none = netcdf_policy.variable_encoding(big, np.float64, compress="none")
    assert "zlib" not in none and "compression" not in none and none["fletcher32"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A sweep result with the default codec, and a NetCDF subset of it written by query."""
    root = tmp_path_factory.mktemp("policy")
    result = root / "result.nc"
    run_sweep(SWEEP, result, workers=2).close()
    subset = root / "subset.nc"
    assert cli.main(["query", str(result), "--sel", "L=10", "--format", "netcdf", "-o",
                     str(subset)]) == 0
    return result, subset


def test_default_files_open_with_ncdump(files):
    """``ncdump -h`` (netCDF-C, any build) reads both files' headers and names the variables."""
    if shutil.which("ncdump") is None:
        pytest.skip("ncdump is not installed (Debian: apt-get install netcdf-bin)")
    for path in files:
        proc = subprocess.run(["ncdump", "-h", "-s", str(path)], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stderr
        assert "Delta" in proc.stdout and "status" in proc.stdout
        # zlib level 1 with shuffle and checksums; no Zstandard (HDF5 filter id 32015)
        for attribute in ('Delta:_DeflateLevel = 1', 'Delta:_Shuffle = "true"',
                          'Delta:_Fletcher32 = "true"'):
            assert attribute in proc.stdout, (path.name, attribute)
        assert "32015" not in proc.stdout
    # and reads the data itself: every value, through the filters
    proc = subprocess.run(["ncdump", "-v", "Delta", str(files[0])], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0 and "Delta =" in proc.stdout, proc.stderr


def test_default_files_open_with_h5netcdf(files):
    """xarray's h5netcdf engine (h5py, without netCDF-C) reads the values bit for bit."""
    pytest.importorskip("h5netcdf", reason="h5netcdf is not installed")
    pytest.importorskip("h5py", reason="h5py (h5netcdf's HDF5 library) is not installed")
    import xarray as xr

    for path in files:
        with xr.open_dataset(path, engine="h5netcdf") as a, \
                xr.open_dataset(path, engine="netcdf4") as b:
            for v in b.data_vars:
                assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v
