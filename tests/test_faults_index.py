"""Bits flipped in the chunk index (the HDF5 B-trees) of a result file.

Fletcher-32 covers each chunk's data, not the B-tree that finds the chunks: a flipped bit there
can make a chunk unfindable, and HDF5 returns the fill value for all of it without an error
(NaN, or netCDF's default fill for integers). A value missing where the status says there is
one is damage: every reader that checks (``info``, ``query``, the library's read check) says so
in one line, exit 1; a flip that changes nothing changes nothing.
"""

from __future__ import annotations

import random
import re
import warnings
from pathlib import Path

import netCDF4
import numpy as np
import pytest

from cosserat_channel import cli, run_sweep
from cosserat_channel.results import selection
from cosserat_channel.sweep import dataset, writer

SWEEP = """\
[grid]
eps = {linspace = [0.01, 0.05, 8]}
L = {linspace = [5.0, 20.0, 8]}
K = [0.5, 5.0, 50.0, 500.0, 5000.0]
A = [0.3333333333333333, 1.0, 2.0, -0.5]
N = [1.0, 1.5, 2.0, 3.0]
[output]
variables = ["Delta", "slip", "sigma_yx_wall", "xi_stop", "stage1_steps"]
"""
# Signatures of HDF5's B-tree nodes (version 1, and the version-2 header, leaf and inner nodes).
SIGNATURES = (b"TREE", b"BTHD", b"BTLF", b"BTIN")


@pytest.fixture(scope="module")
def chunked(tmp_path_factory):
    """A 5,120-point result in chunks of about 2 kB (some 30 a variable): real B-trees."""
    path = tmp_path_factory.mktemp("index") / "out.nc"
    path.with_suffix(".toml").write_text(SWEEP)
    orig = dataset.chunk_shape

    def small(shape, itemsize, target=None):
        return orig(shape, itemsize, target=2048)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(dataset, "chunk_shape", small)
        m.setattr(writer, "chunk_shape", small)
        run_sweep(str(path.with_suffix(".toml")), str(path), workers=1).close()
    with netCDF4.Dataset(path) as nc:
        assert len(nc["Delta"].chunking()) == 5 and nc["Delta"].chunking() != list(nc["Delta"].shape)
    return path


def read_all(path: Path):
    """Every variable as HDF5 gives it (no error: the arrays; an error: None)."""
    try:
        with netCDF4.Dataset(path) as nc, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            nc.set_auto_maskandscale(False)
            return {k: np.asarray(v[...]) for k, v in nc.variables.items()}
    except Exception:  # noqa: BLE001 (any failure to read is a failure HDF5 reports)
        return None


def same(a, b) -> bool:
    return a.keys() == b.keys() and all(
        a[k].shape == b[k].shape and np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f")
        for k in a)


def flips(raw: bytes, n_per_node: int, seed: int = 0):
    """``(byte, bit)`` pairs inside the B-tree nodes of ``raw``."""
    rng = random.Random(seed)
    starts = sorted(m.start() for s in SIGNATURES for m in re.finditer(re.escape(s), raw))
    assert starts, "no B-tree node found"
    for a, b in zip(starts, [*starts[1:], len(raw)]):
        end = min(b, a + 4096)
        for _ in range(n_per_node):
            yield rng.randrange(a, end), rng.randrange(8)


@pytest.mark.slow
def test_every_silent_change_from_an_index_flip_is_reported(chunked, tmp_path, capsys):
    """Random single-bit flips in every B-tree node: each that HDF5 reads without an error but
    with other values than the file holds (a chunk read as fill values) is reported by the
    library's read check, and for each variable so damaged info --check-all and query say so
    (one line, exit 1)."""
    raw = chunked.read_bytes()
    reference = read_all(chunked)
    bad = tmp_path / "bad.nc"
    silent, told = 0, set()
    for pos, bit in flips(raw, 25):
        data = bytearray(raw)
        data[pos] ^= 1 << bit
        bad.write_bytes(bytes(data))
        got = read_all(bad)
        if got is None or same(got, reference):
            continue  # refused by HDF5, or harmless
        silent += 1
        changed = frozenset(k for k in got if not (
            got[k].shape == reference[k].shape
            and np.array_equal(got[k], reference[k], equal_nan=got[k].dtype.kind == "f")))
        if changed == {"xi_stop"}:
            # xi_stop is NaN at every status but eps_too_large_path, and may be NaN there too
            # (next to the axis edge): a blanked chunk of it alone cannot be told from values.
            continue
        with selection.open_results(bad) as ds:
            assert selection.read_problem(ds) is not None, (pos, bit, changed)
        if changed in told:
            continue
        told.add(changed)
        argvs = [["info", "--check-all", str(bad)], ["query", str(bad), "--format", "csv"]]
        blanked = [k for k in ("Delta", "slip", "sigma_yx_wall") if k in changed]
        if blanked:  # a query of one point in the blanked chunk (read without xarray)
            name = blanked[0]
            i = np.argwhere(np.isnan(got[name]) & ~np.isnan(reference[name]))[0]
            argvs.append(["query", str(bad), *(f"--sel={d}={reference[d][k]!r}"
                                               for d, k in zip(("eps", "L", "K", "A", "N"), i))])
        for argv in argvs:
            assert cli.main(argv) == 1, (pos, bit, argv)
            err = capsys.readouterr().err.splitlines()
            assert len(err) == 1 and "damaged" in err[0], (pos, bit, err)
    # The flips that blank a chunk are what this test is about: some must have occurred.
    assert silent >= 1 and told
