"""Result-file query and info: selection, filters, formats, every rejection (synthetic files)."""

import csv
import subprocess
import sys
import io
import json

import netCDF4
import numpy as np
import pytest
import xarray as xr

from cosserat_channel import cli
from cosserat_channel.results import light, render, selection
from cosserat_channel import status as st
from cosserat_channel.outputs import OUTPUTS
from cosserat_channel.parameters import ParameterError

COORDS = {
    "eps": np.array([0.001, 0.01, 0.1]),
    "L": np.array([1.0, 10.0]),
    "K": np.array([0.0, 0.5, 5.0]),
    "A": np.array([1 / 3]),
    "N": np.array([1.0, 2.0]),
}
DIMS = tuple(COORDS)
XI = np.linspace(0.0, 1.0, 5)


def _status(shape):
    """ok everywhere but eps = 0.1 (eps_too_large_path) and eps = 0.001, N = 2 (failed)."""
    s = np.full(shape, st.OK, dtype=np.int8)
    s[2] = st.EPS_TOO_LARGE_PATH
    s[0, ..., 1] = st.INTEGRATION_FAILED
    return s


def make_results() -> xr.Dataset:
    """A small result Dataset in the engine's layout: Delta = 1000 eps + L + K where ok."""
    shape = tuple(v.size for v in COORDS.values())
    eps, L, K, A, N = np.meshgrid(*COORDS.values(), indexing="ij")
    status = _status(shape)
    delta = np.where(status == st.OK, 1000 * eps + L + K, np.nan)

    def out(name, data):
        return DIMS, data, OUTPUTS[name].attrs

    profile = np.broadcast_to(1.0 - XI**2, shape + XI.shape).copy()
    ds = xr.Dataset(
        {
            "Delta": out("Delta", delta),
            "slip": out("slip", np.where(status == st.OK, K / (K + 1), np.nan)),
            "status": (DIMS, status, st.cf_flag_attrs()),
            "stage1_steps": (DIMS, np.arange(status.size, dtype=np.int32).reshape(shape),
                             {"long_name": "accepted steps of stage 1"}),
            "u_over_u0": (DIMS + ("xi",), profile, {"units": "1", "long_name": "u/u(0)"}),
        },
        coords={
            **{d: (d, v, {"units": "1", "long_name": f"parameter {d}"}) for d, v in COORDS.items()},
            "xi": ("xi", XI, {"units": "1", "long_name": "y/W"}),
        },
        attrs={
            "cosserat_channel_version": "0.1.0",
            "rtol": 1e-8,
            "atol": 1e-12,
            "sweep_toml": "# test sweep\n[grid]\neps = [0.001, 0.01, 0.1]\n",
            "sweep_sha256": "0" * 64,
            "created": "2026-01-01T00:00:00+00:00",
            "Conventions": "CF-1.8",
        },
    )
    return ds


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """The synthetic result file on disk (status int8 without _FillValue)."""
    path = tmp_path_factory.mktemp("results") / "out.nc"
    make_results().to_netcdf(path, encoding={"status": {"_FillValue": None}})
    return str(path)


def run(capsys, *argv):
    """``cli.main(argv)`` -> (exit code, stdout, stderr)."""
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def csv_rows(text):
    return list(csv.DictReader(io.StringIO(text)))


# ---------------------------------------------------------------------------------------------
# open_results
# ---------------------------------------------------------------------------------------------
def test_open_results_is_lazy(results):
    """open_results gives a dask-backed Dataset with the flag attributes intact."""
    ds = selection.open_results(results)
    try:
        assert ds["Delta"].chunks is not None
        assert ds["status"].dtype == np.int8
        assert selection.flag_names(ds["status"])["eps_too_large_path"] == st.EPS_TOO_LARGE_PATH
    finally:
        ds.close()


def test_open_results_rejects(tmp_path):
    """Missing, non-NetCDF and foreign NetCDF files raise a one-line ParameterError."""
    text = tmp_path / "x.nc"
    text.write_text("not netcdf\n")
    foreign = tmp_path / "f.nc"
    xr.Dataset({"a": ("x", [1.0])}).to_netcdf(foreign)
    for path, fragment in [(tmp_path / "none.nc", "no such file"), (text, "cannot open"),
                           (foreign, "not a cosserat-channel result file")]:
        with pytest.raises(ParameterError, match=fragment) as info:
            selection.open_results(path)
        assert "\n" not in str(info.value)


# ---------------------------------------------------------------------------------------------
# Selection
# ---------------------------------------------------------------------------------------------
def test_sel_off_grid_is_a_one_line_error_naming_the_nearest_values(capsys, results):
    """--sel L=7 (between 1 and 10) is refused, naming 1 and 10 and --nearest; nothing on stdout."""
    code, out, err = run(capsys, "query", results, "--sel", "L=7", "--format", "csv")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("cosserat-channel: error: --sel L=7")
    assert "nearest grid values: 1, 10" in err and "--nearest" in err
    code, _, err = run(capsys, "query", results, "--sel", "L=100")
    assert code == 2 and "nearest grid value: 10;" in err


def test_sel_matches_within_round_off(capsys, results):
    """A value typed from a printed coordinate (10 significant digits) selects it, silently."""
    code, out, err = run(capsys, "query", results, "--sel", "A=0.3333333333", "--sel",
                         "eps=0.01", "--sel", "K=0", "--format", "csv")
    assert code == 0 and err == ""
    rows = csv_rows(out)
    assert len(rows) == 2 * 2  # L x N
    assert {r["eps"] for r in rows} == {"0.01"} and {r["K"] for r in rows} == {"0.0"}


def test_match_coordinate_zero_on_a_linspace_through_zero():
    """A = 0 matches the ~1e-16 a linspace gives there; A = 0.01 between grid values does not."""
    grid = np.linspace(-3, 5, 161)
    i, exact = selection.match_coordinate(grid, 0.0, "A")
    assert exact and abs(grid[i]) < 1e-12
    with pytest.raises(selection.QueryError, match="nearest grid values: 0, 0.05"):
        selection.match_coordinate(grid, 0.01, "A")
    assert selection.match_coordinate(grid, 0.01, "A", nearest=True) == (i, False)


def test_sel_nearest_opts_in_and_says_what_it_took(capsys, results):
    """With --nearest, --sel takes the nearest value and stderr names the value taken."""
    code, out, err = run(capsys, "query", results, "--nearest", "--sel", "L=7", "--sel",
                         "eps=0.009", "--sel", "K=0.5", "--format", "csv")
    assert code == 0
    rows = csv_rows(out)
    assert len(rows) == 1 * 2  # A x N
    assert {r["L"] for r in rows} == {"10.0"}
    assert {r["eps"] for r in rows} == {"0.01"}
    notes = err.splitlines()
    assert len(notes) == 2  # K=0.5 is on the grid: no note
    assert "--sel L=7 is not a grid value; took the nearest, L=10" in notes[0]
    assert "--sel eps=0.009" in notes[1] and "eps=0.01" in notes[1]


def test_range_inclusive_and_open(capsys, results):
    """--range keeps both bounds; an empty bound leaves that side open."""
    _, out, _ = run(capsys, "query", results, "--range", "eps=:0.01", "--format", "csv")
    assert sorted({float(r["eps"]) for r in csv_rows(out)}) == [0.001, 0.01]
    _, out, _ = run(capsys, "query", results, "--range", "K=0.5:", "--range", "eps=0.01:0.01",
                    "--format", "csv")
    rows = csv_rows(out)
    assert {float(r["K"]) for r in rows} == {0.5, 5.0} and {r["eps"] for r in rows} == {"0.01"}
    assert len(rows) == 2 * 2 * 1 * 2


def test_where_on_floats_and_coordinates(capsys, results):
    """--where clauses on a variable and a coordinate are ANDed."""
    _, out, _ = run(capsys, "query", results, "--where", "Delta > 15", "--where", "K<=0.5",
                    "--format", "csv")
    rows = csv_rows(out)
    expected = {(e, l, k, n) for e in COORDS["eps"] for l in COORDS["L"] for k in COORDS["K"]
                for n in COORDS["N"]
                if 1000 * e + l + k > 15 and k <= 0.5 and e == 0.01}
    got = {(float(r["eps"]), float(r["L"]), float(r["K"]), float(r["N"])) for r in rows}
    assert got == expected and len(got) == 4
    assert all(float(r["Delta"]) > 15 for r in rows)


def test_where_on_status_names(capsys, results):
    """status is compared by flag name; == and != split the points."""
    shape = tuple(v.size for v in COORDS.values())
    status = _status(shape)
    _, out, _ = run(capsys, "query", results, "--where", "status == ok", "--format", "csv")
    rows = csv_rows(out)
    assert len(rows) == int((status == st.OK).sum()) and {r["status"] for r in rows} == {"ok"}
    _, out, _ = run(capsys, "query", results, "--where", "status!=ok", "--format", "csv")
    rows = csv_rows(out)
    assert len(rows) == int((status != st.OK).sum())
    assert {r["status"] for r in rows} == {"eps_too_large_path", "integration_failed"}


def test_csv_rows_match_data(capsys, results):
    """CSV: one column per coordinate and chosen variable, values round-trip exactly."""
    _, out, _ = run(capsys, "query", results, "--sel", "N=1", "--sel", "L=1", "--vars",
                    "Delta,stage1_steps", "--format", "csv")
    rows = csv_rows(out)
    assert list(rows[0]) == ["eps", "L", "K", "A", "N", "status", "Delta", "stage1_steps"]
    ds = make_results().sel(N=1.0, L=1.0)
    assert len(rows) == 9
    for r in rows:
        point = ds.sel(eps=float(r["eps"]), K=float(r["K"])).squeeze("A")
        assert float(r["A"]) == 1 / 3
        np.testing.assert_equal(float(r["Delta"]), float(point["Delta"]))
        assert int(r["stage1_steps"]) == int(point["stage1_steps"])


def test_json_rows_match_data(capsys, results):
    """JSON: an array of objects, NaN as null, status by name, integers as integers."""
    _, out, _ = run(capsys, "query", results, "--sel", "eps=0.1", "--format", "json")
    rows = json.loads(out)
    assert len(rows) == 2 * 3 * 1 * 2
    assert all(r["status"] == "eps_too_large_path" and r["Delta"] is None for r in rows)
    assert all(isinstance(r["stage1_steps"], int) for r in rows)
    assert "u_over_u0" not in rows[0] and "xi" not in rows[0]  # profiles only on request


def test_profile_variables_add_xi_rows(capsys, results):
    """Asking for a profile variable makes one row per xi."""
    _, out, _ = run(capsys, "query", results, "--sel", "eps=0.01", "--sel", "L=1", "--sel", "K=0",
                    "--sel", "N=1", "--vars", "u_over_u0", "--format", "json")
    rows = json.loads(out)
    assert [r["xi"] for r in rows] == XI.tolist()
    np.testing.assert_allclose([r["u_over_u0"] for r in rows], 1 - XI**2)


def test_table_is_capped(capsys, results, monkeypatch):
    """The table shows at most TABLE_ROWS rows and counts the rest."""
    monkeypatch.setattr(render, "TABLE_ROWS", 5)
    code, out, _ = run(capsys, "query", results)
    lines = out.splitlines()
    assert code == 0 and len(lines) == 1 + 5 + 1
    assert lines[0].split()[:6] == ["eps", "L", "K", "A", "N", "status"]
    assert lines[-1] == "… 31 more rows (use --format csv -o FILE)"


def test_empty_selection_is_a_note(capsys, results):
    """No matching point: exit 0, a note on stderr, only the header on stdout."""
    code, out, err = run(capsys, "query", results, "--where", "Delta > 1e9", "--format", "csv")
    assert code == 0 and "empty" in err and len(err.splitlines()) == 1
    assert out.splitlines() == ["eps,L,K,A,N,status,Delta,slip,stage1_steps"]


def test_output_file_written(capsys, results, tmp_path):
    """-o writes the text to the file, nothing to stdout, and leaves no temporary file."""
    target = tmp_path / "rows.csv"
    code, out, err = run(capsys, "query", results, "--where", "status == ok", "--format", "csv",
                         "-o", str(target))
    assert code == 0 and out == "" and err == ""
    assert len(csv_rows(target.read_text())) == 18
    assert [p.name for p in tmp_path.iterdir()] == ["rows.csv"]


def test_netcdf_subset(capsys, results, tmp_path):
    """--format netcdf: a result file again, status int8 with flags and no _FillValue."""
    target = tmp_path / "sub.nc"
    code, _, err = run(capsys, "query", results, "--sel", "N=1", "--range", "eps=:0.01",
                       "--format", "netcdf", "-o", str(target))
    assert code == 0 and err == ""
    with netCDF4.Dataset(target) as nc:
        status = nc["status"]
        assert status.dtype == np.int8
        assert "_FillValue" not in status.ncattrs()
        assert status.getncattr("flag_meanings") == st.cf_flag_attrs()["flag_meanings"]
        assert nc.getncattr("sweep_sha256") == "0" * 64
    ds = selection.open_results(target)
    try:
        assert ds["status"].dims == DIMS
        assert dict(ds.sizes) == {"eps": 2, "L": 2, "K": 3, "A": 1, "N": 1}
        expected = make_results().isel(N=[0], eps=[0, 1])
        np.testing.assert_array_equal(ds["Delta"].values, expected["Delta"].values)
        assert "query" in ds.attrs and "selected" not in ds
    finally:
        ds.close()


def test_netcdf_subset_with_where_masks(capsys, results, tmp_path):
    """With --where the subset is the matching sub-grid; failed points are NaN and flagged."""
    target = tmp_path / "w.nc"
    code, _, _ = run(capsys, "query", results, "--where", "Delta > 15", "--format", "netcdf",
                     "-o", str(target))
    assert code == 0
    with xr.open_dataset(target) as ds:
        assert ds["eps"].values.tolist() == [0.001, 0.01]  # eps = 0.1 has no solution
        selected = ds["selected"].values.astype(bool)
        assert np.all(ds["Delta"].values[selected] > 15)
        assert np.all(np.isnan(ds["Delta"].values[~selected]))
        assert selected.sum() == 9


# ---------------------------------------------------------------------------------------------
# Rejections: exit code 2, one line on stderr
# ---------------------------------------------------------------------------------------------
REJECT = [
    # (extra arguments, fragment of the message)
    (["--sel", "Q=1"], "unknown coordinate 'Q'"),
    (["--sel", "Delta=1"], "unknown coordinate"),  # a variable is not a coordinate
    (["--sel", "L"], "expected NAME=VALUE"),
    (["--sel", "L=ten"], "not a number"),
    (["--sel", "L=nan"], "nan"),
    (["--sel", "L=1", "--sel", "L=10"], "twice"),
    (["--range", "eps=0.1"], "expected NAME=LO:HI"),
    (["--range", "eps=:"], "at least one"),
    (["--range", "eps=0.1:0.01"], "above HI"),
    (["--range", "eps=a:b"], "not a number"),
    (["--range", "Z=0:1"], "unknown coordinate"),
    (["--where", "Delta = 1"], "expected NAME OP VALUE"),
    (["--where", "Delta >"], "expected NAME OP VALUE"),
    (["--where", "delta > 1"], "unknown name 'delta'"),
    (["--where", "status == fine"], "unknown status name 'fine'; valid: ok,"),
    (["--where", "status < ok"], "only == and !="),
    (["--where", "Delta > __import__('os').system('x')"], "not a number"),
    (["--where", "Delta > 1; rm -rf /"], "expected NAME OP VALUE"),
    (["--where", "Delta > (1)"], "not a number"),
    (["--where", "__class__ > 1"], "unknown name"),
    (["--where", "Delta > 1 or 1"], "expected NAME OP VALUE"),
    (["--vars", "Delta,foo"], "unknown variable(s) 'foo'"),
    (["--vars", ","], "at least one"),
    (["--format", "netcdf"], "-o FILE"),
    (["--format", "xml"], "invalid choice"),
]


@pytest.mark.parametrize("extra, fragment", REJECT)
def test_rejections(capsys, results, extra, fragment):
    """Bad clauses exit 2 with one stderr line naming the problem; nothing on stdout."""
    code, out, err = run(capsys, "query", results, *extra)
    assert code == 2
    assert out == ""
    assert len(err.splitlines()) == 1 and err.startswith("cosserat-channel: error: ")
    assert fragment in err


@pytest.mark.parametrize("command", ["query", "info"])
def test_bad_files_exit_2(capsys, tmp_path, command):
    """Missing and foreign files exit 2 with one stderr line, for query and info."""
    text = tmp_path / "notes.nc"
    text.write_text("hello\n")
    foreign = tmp_path / "f.nc"
    xr.Dataset({"a": ("x", [1.0])}).to_netcdf(foreign)
    for path, fragment in [(tmp_path / "absent.nc", "no such file"), (text, "cannot open"),
                           (foreign, "not a cosserat-channel result file")]:
        code, out, err = run(capsys, command, str(path))
        assert code == 2 and out == "" and len(err.splitlines()) == 1 and fragment in err


def test_output_into_missing_directory(capsys, results, tmp_path):
    """-o into a directory that does not exist is rejected before any work."""
    code, _, err = run(capsys, "query", results, "--format", "csv", "-o",
                       str(tmp_path / "nope" / "x.csv"))
    assert code == 2 and "does not exist" in err


# ---------------------------------------------------------------------------------------------
# info
# ---------------------------------------------------------------------------------------------
def test_info_counts_match_data(capsys, results):
    """info lists dimensions, units, status counts with percentages and the provenance."""
    code, out, err = run(capsys, "info", results)
    assert code == 0 and err == ""
    status = _status(tuple(v.size for v in COORDS.values()))
    total = status.size
    lines = out.splitlines()
    for s in st.Status:
        line = next(l for l in lines if l.split()[:1] == [s.name])
        n = int((status == s.value).sum())
        assert line.split()[1:3] == [str(n), f"{100 * n / total:.2f}"]
    assert f"status ({total} points)" in out
    eps_line = next(l for l in lines if l.split()[:1] == ["eps"])
    assert eps_line.split()[1:4] == ["3", "0.001", ".."]
    assert "particle diameters" in out and "shear-layer thickness" in out
    assert "0" * 64 in out and "# test sweep" in out and "1e-08" in out


@pytest.fixture(scope="module")
def tool_files(tmp_path_factory):
    """An atlas, a traced boundary and a boundary drawn from the atlas, written by the commands."""
    d = tmp_path_factory.mktemp("tool_files")
    paths = {k: str(d / f"{k}.nc") for k in ("atlas", "traced", "drawn")}
    assert cli.main(["atlas", "-o", paths["atlas"], "--A", "0.25:0.5", "--N", "0.8:0.9",
                     "--tol", "1e-3", "--degree", "2", "--max-depth", "0", "--workers", "1"]) == 0
    assert cli.main(["boundary", "--A", "0.3,0.4", "--N", "0.85", "--coarse", "8", "--trace",
                     "-o", paths["traced"]]) == 0
    assert cli.main(["boundary", "--A", "0.3,0.4,0.45", "--N", "0.85", "--atlas", paths["atlas"],
                     "-o", paths["drawn"]]) == 0
    return paths


@pytest.mark.parametrize("which, kind, pairs", [("traced", "boundary", 2), ("drawn", "boundary", 3),
                                               ("atlas", "atlas", None)])
def test_info_describes_boundary_and_atlas_files(capsys, tool_files, which, kind, pairs):
    """info reads every file the tool writes: its kind, its variables with their text, the flag
    counts of a boundary (one per (A, N) pair) or the cells of an atlas, and CF-1.8."""
    capsys.readouterr()
    code, out, err = run(capsys, "info", tool_files[which])
    assert code == 0 and err == "", err
    lines = out.splitlines()
    assert lines[1].startswith(f"kind  {kind}")
    assert any(l.split()[:2] == ["Conventions", "CF-1.8"] for l in lines)
    with xr.open_dataset(tool_files[which]) as ds:
        for v in ds.data_vars:
            assert any(l.split()[:1] == [v] for l in lines), v
        if kind == "boundary":
            assert f"edges ({pairs} (A, N) pairs)" in out
            start = lines.index(f"edges ({pairs} (A, N) pairs)")
            counts = {l.split()[0]: int(l.split()[1]) for l in lines[start + 1:start + 4]}
            kinds = ds["edge_kind"].values.ravel().tolist()
            assert counts == {n: kinds.count(i) for i, n in
                              enumerate(ds["edge_kind"].attrs["flag_meanings"].split())}
        else:
            n_leaf = ds.sizes["leaf"]
            assert f"cells ({n_leaf} leaves, {int((ds['leaf_n'] < 0).sum())} unresolved; " in out


# ---------------------------------------------------------------------------------------------
# Small queries read with netCDF4 alone
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def run_results(tmp_path_factory):
    """The synthetic results as a file of 'run' (its 'source' attribute): the light path."""
    path = tmp_path_factory.mktemp("light") / "out.nc"
    ds = make_results()
    ds.attrs["source"] = "cosserat-channel run"
    ds.to_netcdf(path, encoding={"status": {"_FillValue": None}})
    return str(path)


@pytest.mark.parametrize("argv", [
    [],
    ["--sel", "L=10", "--format", "csv"],
    ["--range", "eps=:0.01", "--where", "status == ok", "--where", "Delta > 11", "--format", "csv"],
    ["--where", "status != ok", "--format", "json"],
    ["--vars", "u_over_u0,Delta", "--sel", "eps=0.01", "--sel", "L=1", "--format", "csv"],
    ["--where", "eps < 0.05", "--where", "N >= 2", "--vars", "slip", "--format", "csv"],
    ["--sel", "K=0.4", "--nearest", "--range", "eps=0.005:", "--format", "table"],
    ["--range", "K=10:20"],
    ["--where", "stage1_steps >= 30", "--where", "slip != 0.5", "--format", "json"],
    ["--range", "K=:0.5", "--range", "N=2:"],
])
def test_small_query_without_xarray_gives_the_same_answer(capsys, monkeypatch, results,
                                                          run_results, argv):
    """The netCDF4-only reading of a file of 'run' answers as xarray's reading of the same data:
    the same rows, values, flag names, notes and exit code."""
    from cosserat_channel.cli import _sweeps

    assert light.open_light(results) is None  # no 'source': read through xarray
    want = run(capsys, "query", results, *argv)
    monkeypatch.setattr(_sweeps, "open_results", lambda path: pytest.fail("read with xarray"))
    got = run(capsys, "query", run_results, *argv)
    assert got == want
    assert want[0] == 0 and (want[1] or "empty" in want[2])


def test_large_boxes_and_netcdf_subsets_go_through_dask(capsys, monkeypatch, run_results, tmp_path):
    """Above ROW_BLOCK selected points (or for a NetCDF subset) the file is read through dask."""
    from cosserat_channel.cli import _sweeps

    opened = []
    real = _sweeps.open_results
    monkeypatch.setattr(_sweeps, "open_results", lambda path: opened.append(path) or real(path))
    assert run(capsys, "query", run_results, "--sel", "L=10")[0] == 0
    assert opened == []
    monkeypatch.setattr(selection, "ROW_BLOCK", 10)
    code, out, _ = run(capsys, "query", run_results, "--sel", "L=10", "--format", "csv")
    assert code == 0 and len(csv_rows(out)) == 18 and opened == [run_results]
    monkeypatch.setattr(selection, "ROW_BLOCK", 1_000_000)
    sub = str(tmp_path / "s.nc")
    assert run(capsys, "query", run_results, "--sel", "L=10", "--format", "netcdf", "-o", sub)[0] == 0
    assert opened == [run_results, run_results]


def test_a_slice_query_imports_neither_xarray_nor_dask(run_results, tmp_path):
    """A fresh interpreter answers a slice query without importing xarray, dask or numba."""
    code = ("import sys; from cosserat_channel import cli; "
            f"assert cli.main(['query', {run_results!r}, '--sel', 'L=10', '--format', 'csv', "
            f"'-o', {str(tmp_path / 'q.csv')!r}]) == 0; "
            "loaded = [m for m in ('xarray', 'dask', 'numba') if m in sys.modules]; "
            "assert not loaded, loaded")
    subprocess.run([sys.executable, "-c", code], check=True)
    assert len(csv_rows((tmp_path / "q.csv").read_text())) == 18


def test_files_that_need_decoding_are_read_through_xarray(tmp_path):
    """A scaled variable, a fill value other than NaN or a foreign file: no light reading."""
    base = make_results()
    base.attrs["source"] = "cosserat-channel run"
    cases = {
        "scaled": ({}, {"slip": {"scale_factor": 0.5, "dtype": "int16", "_FillValue": -1}}),
        "fill": ({}, {"Delta": {"_FillValue": -9.0}}),
        "foreign": ({"source": "elsewhere"}, {}),
    }
    for name, (attrs, encoding) in cases.items():
        path = tmp_path / f"{name}.nc"
        ds = base.copy()
        ds.attrs.update(attrs)
        ds.to_netcdf(path, encoding={"status": {"_FillValue": None}, **encoding})
        assert light.open_light(path) is None, name
    plain = tmp_path / "plain.nc"
    base.to_netcdf(plain, encoding={"status": {"_FillValue": None}})
    lf = light.open_light(plain)
    assert lf is not None
    lf.close()
