"""``info`` on a NetCDF file that is no file of the tool says what it is (its title, dimensions,
variables) and why it is refused (what it lacks of the kind it comes near), in one line: a
crafted atlas that declares 2^27 leaves and holds none of an atlas's variables was only "not a
cosserat-channel result file"."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cosserat_channel import cli


def _info(capsys, path):
    code = cli.main(["info", str(path)])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0]
    return lines[0]


def test_a_crafted_atlas_is_named_and_what_it_lacks_said(tmp_path, capsys):
    import netCDF4

    path = tmp_path / "bomb.nc"
    with netCDF4.Dataset(path, "w") as d:
        d.setncatts({"title": "cosserat-channel solvability atlas", "max_depth": 8})
        d.createDimension("leaf", 1 << 27)
        d.createVariable("leaf_error", "f8", ("leaf",), zlib=True, chunksizes=(1 << 20,))
    assert path.stat().st_size < 1_000_000  # declared, never written
    line = _info(capsys, path)
    assert "titled 'cosserat-channel solvability atlas'" in line
    assert "dimensions leaf (134,217,728) and variables leaf_error" in line
    assert "as an atlas it lacks leaf_coefficients and sample_A" in line


@pytest.mark.parametrize("ds, words", [
    (xr.Dataset({"a": ("x", [1.0])}),
     "a NetCDF file with dimensions x (1) and variables a; it has none of the variables of a "
     "result (status), a boundary (eta_max, edge_kind) or an atlas (leaf_coefficients, "
     "sample_A)"),
    (xr.Dataset({"status": ("eps", np.zeros(2, np.int8))}, coords={"eps": [0.1, 0.2]}),
     "its status is not a flag variable"),
    (xr.Dataset({"eta_max": ("A", [1.0])}, attrs={"title": "a\x1b[2Jboundary"}),
     "titled 'a\\x1b[2Jboundary' with dimensions A (1) and variables eta_max; as a boundary "
     "it lacks edge_kind"),
    (xr.Dataset({f"v{i}": ("x", [1.0]) for i in range(9)}), "variables v0, v1, v2, v3, v4, v5 "
     "and 3 more"),
])
def test_other_files_are_described_in_one_line(tmp_path, capsys, ds, words):
    path = tmp_path / "f.nc"
    ds.to_netcdf(path)
    line = _info(capsys, path)
    assert "not a cosserat-channel result file" in line and words in line
