"""The result file written tile by tile: the same bits as the in-memory result, read-friendly
chunks, and the disk space checked before any work."""

from __future__ import annotations

import math

import netCDF4
import numpy as np
import pytest

from cosserat_channel import cli
from cosserat_channel import files
from cosserat_channel.sweep import engine, run_sweep, writer
from cosserat_channel.sweep.dataset import chunk_shape
from cosserat_channel.sweep.spec import SweepError, load_sweep
from cosserat_channel.sweep.store import partial_dir

# 4 x 3 x 3 x 2 x 3 = 216 points; eps L = 1/3 three ways, so triples serve several points.
GRID = {"eps": [1 / 30, 1 / 15, 1 / 60, 0.1], "L": [5.0, 10.0, 20.0], "K": [0.0, 0.5, 3.0],
        "A": [1 / 3, 1.0], "N": [1.0, 1.5, 2.0]}


def test_tiles_locate_every_point_in_its_box():
    """Every grid index lands in the tile whose box holds it, at its C-order place in that box,
    edge tiles (smaller) included."""
    shape = (7, 5, 4, 3, 6)
    tiles = writer.Tiles.__new__(writer.Tiles)
    tiles.shape, tiles.tile = shape, (3, 2, 4, 3, 6)
    tiles.grid = tuple(-(-n // t) for n, t in zip(shape, tiles.tile))
    tiles.count = math.prod(tiles.grid)
    flat = np.arange(math.prod(shape))
    tile, local = tiles.locate(flat)
    grid = flat.reshape(shape)
    seen = 0
    for i in range(tiles.count):
        box = grid[tiles.slices(i)]
        assert np.array_equal(flat[tile == i][np.argsort(local[tile == i])], box.ravel())
        seen += box.size
    assert seen == flat.size and tiles.count == 3 * 3


@pytest.mark.parametrize("reduce", [True, False])
def test_file_written_in_many_tiles_equals_the_in_memory_result(tmp_path, monkeypatch, reduce):
    """Tiny tiles (dozens of them, with profiles and counters) give the in-memory values to the
    last bit, and the file's chunks are chunk_shape's."""
    monkeypatch.setattr(writer, "TILE_POINTS", 16)
    monkeypatch.setattr(writer, "chunk_shape", lambda shape, size: (1, 2, 2, 1, 2))
    spec = load_sweep({"grid": GRID, "output": {
        "variables": ["Delta", "slip", "xi_p", "stage1_steps"], "profile_points": 4}})
    out = tmp_path / "r.nc"
    with run_sweep(spec, out, workers=2, block_size=5, reduce=reduce) as ds:
        ds.load()
    ref = run_sweep(spec, workers=1, reduce=reduce)
    assert set(ds.data_vars) == set(ref.data_vars)
    for v in ref.data_vars:
        assert ds[v].dtype == ref[v].dtype, v
        assert np.array_equal(ds[v].values, ref[v].values, equal_nan=True), v
    assert not (tmp_path / "r.nc.partial").exists()


def test_chunks_serve_a_slice_and_a_curve():
    """A 10^8-point grid: an A x N slice and a curve along eps each read a few MB, not a slab."""
    shape = (100, 100, 100, 10, 10)
    c = chunk_shape(shape, 8)
    assert math.prod(c) * 8 <= 1 << 20
    slice_chunks = math.ceil(shape[3] / c[3]) * math.ceil(shape[4] / c[4])
    curve_chunks = math.ceil(shape[0] / c[0])
    assert slice_chunks * math.prod(c) * 8 < 16 << 20
    assert curve_chunks * math.prod(c) * 8 < 8 << 20


def test_large_file_has_those_chunks(tmp_path):
    out = tmp_path / "c.nc"
    grid = {**GRID, "K": {"linspace": [0, 3, 30]}, "A": {"linspace": [0, 1, 10]}}
    run_sweep({"grid": grid, "output": {"variables": ["slip"]}}, out, workers=2).close()
    with netCDF4.Dataset(out) as nc:
        shape = nc["slip"].shape
        assert nc["slip"].chunking() == list(chunk_shape(shape, 8))
        assert nc["slip"].filters()["fletcher32"]


def test_too_little_disk_space_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """The estimate exceeds the free space: one line naming the need and the space, exit 2,
    no store, nothing solved."""
    toml = tmp_path / "s.toml"
    toml.write_text("[grid]\neps = [0.02, 0.05]\nL = [5.0, 10.0]\nK = 0.5\nA = 1.0\nN = 1.0\n")
    real = files.shutil.disk_usage
    monkeypatch.setattr(files.shutil, "disk_usage",
                        lambda p: real(p)._replace(free=100))
    monkeypatch.setattr(engine, "_run", lambda *a, **k: pytest.fail("computed anyway"))
    out = tmp_path / "out.nc"
    assert cli.main(["run", str(toml), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "disk space" in err and "100 B free" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
    with pytest.raises(SweepError, match="disk space"):
        run_sweep(str(toml), str(out))
    assert not (tmp_path / partial_dir("out.nc")).exists()


def test_disk_estimate_grows_with_the_grid_and_counts_what_is_stored():
    spec = load_sweep({"grid": GRID, "output": {"variables": ["Delta", "slip"]}})
    plan = engine.Plan(spec.coords())
    need = engine.disk_needed(spec, plan, None, "/nonexistent/out.nc")
    assert need >= spec.size * (8 + 8 + 1)  # two float64 outputs and status, uncompressed
    big = load_sweep({"grid": {**GRID, "K": {"linspace": [0, 3, 300]}},
                      "output": {"variables": ["Delta", "slip"]}})
    assert engine.disk_needed(big, engine.Plan(big.coords()), None, "/x") > 50 * need
