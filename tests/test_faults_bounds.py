"""Unbounded inputs are refused before they are read whole or allocated: fit data from a device
that never ends a line, a table beyond its rows, a broadcast of 10^9 points for ``solve``, and
atlas files whose declared attributes or sizes no atlas has. Each is one line naming what is
beyond which limit; nothing is allocated first.

Devices and FIFOs are private ones made in a temporary directory."""

from __future__ import annotations

import os
import resource
import shutil
import stat
import subprocess
import sys
import threading

import numpy as np
import pytest

from cosserat_channel import cli
from cosserat_channel.atlas import store
from cosserat_channel.calibrate import DataError, data as data_mod, read_data
from test_faults import package_env, one_line_error

HEADER = "quantity,value,std_error,xi,eps\n"


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def test_fit_data_from_a_device_that_never_ends_a_line_is_one_line_in_bounded_memory(tmp_path):
    """A private /dev/zero as the data: refused at the first line's limit, not read whole
    (before: 5.7 GB in 13 s), in its own process so that its peak memory is its own."""
    if os.geteuid() != 0:
        pytest.skip("mknod needs root")
    zero = tmp_path / "zero"
    os.mknod(zero, 0o600 | stat.S_IFCHR, os.makedev(1, 5))
    code = ("import resource, sys\n"
            "from cosserat_channel import cli\n"
            "rc = cli.main(['fit', sys.argv[1], '--free', 'L'])\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)\n"
            "sys.exit(rc)\n")
    def peak(path):
        proc = subprocess.run([sys.executable, "-c", code, str(path)], env=package_env(),
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 2, proc.stderr
        return int(proc.stdout.split()[-1]), one_line_error(proc.stderr)

    small = tmp_path / "header.csv"
    small.write_text(HEADER)  # refused too ("no measurements"): the same process, no data
    base, _ = peak(small)
    mb, line = peak(zero)
    assert "line 1: longer than" in line and f"{data_mod.MAX_LINE_CHARS:,}" in line
    assert mb - base < 100  # MB: what the device sent is not kept
    assert stat.S_ISCHR(zero.lstat().st_mode)


def test_fit_data_from_a_fifo_beyond_the_lines_limit_is_one_line(tmp_path, monkeypatch):
    """A FIFO that keeps sending blank lines is refused at the limit of lines; the writer is
    left to end on its own."""
    monkeypatch.setattr(data_mod, "MAX_LINES", 1000)
    fifo = tmp_path / "data.csv"
    os.mkfifo(fifo)

    def feed():
        try:
            with open(fifo, "w") as f:
                f.write(HEADER)
                while True:
                    f.write("\n" * 100)
        except (BrokenPipeError, OSError):
            pass

    t = threading.Thread(target=feed, daemon=True)
    t.start()
    with pytest.raises(DataError) as err:
        read_data(fifo)
    t.join(10)
    assert "more than 1,000 lines" in str(err.value)
    assert stat.S_ISFIFO(fifo.lstat().st_mode)


def test_a_csv_table_streams_into_numbers_and_names_the_first_bad_cell(tmp_path):
    """Read as it streams: the same columns as before (fractions, empty cells, comments), and a
    bad cell found by the column checks is still named by its row and line."""
    path = tmp_path / "d.csv"
    rows = [f"u_over_u0,0.9,0.01,{x / 10:g},1/30\n" for x in range(11)]
    path.write_text("# comment\n" + HEADER + "".join(rows) + "\nDelta,10.3,0.5,,\n")
    d = read_data(path)
    assert len(d) == 12 and d.lines.tolist() == list(range(3, 14)) + [15]
    assert d.columns["eps"][0] == 1 / 30 and np.isnan(d.columns["eps"][-1])
    assert d.quantity[-1] == "Delta" and np.isnan(d.xi[-1])
    path.write_text(HEADER + "".join(rows) + "u_over_u0,0.9,0,0.5,1/30\n"
                    + "u_over_u0,0.9,0.01,2,1/30\n")
    with pytest.raises(DataError, match=r"row 12 \(line 13\), column 'std_error'"):
        read_data(path)
    path.write_text(HEADER + "".join(rows) + "u_over_u0,0.9,0.01,0.5,-1\n"
                    + "u_over_u0,0.9,0.01,0.5,-2\n")
    with pytest.raises(DataError, match=r"row 12 \(line 13\), column 'eps'"):
        read_data(path)


def test_reading_and_checking_a_million_rows_is_linear_and_small(tmp_path):
    """10^6 rows read and checked in bounded memory: the numbers (8 bytes a cell), not the text
    (over 40 bytes a cell as Python strings); the profile of 20 distinct points is solved once
    per evaluation, whatever the rows."""
    path = tmp_path / "big.csv"
    n = 1_000_000
    xi = np.tile(np.linspace(0.05, 1.0, 20), n // 20)
    with open(path, "w") as f:
        f.write(HEADER)
        f.writelines(f"u_over_u0,{1 - x * x / 4:.6f},0.002,{x:.4f},1/30\n" for x in xi)
    before = _peak_mb()
    d = read_data(path)
    assert len(d) == n and d.lines[-1] == n + 1
    assert _peak_mb() - before < 400  # MB; the text of the cells as lists took well over 1 GB


@pytest.mark.parametrize("shapes", [((1000, 1, 1), (1, 1000, 1), (1, 1, 1000)),
                                    ((100000, 1), (1, 100000), (1,))])
def test_solve_refuses_a_broadcast_beyond_its_limit_before_making_it(shapes):
    """(before: a 10^9-point broadcast, 8 GB in 20 s, before any check)."""
    import cosserat_channel as cc
    from cosserat_channel.sweep import arrays

    eps = np.full(shapes[0], 0.03)
    L = np.full(shapes[1], 10.0)
    K = np.full(shapes[2], 0.5)
    before = _peak_mb()
    with pytest.raises(cc.ParameterError) as err:
        cc.solve(eps, L, K, 1 / 3, 1.0)
    text = str(err.value)
    assert "\n" not in text and f"{arrays.MAX_SOLVE_POINTS:,}" in text and "eps (" in text
    assert _peak_mb() - before < 100


def test_solve_refuses_labelled_arrays_beyond_the_limit():
    import xarray as xr

    import cosserat_channel as cc

    eps = xr.DataArray(np.full(20000, 0.03), dims="a")
    L = xr.DataArray(np.full(20000, 10.0), dims="b")
    with pytest.raises(cc.ParameterError, match="400,000,000 points"):
        cc.solve(eps, L, xr.DataArray(np.full(1, 0.5), dims="c"), 1 / 3, 1.0)


def _edited_atlas(tmp_path, name, **attrs):
    import netCDF4

    path = tmp_path / name
    shutil.copy(store.SHIPPED, path)
    with netCDF4.Dataset(path, "a") as d:
        for k, v in attrs.items():
            d.setncattr(k, v)
    return path


@pytest.mark.parametrize("attrs, words", [
    ({"degree": "abc"}, "degree must be an integer in [1, 64]; got 'abc'"),
    ({"max_depth": 30}, "max_depth must be an integer in [0, 8]; got 30"),
    ({"max_depth": 60}, "max_depth must be an integer in [0, 8]; got 60"),
    ({"max_depth": -5}, "max_depth must be an integer in [0, 8]; got -5"),
    ({"max_depth": 15}, "max_depth must be an integer in [0, 8]; got 15"),
    ({"roots_A": 1e9}, "roots_A must be an integer in [1, "),
    ({"roots_A": 5000, "roots_N": 5000}, "cells are beyond the"),
    ({"tol": float("nan")}, "tol must be a finite number"),
    ({"A_min": 7.0}, "A_min < A_max"),
])
@pytest.mark.skipif(not store.SHIPPED.is_file(), reason="no shipped atlas in this copy")
def test_crafted_atlas_attributes_are_one_line_in_info_and_boundary(tmp_path, capsys, attrs,
                                                                      words):
    """The shipped atlas copied with one attribute edited: ``info`` and ``boundary`` each say
    so in one line naming the attribute and its range, exit non-zero, and allocate nothing
    (before: tracebacks, or 4.3 GB for a raster at max_depth 15)."""
    path = _edited_atlas(tmp_path, "a.nc", **attrs)
    before = _peak_mb()
    assert cli.main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and str(path) in err[0]
    assert cli.main(["boundary", "--atlas", str(path), "--A", "0.3333", "--N", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]
    assert _peak_mb() - before < 200


@pytest.mark.skipif(not store.SHIPPED.is_file(), reason="no shipped atlas in this copy")
def test_an_atlas_declaring_a_huge_dimension_is_refused_before_it_is_read(tmp_path, capsys):
    """A small file whose compressed variable declares 2^27 leaves (zeros compress to nothing):
    refused from its declared size, before the values are read."""
    import netCDF4

    path = tmp_path / "bomb.nc"
    src = netCDF4.Dataset(store.SHIPPED)
    with netCDF4.Dataset(path, "w") as d:
        d.setncatts({k: src.getncattr(k) for k in src.ncattrs()})
        d.createDimension("leaf", 1 << 27)
        v = d.createVariable("leaf_error", "f8", ("leaf",), zlib=True, complevel=9,
                             chunksizes=(1 << 20,))
        v[:] = 0.0
    src.close()
    assert path.stat().st_size < 2_000_000
    before = _peak_mb()
    assert cli.main(["boundary", "--atlas", str(path), "--A", "0.3333", "--N", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dimension leaf has 134,217,728 entries" in err[0]
    assert _peak_mb() - before < 200
