"""Publishing an output without replacing what appeared meanwhile, and the shipped atlas bound
to the digest the code records.

* two ``fit -o same.json`` at once, and a file appearing at the output of ``run``, ``atlas``
  and ``fit`` while they work: the file there is kept, the new output is kept beside it, one
  line, exit 1; with ``--overwrite`` it is replaced as asked;
* the shipped atlas edited in a copy of the package (every transition x1.05, HDF5 checksums
  still valid): one line, and the answer comes from tracing.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import netCDF4
import numpy as np
import pytest

import cosserat_channel
from cosserat_channel import atlas as at
from cosserat_channel import cli, files
from cosserat_channel.atlas import store as atlas_store
from cosserat_channel.sweep import engine

ROOT = Path(__file__).resolve().parent.parent


# ---------------------------------------------------------------------------------------------
# files.publish_new
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("how", ["renameat2", "link", "neither"])
def test_publish_new_never_replaces(tmp_path, monkeypatch, how):
    """Each way of publishing (renameat2, a hard link, the check-then-rename of a file system
    with neither) puts the file where nothing is and refuses where something is, src kept."""
    if how != "renameat2":
        monkeypatch.setattr(files, "_renameat2", lambda: None)
    if how == "neither":
        def no_link(src, dst):
            raise PermissionError(1, "Operation not permitted")

        monkeypatch.setattr(os, "link", no_link)
    src, dst = tmp_path / "a", tmp_path / "b"
    src.write_text("new")
    files.publish_new(src, dst)
    assert dst.read_text() == "new" and not src.exists()
    src.write_text("newer")
    with pytest.raises(FileExistsError):
        files.publish_new(src, dst)
    assert dst.read_text() == "new" and src.read_text() == "newer"


def test_a_file_appearing_meanwhile_is_kept_and_the_output_beside_it(tmp_path):
    out = tmp_path / "out.json"

    def write(tmp):
        out.write_text("theirs")  # appears while the output is made
        Path(tmp).write_text("ours")

    with pytest.raises(files.OutputAppeared) as info:
        files.atomic_output(out, write, replace=False)
    assert out.read_text() == "theirs"
    kept = tmp_path / "out.new.json"
    assert kept.read_text() == "ours" and repr(str(kept)) in str(info.value)
    assert "\n" not in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json", "out.new.json"]
    files.atomic_output(out, lambda tmp: Path(tmp).write_text("asked"))  # replace: as asked
    assert out.read_text() == "asked"


# ---------------------------------------------------------------------------------------------
# fit, run, atlas
# ---------------------------------------------------------------------------------------------
FIT_DATA = """\
quantity,value,std_error,eps
Delta,{d1},0.05,0.01
Delta,{d2},0.05,0.02
Delta,{d3},0.05,0.05
"""


@pytest.fixture
def fit_csv(tmp_path):
    from cosserat_channel import solve_point

    d = [solve_point(e, 10.0, 5.0, 1 / 3, 1.0).Delta for e in (0.01, 0.02, 0.05)]
    path = tmp_path / "data.csv"
    path.write_text(FIT_DATA.format(d1=d[0], d2=d[1], d3=d[2]))
    return path


# Runs cli.main with files.write_text held until both processes are there: each has checked
# its output and computed its fit before either publishes.
TWO = r"""
import os, sys, time
from cosserat_channel import cli, files
ready, go = sys.argv[1:3]
orig = files.write_text
def write_text(*a, **k):
    open(ready, "w").close()
    deadline = time.monotonic() + 300
    while not os.path.exists(go) and time.monotonic() < deadline:
        time.sleep(0.01)
    return orig(*a, **k)
files.write_text = write_text
sys.exit(cli.main(sys.argv[3:]))
"""


def test_two_fits_to_the_same_output_lose_nothing(tmp_path, fit_csv):
    """Two 'fit -o same.json' at once: one result is at same.json, the other beside it, and
    the one that found the name taken says so in one line, exit 1."""
    import json
    import time

    from test_faults import package_env

    out = tmp_path / "same.json"
    go = tmp_path / "go"
    argv = ["fit", str(fit_csv), "--free", "L", "--fixed", "K=5,A=1/3,N=1", "-o", str(out)]
    procs = [subprocess.Popen([sys.executable, "-c", TWO, str(tmp_path / f"ready{i}"), str(go),
                               *argv], env=package_env(), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for i in range(2)]
    deadline = time.monotonic() + 600
    while not all((tmp_path / f"ready{i}").exists() for i in range(2)):
        assert time.monotonic() < deadline and all(p.poll() is None for p in procs)
        time.sleep(0.05)
    go.touch()
    results = [p.communicate(timeout=600) for p in procs]
    assert sorted(p.returncode for p in procs) == [0, 1], results
    assert sorted(p.name for p in tmp_path.glob("same*.json")) == ["same.json", "same.new.json"]
    err = [line for _, e in results for line in e.splitlines() if "error:" in line]
    assert len(err) == 1 and "appeared while" in err[0], results
    assert json.loads(out.read_text())["estimates"] == \
        json.loads((tmp_path / "same.new.json").read_text())["estimates"]


def test_fit_output_appearing_mid_run_is_kept(tmp_path, fit_csv, monkeypatch, capsys):
    from cosserat_channel.calibrate import estimate

    out = tmp_path / "fit.json"
    orig = estimate.fit

    def fit(*a, **k):
        result = orig(*a, **k)
        out.write_text("someone else's\n")
        return result

    monkeypatch.setattr(estimate, "fit", fit)
    argv = ["fit", str(fit_csv), "--free", "L", "--fixed", "K=5,A=1/3,N=1", "-o", str(out)]
    assert cli.main(argv) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "appeared while" in err[0] and "fit.new.json" in err[0], err
    assert out.read_text() == "someone else's\n"
    assert "estimates" in (tmp_path / "fit.new.json").read_text()


SWEEP = """\
[grid]
eps = [0.01, 0.02]
L = [5.0, 10.0]
K = [5.0]
A = [0.3333333333333333]
N = [1.0]
"""


def test_run_output_appearing_mid_run_is_kept(tmp_path, monkeypatch, capsys):
    """A file appears at run's output while it works: kept; the result beside it, whole."""
    sweep = tmp_path / "s.toml"
    sweep.write_text(SWEEP)
    out = tmp_path / "out.nc"
    orig = engine.WorkStore.put

    def put(self, k, result):
        orig(self, k, result)
        if not out.exists():
            out.write_bytes(b"someone else's")

    monkeypatch.setattr(engine.WorkStore, "put", put)
    assert cli.main(["run", str(sweep), "-o", str(out), "--workers", "1"]) == 1
    err = capsys.readouterr().err.splitlines()
    err = [e for e in err if "error" in e]
    assert len(err) == 1 and "appeared while" in err[0] and "out.new.nc" in err[0], err
    assert out.read_bytes() == b"someone else's"
    import xarray as xr

    with xr.open_dataset(tmp_path / "out.new.nc") as ds:
        assert (ds["status"] == 0).all()
    # Asked to replace it, the run does (its blocks were kept: nothing is solved again).
    monkeypatch.setattr(engine.WorkStore, "put", orig)
    assert cli.main(["run", str(sweep), "-o", str(out), "--workers", "1", "--overwrite"]) == 0
    with xr.open_dataset(out) as ds:
        assert (ds["status"] == 0).all()


def test_atlas_output_appearing_mid_build_is_kept(tmp_path, monkeypatch, capsys):
    out = tmp_path / "a.nc"
    orig = at.build_atlas

    def build(*a, **k):
        result = orig(*a, **k)
        out.write_bytes(b"someone else's")
        return result

    monkeypatch.setattr(at, "build_atlas", build)
    argv = ["atlas", "--A=0.3:0.4", "--N=1:1.1", "--tol", "1e-3", "--max-depth", "1",
            "--workers", "1", "-o", str(out)]
    assert cli.main(argv) == 1
    err = [e for e in capsys.readouterr().err.splitlines() if "error" in e]
    assert len(err) == 1 and "appeared while" in err[0] and "a.new.nc" in err[0], err
    assert out.read_bytes() == b"someone else's"
    assert at.load_atlas(tmp_path / "a.new.nc").box == (0.3, 0.4, 1.0, 1.1)


# ---------------------------------------------------------------------------------------------
# The shipped atlas
# ---------------------------------------------------------------------------------------------
def test_the_recorded_digest_is_the_shipped_file():
    """The digest the code records is the shipped file's (``make atlas`` records it)."""
    from cosserat_channel.atlas.shipped_digest import SHA256

    assert atlas_store.file_digest(atlas_store.SHIPPED) == SHA256, (
        "the shipped atlas changed without its digest: 'make atlas' records it, or run "
        "python -c 'from cosserat_channel.atlas.store import record_shipped_digest as r; r()'")
    assert atlas_store.shipped_problem() is None
    text = (ROOT / "Makefile").read_text()
    atlas_target = text[text.index("\natlas:"):].split("\n\n")[0]
    assert "record_shipped_digest" in atlas_target


@pytest.fixture(scope="module")
def tampered(tmp_path_factory):
    """A copy of the package whose shipped atlas has every transition x1.05, edited in place
    with netCDF4 (its HDF5 checksums are valid)."""
    here = Path(cosserat_channel.__file__).resolve().parent
    src = tmp_path_factory.mktemp("copy") / "src"
    shutil.copytree(here, src / here.name, ignore=shutil.ignore_patterns("__pycache__"))
    data = src / here.name / "atlas" / "data" / "whole_plane.nc"
    with netCDF4.Dataset(data, "a") as nc:
        v = nc["leaf_coefficients"]
        c = v[...]
        c[..., 0, 0] += np.log(1.05)  # log eta's constant term: every transition x1.05
        v[...] = c
    return src


MAIN = "import sys; from cosserat_channel import cli; sys.exit(cli.main(sys.argv[1:]))"


def run_copy(src, *argv, **env):
    env = dict(os.environ, PYTHONPATH=str(src), **env)
    return subprocess.run([sys.executable, "-c", MAIN, *argv], env=env, capture_output=True,
                          text=True, timeout=900)


@pytest.mark.slow
def test_a_tampered_shipped_atlas_is_not_used(tampered, tmp_path):
    """boundary on the edited copy: one line saying the shipped atlas is not what the package
    records, and eta_max traced afresh (the true 7.659 at A = 1/3, N = 2, not 8.05)."""
    proc = run_copy(tampered, "boundary", "--A", "0.3333333333333333", "--N", "2",
                    XDG_CACHE_HOME=str(tmp_path / "home"))  # no cached atlas
    assert proc.returncode == 0, proc.stderr
    lines = [x for x in proc.stderr.splitlines() if "shipped atlas" in x]
    assert len(lines) == 1 and "not the file this package records" in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert "7.659" in proc.stdout or "7.66" in proc.stdout, proc.stdout


def test_info_on_the_tampered_shipped_atlas_says_so(tampered):
    proc = run_copy(tampered, "info", str(tampered / "cosserat_channel" / "atlas" / "data" /
                                          "whole_plane.nc"))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and "not the file this package records" in err[0], err
