"""Chunks encoded outside the HDF5 library: the library's own bytes, a file any netCDF-4 reader
opens with its checksums verified, and a sweep written that way holding the values of the
library-written file and of the in-memory result, bit for bit."""

from __future__ import annotations

import logging
import os
import signal
import zlib

import netCDF4
import numpy as np
import pytest

from cosserat_channel import netcdf_policy
from cosserat_channel import chunk_filters
from cosserat_channel.sweep import dataset, encode, engine, run_sweep, schedulers, writer
from cosserat_channel.sweep.spec import load_sweep
from support import LOCAL_CLUSTER, assert_identical

h5py = pytest.importorskip("h5py")

# 4 x 3 x 6 x 5 x 4 = 1440 points; eps L = 1/3 three ways, so triples serve several points.
GRID = {"eps": [1 / 30, 1 / 15, 1 / 60, 0.1], "L": [5.0, 10.0, 20.0],
        "K": {"linspace": [0, 3, 6]}, "A": {"linspace": [0.1, 1.5, 5]},
        "N": {"linspace": [1.0, 2.0, 4]}}
VARIABLES = ["Delta", "slip", "m_wall", "xi_p", "stage1_steps"]


def fletcher32_reference(data: bytes) -> int:
    """HDF5's H5_checksum_fletcher32 as its C source reads, one word at a time."""
    sum1 = sum2 = 0
    words = len(data) // 2
    i = 0
    while words:
        t = min(words, 360)
        words -= t
        for _ in range(t):
            sum1 = (sum1 + (data[i] << 8 | data[i + 1])) & 0xFFFFFFFF
            sum2 = (sum2 + sum1) & 0xFFFFFFFF
            i += 2
        sum1 = (sum1 & 0xFFFF) + (sum1 >> 16)
        sum2 = (sum2 & 0xFFFF) + (sum2 >> 16)
    if len(data) % 2:
        sum1 += data[i] << 8
        sum2 += sum1
        sum1 = (sum1 & 0xFFFF) + (sum1 >> 16)
        sum2 = (sum2 & 0xFFFF) + (sum2 >> 16)
    sum1 = (sum1 & 0xFFFF) + (sum1 >> 16)
    sum2 = (sum2 & 0xFFFF) + (sum2 >> 16)
    return sum2 << 16 | sum1


@pytest.mark.parametrize("size", [0, 1, 2, 719, 720, 721, 1441, 5000])
def test_fletcher32_is_hdf5s(size):
    """The checksum of random bytes, of all-0xff bytes (sums that fold to 0xffff) and of zeros,
    odd lengths and block boundaries (360 words) included, is HDF5's C loop's."""
    rng = np.random.default_rng(size)
    for data in (rng.integers(0, 256, size, dtype=np.uint8), np.full(size, 255, np.uint8),
                 np.zeros(size, np.uint8)):
        assert chunk_filters.fletcher32(data) == fletcher32_reference(data.tobytes())


def test_shuffle_groups_bytes_by_significance():
    data = np.arange(8 * 5 + 3, dtype=np.uint8)
    for itemsize in (2, 4, 8):
        got = chunk_filters.shuffle(data, itemsize)
        whole = data.size // itemsize * itemsize
        assert np.array_equal(got[:whole], data[:whole].reshape(-1, itemsize).T.ravel())
        assert np.array_equal(got[whole:], data[whole:])
    assert chunk_filters.shuffle(data, 1) is data


FLETCHER, SHUFFLE8, DEFLATE1 = ((3, ()), (2, (8,)), (1, (1,)))


@pytest.mark.parametrize("pipeline", [(FLETCHER, SHUFFLE8, DEFLATE1), (FLETCHER, SHUFFLE8),
                                      (FLETCHER,), (FLETCHER, (2, ()), DEFLATE1),
                                      (SHUFFLE8, DEFLATE1), (SHUFFLE8, FLETCHER), (DEFLATE1,), ()])
@pytest.mark.parametrize("shape", [(1, 1, 1, 1, 1), (2, 3, 5, 3, 4), (3, 1, 97, 1, 2)])
def test_a_chunk_encoded_from_its_place_in_the_tile_is_the_padded_chunk_encoded(shape, pipeline):
    """encode_part, which reads a chunk's values where they lie in the tile (strided, broadcast
    along an axis, an edge chunk's smaller box), gives the bytes of the padded chunk copied out
    and encoded filter by filter: random bits (NaN included), all-0xff bytes (checksum sums that
    fold to 0xffff), 8-byte floats and integers, and 1- and 4-byte integers."""
    rng = np.random.default_rng(sum(shape))
    edge = tuple(max(1, n - 1) for n in shape)
    for dtype, fill in ((np.float64, np.nan), (np.int64, 0), (np.int8, -1), (np.int32, 7)):
        size = np.dtype(dtype).itemsize
        tiles = {"random": rng.integers(0, 256, (2,) + shape + (size,), dtype=np.uint8),
                 "0xff": np.full((2,) + shape + (size,), 255, dtype=np.uint8)}
        for kind, raw in tiles.items():
            tile = raw.view(dtype)[..., 0]
            views = {"whole": tile[0], "strided": tile.transpose(1, 2, 3, 4, 5, 0)[..., 1],
                     "edge": tile[0][tuple(slice(0, n) for n in edge)],
                     "broadcast": np.broadcast_to(tile[0][:, :, :1], shape)}
            for how, part in views.items():
                whole = np.full(shape, fill, dtype=dtype)
                whole[tuple(slice(0, n) for n in part.shape)] = part
                got = chunk_filters.encode_part(part, shape, fill, pipeline)
                want = chunk_filters.encode(whole, pipeline)
                if pipeline and pipeline[-1] == DEFLATE1:
                    got, want = zlib.decompress(got), zlib.decompress(want)
                assert got == want, (np.dtype(dtype).name, kind, how)


def test_deflate_is_a_zlib_stream_of_the_bytes():
    """Random bytes, a chunk of rows that repeat (deflated again by the level that finds long
    repeats when ISA-L's fast level shrinks it below REPETITIVE) and zlib's levels 0 and 6: every
    stream decompresses with zlib to the bytes given."""
    rng = np.random.default_rng(5)
    rows = np.repeat(rng.normal(size=(40, 1, 15)), 50, axis=1)
    for data in (rng.integers(0, 256, 100_000, dtype=np.uint8).tobytes(),
                 chunk_filters.shuffle(rows.view(np.uint8).ravel(), 8).tobytes()):
        for level in (0, 1, 6):
            for repeats in (False, True, lambda: True, lambda: False):
                assert zlib.decompress(chunk_filters.deflate(data, level, repeats)) == data


@pytest.mark.skipif(chunk_filters.DEFLATE == "zlib", reason="one deflate level without ISA-L")
def test_the_long_repeat_retry_is_for_chunks_constant_along_an_axis():
    """A chunk that the fast level shrinks below REPETITIVE is deflated again by the level that
    finds long repeats when it is constant along an axis (a full copy, not a broadcast view: the
    caller did not say so), smaller than the fast level's by more than half and no larger than
    when the caller says so; a chunk mostly of one value (NaN) that is constant along no axis
    keeps the fast level's bytes; a chunk of small integers that the fast level shrinks most
    keeps them too, the retry being larger."""
    rng = np.random.default_rng(3)
    shape = (4, 3, 50, 3, 5)
    pipeline = (FLETCHER, SHUFFLE8, DEFLATE1)
    unfiltered = (FLETCHER, SHUFFLE8)

    def fast(part):
        return chunk_filters.deflate(chunk_filters.encode(np.ascontiguousarray(part), unfiltered),
                                     1, lambda: False)

    along_K = np.repeat(rng.normal(size=(4, 3, 1, 3, 5)), 50, axis=2)
    assert chunk_filters.constant_along_an_axis(along_K)
    found = chunk_filters.encode_part(along_K, shape, np.nan, pipeline)
    told = chunk_filters.encode_part(np.broadcast_to(along_K[:, :, :1], shape), shape, np.nan,
                                     pipeline, repeats=True)
    assert len(found) <= len(told) < len(fast(along_K)) / 2
    mostly_nan = np.full(shape, np.nan)
    mostly_nan.flat[::97] = rng.normal(size=mostly_nan.flat[::97].size)
    assert not chunk_filters.constant_along_an_axis(mostly_nan)
    found = chunk_filters.encode_part(mostly_nan, shape, np.nan, pipeline)
    assert len(found) < chunk_filters.REPETITIVE * mostly_nan.nbytes
    assert found == fast(mostly_nan)
    assert zlib.decompress(found) == zlib.decompress(chunk_filters.encode(mostly_nan, pipeline))
    codes = np.broadcast_to(rng.integers(0, 3, (4, 3, 1, 3, 5)).astype(np.int8), shape)
    bytewise = (FLETCHER, (2, (1,)))
    told = chunk_filters.encode_part(codes, shape, -1, bytewise + (DEFLATE1,), repeats=True)
    plain = chunk_filters.encode(np.ascontiguousarray(codes), bytewise)
    assert told == chunk_filters.deflate(plain, 1, lambda: False)
    isal = chunk_filters._isal
    assert len(told) < len(isal.compress(plain, chunk_filters.ISAL_REPEATS, isal.COMP_ZLIB))


def _pipeline(ds):
    plist = ds.id.get_create_plist()
    return tuple((plist.get_filter(i)[0], tuple(int(v) for v in plist.get_filter(i)[2]))
                 for i in range(plist.get_nfilters()))


@pytest.mark.parametrize("compress", ["zlib", "none"])
def test_chunks_encoded_here_read_back_through_netcdf4_with_checksums(tmp_path, compress):
    """Variables netCDF4 creates under the package's policy; chunks encoded here and placed with
    H5Dwrite_chunk (edge chunks padded) read back through netCDF4 bit for bit, NaN included;
    each chunk's checksum and decompressed bytes are those the library writes for the same
    values; and a flipped byte in a placed chunk fails to read instead of changing a value."""
    rng = np.random.default_rng(1)
    shape, chunks = (5, 3, 7, 4, 2), (2, 2, 4, 3, 2)
    values = {"f": np.cumsum(rng.normal(size=shape), axis=2),
              "s": rng.integers(-3, 9, shape).astype(np.int8),
              "c": rng.integers(0, 10**6, shape).astype(np.int32)}
    values["f"][0, 0, 0, 0, 0] = np.nan
    paths = {}
    for how in ("library", "here"):
        paths[how] = tmp_path / f"{how}.nc"
        with netCDF4.Dataset(paths[how], "w") as nc:
            dims = tuple(f"d{i}" for i in range(len(shape)))
            for d, n in zip(dims, shape):
                nc.createDimension(d, n)
            for name, v in values.items():
                enc = dict(netcdf_policy.variable_encoding(shape, v.dtype,
                                                                  compress=compress),
                           chunksizes=chunks)
                if compress == "zlib":
                    enc.update(zlib=True, complevel=1, shuffle=True)
                var = netcdf_policy.create_variable(nc, name, v.dtype, dims, enc)
                if how == "library":
                    var[:] = v
    with h5py.File(paths["here"], "r+") as f:
        for name, v in values.items():
            ds = f[name]
            layout = encode.Layout(tuple(ds.chunks), _pipeline(ds), ds.fillvalue)
            assert chunk_filters.supported(layout.pipeline)
            assert layout.pipeline[0][0] == chunk_filters.FILTER_FLETCHER32
            job = encode.TileJob(None, None, (0,) * 5, {}, None, {name: layout})
            for _, offset, data in _encode_values(job, name, v):
                ds.id.write_direct_chunk(offset, data)
    with netCDF4.Dataset(paths["here"]) as nc:
        for name, v in values.items():
            assert nc[name].filters()["fletcher32"]
            got = nc[name][:]
            assert got.dtype == v.dtype and np.array_equal(got, v, equal_nan=True), name
    # The bytes the library stores: the same checksum over the same (padded) chunk.
    with h5py.File(paths["library"], "r") as lib, h5py.File(paths["here"], "r") as here:
        for name in values:
            for index in np.ndindex(*(-(-n // c) for n, c in zip(shape, chunks))):
                offset = tuple(i * c for i, c in zip(index, chunks))
                a = lib[name].id.read_direct_chunk(offset)[1]
                b = here[name].id.read_direct_chunk(offset)[1]
                if compress == "zlib":
                    a, b = zlib.decompress(a), zlib.decompress(b)
                assert a == b, (name, offset)
    # A damaged chunk is refused on reading.
    with h5py.File(paths["here"], "r") as f:
        offset = f["f"].id.get_chunk_info(0).byte_offset
    raw = bytearray(paths["here"].read_bytes())
    raw[offset + 3] ^= 0x40
    paths["here"].write_bytes(bytes(raw))
    with netCDF4.Dataset(paths["here"]) as nc, pytest.raises(RuntimeError):
        nc["f"][:]


def _encode_values(job, name, value):
    """:func:`encode.encode_tile`'s chunk loop on given values (no derivation)."""
    layout = job.layouts[name]
    out = []
    for index in np.ndindex(*(-(-n // c) for n, c in zip(value.shape, layout.chunks))):
        lo = tuple(i * c for i, c in zip(index, layout.chunks))
        part = value[tuple(slice(a, a + c) for a, c in zip(lo, layout.chunks))]
        whole = np.full(layout.chunks, layout.fill, dtype=value.dtype)
        whole[tuple(slice(0, s) for s in part.shape)] = part
        out.append((name, lo, chunk_filters.encode(whole, layout.pipeline)))
    return out


def _small_tiles(monkeypatch, chunks=(1, 2, 3, 2, 2)):
    """Many tiles of few chunks, the file chunked (and compressed) to match."""
    monkeypatch.setattr(writer, "TILE_POINTS", 48)
    monkeypatch.setattr(writer, "chunk_shape", lambda shape, size: chunks)
    monkeypatch.setattr(dataset, "chunk_shape", lambda shape, size, target=None: chunks)
    monkeypatch.setattr(netcdf_policy, "MIN_COMPRESSED", 0)


def _written_by(caplog) -> str:
    phase = next(r for r in caplog.records if "solving threads" in r.msg)
    return phase.getMessage()


@pytest.mark.parametrize("reduce", [True, False])
@pytest.mark.parametrize("compress", ["zlib", "none"])
def test_encoded_file_equals_the_library_written_file_and_memory(tmp_path, monkeypatch, caplog,
                                                                 reduce, compress):
    """Dozens of tiles, edge chunks, every variable type (float64, int8 status, int32 counter):
    the file whose chunks were encoded in the solving threads' pool holds, read through netCDF4
    (checksums verified) and xarray, the values of the file netCDF4 writes itself and of the
    in-memory result, bit for bit, with the same filters and chunks."""
    _small_tiles(monkeypatch)
    spec = load_sweep({"grid": GRID, "output": {"variables": VARIABLES}})
    out = tmp_path / "direct.nc"
    with caplog.at_level(logging.INFO, logger="cosserat_channel.sweep"):
        run_sweep(spec, out, workers=2, block_size=7, reduce=reduce, compress=compress).close()
    assert "encoded where solved" in _written_by(caplog)
    caplog.clear()
    # The library's own writing: the same run without an encoder.
    monkeypatch.setattr(engine, "LocalEncoder", lambda n: None)
    lib = tmp_path / "library.nc"
    with caplog.at_level(logging.INFO, logger="cosserat_channel.sweep"):
        run_sweep(spec, lib, workers=2, block_size=7, reduce=reduce, compress=compress).close()
    assert "by the writer" in _written_by(caplog)
    plan = engine.Plan(spec.coords(), reduce=reduce, block_size=7,
                       tile=engine._tile(spec, None, out))
    assert len(plan.groups) > 3
    with netCDF4.Dataset(out) as a, netCDF4.Dataset(lib) as b:
        assert list(a.variables) == list(b.variables)
        for name in b.variables:
            va, vb = a[name][:], b[name][:]
            assert va.dtype == vb.dtype, name
            assert va.tobytes() == vb.tobytes(), name
            assert a[name].filters() == b[name].filters(), name
            assert a[name].chunking() == b[name].chunking(), name
            assert {k: a[name].getncattr(k) for k in a[name].ncattrs()}.keys() == \
                {k: b[name].getncattr(k) for k in b[name].ncattrs()}.keys()
    assert_identical(out, run_sweep(spec, workers=1, reduce=reduce))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["direct.nc", "library.nc"]


def test_profiles_and_unaligned_chunks_are_written_by_the_library(tmp_path, monkeypatch, caplog):
    """Profiles (chunks of their own, across tiles) go through netCDF4 as before: same values."""
    monkeypatch.setattr(writer, "TILE_POINTS", 16)
    spec = load_sweep({"grid": GRID, "output": {"variables": ["Delta"], "profile_points": 3}})
    out = tmp_path / "p.nc"
    with caplog.at_level(logging.INFO, logger="cosserat_channel.sweep"):
        run_sweep(spec, out, workers=2, block_size=7).close()
    assert "by the writer" in _written_by(caplog)
    assert_identical(out, run_sweep(spec, workers=1))


def test_a_failed_encoding_ends_the_run_and_the_rerun_writes_the_file(tmp_path, monkeypatch):
    """An encoding task that fails (here: the third tile) ends the run with that error, the
    unfinished file deleted and every block kept; the rerun solves nothing and writes the file."""
    _small_tiles(monkeypatch)
    spec = load_sweep({"grid": GRID, "output": {"variables": ["Delta", "slip"]}})
    out = tmp_path / "r.nc"
    real, calls = encode.encode_tile, []

    def failing(job):
        calls.append(1)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return real(job)

    monkeypatch.setattr(encode, "encode_tile", failing)
    with pytest.raises(Exception, match="No space left on device"):
        run_sweep(spec, out, workers=2, block_size=7)
    assert not out.exists()
    store = tmp_path / "r.nc.partial"
    assert not list(store.glob("*.tmp"))
    monkeypatch.setattr(encode, "encode_tile", real)
    with run_sweep(spec, out, workers=2, block_size=7) as ds:
        ds.load()
    assert_identical(out, run_sweep(spec, workers=1))


KILLED = """
import os, signal, sys
from cosserat_channel import netcdf_policy
from cosserat_channel.sweep import dataset, run_sweep, writer
chunks = (1, 2, 3, 2, 2)
writer.TILE_POINTS = 48
writer.chunk_shape = lambda shape, size: chunks
dataset.chunk_shape = lambda shape, size, target=None: chunks
netcdf_policy.MIN_COMPRESSED = 0
real, placed = writer.StreamWriter._place_oldest, []
def place(self):
    real(self)
    placed.append(1)
    if len(placed) == 3:
        os.kill(os.getpid(), signal.SIGKILL)
writer.StreamWriter._place_oldest = place
run_sweep(sys.argv[1], sys.argv[2], workers=2, block_size=7, overwrite=True)
"""


def test_killed_while_placing_chunks_then_rerun_is_identical(tmp_path, monkeypatch):
    """The process killed (SIGKILL) once three tiles' chunks are placed: the old file untouched,
    the unfinished file only inside the store; the rerun solves nothing and writes the whole
    file from the store."""
    import subprocess
    import sys

    import cosserat_channel

    _small_tiles(monkeypatch)
    sweep = tmp_path / "s.toml"
    axes = "\n".join(f"{d} = {v!r}".replace("'", '"').replace(":", " =")
                     for d, v in GRID.items())
    sweep.write_text(f"[grid]\n{axes}\n[output]\nvariables = [\"Delta\", \"slip\"]\n")
    spec = load_sweep(str(sweep))
    out = tmp_path / "r.nc"
    out.write_bytes(b"an earlier result")
    src = os.path.dirname(os.path.dirname(os.path.abspath(cosserat_channel.__file__)))
    proc = subprocess.run([sys.executable, "-c", KILLED, str(sweep), str(out)],
                          capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, PYTHONPATH=src))
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert out.read_bytes() == b"an earlier result"
    store = tmp_path / "r.nc.partial"
    assert list(store.glob(".*.tmp"))  # the file being written, left by the kill
    with run_sweep(spec, out, workers=2, block_size=7, overwrite=True) as ds:
        ds.load()
    assert not store.exists()
    assert_identical(out, run_sweep(spec, workers=1))


def test_cluster_workers_encode_and_one_lost_mid_encode_changes_nothing(tmp_path, monkeypatch,
                                                                       caplog):
    """With a dask.distributed cluster the tiles are derived and encoded on its workers; every
    worker killed while the first tile is being encoded: the task runs again on the new
    workers, the file holds the in-memory values."""
    distributed = pytest.importorskip("dask.distributed")
    _small_tiles(monkeypatch)
    spec = load_sweep({"grid": GRID, "output": {"variables": ["Delta", "slip", "m_wall"]}})
    out = tmp_path / "d.nc"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  **LOCAL_CLUSTER) as cluster, \
            distributed.Client(cluster) as client:
        pids = set(client.run(os.getpid).values())
        real_submit = schedulers.ClusterEncoder.submit
        lost = []

        def submit(self, function, job):
            fut = real_submit(self, function, job)
            if not lost:
                lost.append(1)
                for pid in pids:
                    os.kill(pid, signal.SIGKILL)
            return fut

        monkeypatch.setattr(schedulers.ClusterEncoder, "submit", submit)
        with caplog.at_level(logging.INFO, logger="cosserat_channel.sweep"):
            run_sweep(spec, out, scheduler=client, block_size=7).close()
        assert lost
    assert "encoded where solved" in _written_by(caplog)
    assert_identical(out, run_sweep(spec, workers=1))


@pytest.mark.parametrize("reduce", [True, False])
def test_a_box_of_a_tile_derives_the_values_of_that_box_of_the_grid(reduce):
    """grid_values on a box of a tile (TileGrid.box, reading the tile's own rows) is, bit for bit,
    grid_values on the same box of the whole grid (a Region of the plan): boxes at every offset,
    those that reach the tile's edge and those smaller than a chunk along some axes included."""
    spec = load_sweep({"grid": GRID, "output": {"variables": VARIABLES}})
    plan = engine.Plan(spec.coords(), reduce=reduce, block_size=7)
    rng = np.random.default_rng(7)
    res = rng.normal(size=(plan.n_triples, dataset.layout.N_R))
    res[:, dataset.layout.R_STATUS] = rng.integers(0, 3, plan.n_triples)
    per_triple = {"res": res, "steps": rng.integers(0, 500, (plan.n_triples, 2))}
    one_minus = rng.uniform(0.01, 1.0, plan.shape)
    tile = (slice(1, 4), slice(0, 3), slice(1, 6), slice(2, 5), slice(1, 4))
    job = encode.tile_job(spec, plan.region(tile), per_triple, one_minus[tile], {})
    for box in [(slice(0, 3), slice(0, 3), slice(0, 5), slice(0, 3), slice(0, 3)),
                (slice(1, 3), slice(2, 3), slice(3, 5), slice(0, 2), slice(2, 3)),
                (slice(2, 3), slice(0, 2), slice(0, 1), slice(1, 3), slice(0, 3))]:
        part = job.grid.box(box)
        grid_box = tuple(slice(t.start + b.start, t.start + b.stop) for t, b in zip(tile, box))
        for spread in (True, False):
            got = dataset.grid_values(spec, part, job.per_triple, job.one_minus[box],
                                      spread=spread)
            want = dataset.grid_values(spec, plan.region(grid_box), per_triple,
                                       one_minus[grid_box], spread=spread)
            assert list(got) == list(want)
            for name in want:
                a, b = np.asarray(got[name][1]), np.asarray(want[name][1])
                assert a.shape == b.shape and a.dtype == b.dtype, name
                assert a.tobytes() == b.tobytes(), (name, box, spread)


@pytest.mark.parametrize("reduce", [True, False])
def test_chunks_that_end_inside_a_tile_along_K_are_encoded_whole(tmp_path, monkeypatch, caplog,
                                                                 reduce):
    """Chunks of 4 along a K of 6 (every tile holds a column of chunks whose last ends at the
    grid's edge) and of 3 along an N of 4: every chunk stored, the K-constant variables' included
    (encoded once, placed at each K position), is the one netCDF4 stores itself, padding and
    checksum included, and the file holds the in-memory values bit for bit."""
    chunks = (1, 2, 4, 2, 3)
    _small_tiles(monkeypatch, chunks=chunks)
    spec = load_sweep({"grid": GRID, "output": {"variables": VARIABLES + ["sigma_yx_wall"]}})
    out = tmp_path / "k.nc"
    with caplog.at_level(logging.INFO, logger="cosserat_channel.sweep"):
        run_sweep(spec, out, workers=2, block_size=7, reduce=reduce).close()
    assert "encoded where solved" in _written_by(caplog)
    monkeypatch.setattr(engine, "LocalEncoder", lambda n: None)
    lib = tmp_path / "library.nc"
    run_sweep(spec, lib, workers=2, block_size=7, reduce=reduce).close()
    with h5py.File(out, "r") as a, h5py.File(lib, "r") as b:
        for name in ["status", *spec.variables]:
            assert a[name].chunks == b[name].chunks == chunks
            for index in np.ndindex(*(-(-n // c) for n, c in zip(a[name].shape, chunks))):
                offset = tuple(i * c for i, c in zip(index, chunks))
                got = zlib.decompress(a[name].id.read_direct_chunk(offset)[1])
                assert got == zlib.decompress(b[name].id.read_direct_chunk(offset)[1]), \
                    (name, offset)
    assert_identical(out, run_sweep(spec, workers=1, reduce=reduce))
