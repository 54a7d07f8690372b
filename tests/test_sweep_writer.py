"""The result file written tile by tile: the same bits as the in-memory result, read-friendly
chunks, and the disk space checked before any work."""

from __future__ import annotations

import math
import time

import netCDF4
import numpy as np
import pytest

from cosserat_channel import cli
from cosserat_channel import files
from cosserat_channel.sweep import block, budget, engine, run_sweep, writer
from cosserat_channel.sweep.dataset import chunk_shape, variable_encoding
from cosserat_channel.sweep.plan import block_plan
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


def test_mapped_per_triple_arrays_give_the_in_memory_values(tmp_path, monkeypatch):
    """Beyond WRITER_MEMORY the writer's per-integration arrays are mapped onto unlinked files in
    the store (memory then follows the groups being written): the file holds the in-memory
    values to the last bit, the disk estimate counts the mapped bytes, nothing is left."""
    monkeypatch.setattr(writer, "TILE_POINTS", 16)
    spec = load_sweep({"grid": GRID, "output": {
        "variables": ["Delta", "slip", "stage1_steps"], "profile_points": 4}})
    xi = engine._profile_xi(spec)
    kept = budget.disk_needed(spec, 72, xi, str(tmp_path / "r.nc"))
    monkeypatch.setattr(writer, "WRITER_MEMORY", 0)
    assert budget.disk_needed(spec, 72, xi, str(tmp_path / "r.nc")) == \
        kept + 72 * writer.bytes_per_triple(4)
    arrays = []
    real = writer.StreamWriter._array
    monkeypatch.setattr(writer.StreamWriter, "_array", lambda self, *a: (
        arrays.append(real(self, *a)), arrays[-1])[1])
    out = tmp_path / "r.nc"
    with run_sweep(spec, out, workers=2, block_size=5) as ds:
        ds.load()
    assert len(arrays) == 3 and all(isinstance(a, np.memmap) for a in arrays)
    ref = run_sweep(spec, workers=1)
    for v in ref.data_vars:
        assert np.array_equal(ds[v].values, ref[v].values, equal_nan=True), v
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc"]


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
        assert nc["status"].chunking() == nc["slip"].chunking()


@pytest.mark.parametrize("compress, filters", [
    (None, {"zstd": False, "zlib": True, "complevel": 1, "shuffle": True}),  # the default
    ("zstd", {"zstd": True, "zlib": False, "complevel": -1}),
    ("none", {"zstd": False, "zlib": False}),
])
def test_codec_of_the_file_and_its_values_read_back_identically(tmp_path, compress, filters):
    """The default codec is zlib level 1 with shuffle (README, netcdf_policy), ``"zstd"`` is
    Zstandard level -1, ``"none"`` raw chunks; each file reads back through xarray's netCDF4
    engine with the in-memory result's values, bit for bit."""
    xr = pytest.importorskip("xarray")
    out = tmp_path / "c.nc"
    grid = {**GRID, "K": {"linspace": [0, 3, 30]}, "A": {"linspace": [0, 1, 10]}}
    spec = load_sweep({"grid": grid, "output": {"variables": ["Delta", "slip", "m_wall"]}})
    run_sweep(spec, out, workers=2, compress=compress).close()
    with netCDF4.Dataset(out) as nc:
        for name in ("Delta", "slip", "m_wall", "status"):
            got = nc[name].filters()
            assert {k: got[k] for k in filters} == filters, name
            assert got["fletcher32"], name
    ref = run_sweep(spec, workers=1)
    with xr.open_dataset(out, engine="netcdf4") as ds:
        for v in ref.data_vars:
            assert ds[v].dtype == ref[v].dtype, v
            assert np.array_equal(ds[v].values, ref[v].values, equal_nan=True), v


def test_grid_variables_of_every_type_share_the_tiles_chunks():
    """int8 status and int32 counters are chunked like the float64 outputs, so that no chunk
    straddles two tiles (it would be compressed, and read back, once per tile)."""
    shape = (50, 40, 500, 10, 10)
    f8 = variable_encoding("Delta", shape, np.float64, False)["chunksizes"]
    assert f8 == chunk_shape(shape, 8) != chunk_shape(shape, 1)
    for name, dtype in (("status", np.int8), ("stage1_steps", np.int32)):
        assert variable_encoding(name, shape, dtype, False)["chunksizes"] == f8
    tiles = writer.Tiles(shape)
    assert all(t % c == 0 or t == n for t, c, n in zip(tiles.tile, f8, shape))


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
    need = budget.disk_needed(spec, plan.n_triples, None, "/nonexistent/out.nc")
    assert need >= spec.size * (8 + 8 + 1)  # two float64 outputs and status, uncompressed
    big = load_sweep({"grid": {**GRID, "K": {"linspace": [0, 3, 300]}},
                      "output": {"variables": ["Delta", "slip"]}})
    assert budget.disk_needed(big, engine.Plan(big.coords()).n_triples, None, "/x") > 50 * need


# ---------------------------------------------------------------------------------------------
# Tile-aligned blocks, and tiles written while the other blocks are solved
# ---------------------------------------------------------------------------------------------
# eps L = 1/3 is shared by (1/30, 10), (1/15, 5) and (1/60, 20): with one eps and one L per tile
# box, the boxes of those three pairs join one group; the other boxes stay groups of their own.
def _planned(reduce, tile):
    spec = load_sweep({"grid": GRID})
    return spec, engine.Plan(spec.coords(), reduce=reduce, block_size=5, tile=tile)


@pytest.mark.parametrize("reduce, tile", [(True, (1, 1, 3, 1, 2)), (True, (2, 2, 3, 2, 3)),
                                          (True, (1, 1, 2, 1, 3)), (False, (1, 2, 2, 1, 2))])
def test_groups_hold_every_point_of_their_blocks(reduce, tile):
    """Each block's points lie in the tiles of its group, the groups cut the tile grid into
    disjoint sets, and plan.tile_local agrees with Tiles.locate."""
    spec, plan = _planned(reduce, tile)
    tiles = writer.Tiles.__new__(writer.Tiles)
    tiles.shape, tiles.tile = spec.shape, tile
    tiles.grid = tuple(-(-n // t) for n, t in zip(spec.shape, tile))
    tiles.count = math.prod(tiles.grid)
    members = np.concatenate(plan.groups)
    assert np.array_equal(np.sort(members), np.arange(tiles.count))
    covered = np.zeros(spec.size, dtype=int)
    for k in range(len(plan.blocks)):
        flat = plan.inputs(k).flat
        covered[flat] += 1
        where, local = tiles.locate(flat)
        assert np.isin(where, plan.groups[plan.block_group[k]]).all(), k
        fast = plan.tile_local(k)
        if fast is not None:
            assert np.array_equal(fast[0], where) and np.array_equal(fast[1], local), k
    assert (covered == 1).all()
    if reduce and tile[2] < spec.shape[2]:  # tiles split K: a triple spans them, one group
        assert len(plan.groups) == 1 and plan.tile_local(0) is None
    elif not reduce:  # every point its own triple: every tile its own group
        assert len(plan.groups) == tiles.count
    elif tile[:2] == (1, 1):
        # 12 (eps, L) boxes times 2 x 2 (A, N) boxes, less those joined by a shared eps L
        assert 1 < len(plan.groups) < 12 * 2 * 2


def test_one_group_plans_the_blocks_as_before():
    """A tile as large as the grid gives the snake deal over the whole grid (and its digest):
    stores of runs planned that way stay valid."""
    spec = load_sweep({"grid": GRID})
    whole = engine.Plan(spec.coords(), block_size=5, tile=spec.shape)
    none = engine.Plan(spec.coords(), block_size=5)
    ref = block_plan(none.costs(), 5)
    assert len(whole.groups) == 1
    assert all(np.array_equal(a, b) for a, b in zip(whole.blocks, ref))
    assert whole.digest() == none.digest()


@pytest.mark.parametrize("pending, group_points", [(1 << 30, 1 << 30), (0, 1 << 30), (0, 0)])
def test_streamed_file_equals_the_in_memory_result(tmp_path, monkeypatch, pending, group_points):
    """Many groups of small tiles; the plug-edge values taken as solved, read back from the
    store (nothing kept in memory) or regrouped through bucket files: the in-memory values to
    the last bit."""
    monkeypatch.setattr(writer, "TILE_POINTS", 16)
    monkeypatch.setattr(writer, "chunk_shape", lambda shape, size: (1, 1, 2, 1, 2))
    monkeypatch.setattr(writer, "PENDING_BYTES", pending)
    monkeypatch.setattr(writer, "GROUP_POINTS", group_points)
    reads = []
    real_get = engine.WorkStore.get
    monkeypatch.setattr(engine.WorkStore, "get", lambda self, k, t=None: (
        reads.append(k), real_get(self, k, t))[1])
    spec = load_sweep({"grid": GRID, "output": {"variables": ["Delta", "slip", "m_wall"]}})
    out = tmp_path / "r.nc"
    with run_sweep(spec, out, workers=2, block_size=3) as ds:
        ds.load()
    read_back = len(reads)
    ref = run_sweep(spec, workers=1)
    for v in ref.data_vars:
        assert np.array_equal(ds[v].values, ref[v].values, equal_nan=True), v
    blocks = engine.Plan(spec.coords(), block_size=3, tile=engine._tile(spec, None, out)).blocks
    # Blocks solved in this process are read back only when they were not kept in memory.
    assert read_back == (0 if pending else len(blocks))
    assert not (tmp_path / "r.nc.partial").exists()


def test_tiles_are_written_while_blocks_are_still_solved(tmp_path, monkeypatch):
    """The first group's tiles reach the file before the last block is solved."""
    monkeypatch.setattr(writer, "TILE_POINTS", 16)
    monkeypatch.setattr(writer, "chunk_shape", lambda shape, size: (1, 1, 3, 2, 3))
    events = []
    real_solve, real_write = block.solve_block, writer.StreamWriter._write_group

    def slow_solve(*args, **kwargs):
        out = real_solve(*args, **kwargs)
        time.sleep(0.05)  # leaves the writer's thread time to run even on a loaded machine
        events.append("solved")
        return out

    def write_group(self, g):
        events.append("write")
        real_write(self, g)

    monkeypatch.setattr(block, "solve_block", slow_solve)
    monkeypatch.setattr(writer.StreamWriter, "_write_group", write_group)
    spec = load_sweep({"grid": GRID})
    run_sweep(spec, tmp_path / "r.nc", workers=1, block_size=2).close()
    plan = engine.Plan(spec.coords(), block_size=2, tile=engine._tile(spec, None, "r.nc"))
    assert len(plan.groups) > 3
    assert events.count("write") == len(plan.groups)
    assert events.index("write") < len(events) - 1 - events[::-1].index("solved")


def test_a_failed_write_keeps_the_blocks_and_leaves_no_file(tmp_path, monkeypatch):
    """HDF5 failing mid-run (a full disk): one WriteError naming the output, the earlier file
    untouched, no temporary file, every block kept; the rerun writes the file from the store."""
    monkeypatch.setattr(writer, "TILE_POINTS", 16)
    monkeypatch.setattr(writer, "chunk_shape", lambda shape, size: (1, 1, 3, 2, 3))
    spec = load_sweep({"grid": GRID, "output": {"variables": ["Delta"]}})
    out = tmp_path / "r.nc"
    out.write_bytes(b"an earlier result")
    real = writer.create_variables

    def fail(*args, **kwargs):
        raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(writer, "create_variables", fail)
    with pytest.raises(files.WriteError, match="cannot write .*r.nc.*HDF error"):
        run_sweep(spec, out, workers=2, block_size=2, overwrite=True)
    assert out.read_bytes() == b"an earlier result"
    store = tmp_path / "r.nc.partial"
    assert not list(store.glob("*.tmp")) and not list(tmp_path.glob(".*.tmp"))
    monkeypatch.setattr(writer, "create_variables", real)
    with run_sweep(spec, out, workers=2, block_size=2) as ds:
        ds.load()
    ref = run_sweep(spec, workers=1)
    assert np.array_equal(ds.Delta.values, ref.Delta.values, equal_nan=True)
