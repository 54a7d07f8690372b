"""The result file written tile by tile, so that memory follows the tile, not the grid.

A result variable is grid-sized (10^8 points of float64 are 800 MB), but everything it is derived
from is per *triple* (a few per cent of the points with the similarity reduction), except the
plug edge ``1 - xi_p``, which has one value per grid point. The file is cut into *tiles*
(:class:`Tiles`, boxes of whole chunks, spanning the whole ``K`` axis when that fits), the tiles
are joined into *groups* (:class:`.plan.Plan`: every triple's points lie in one group) and every
block holds triples of one group. :class:`StreamWriter` writes a group's tiles as soon as its
blocks are done, in a thread of its own while the other blocks are solved:

1. a finished block's per-triple arrays go into memory (:meth:`StreamWriter.add`), its
   ``1 - xi_p`` values too (as they came from the kernel: the store's copy is not read back)
   until its group is complete, or, past :data:`PENDING_BYTES`, are read back from the store
   (checked against its digest) when the group is written;
2. the group's values are placed in its tiles (in memory, one scatter per block; a group larger
   than :data:`GROUP_POINTS`, e.g. one that holds every tile because ``eta`` values are shared
   across the grid, goes through per-tile *bucket* files in ``scratch/`` instead);
3. each tile's values are derived by :func:`.dataset.grid_values` (the function the in-memory
   result uses, elementwise, hence the same bits) and its chunks encoded (checksum, shuffle,
   deflate, as HDF5 would) by :func:`.encode.encode_tile`, in parallel where the blocks are
   solved (a pool of threads beside the solving ones, or the cluster's workers); this thread
   only places the encoded chunks into the file (HDF5's direct chunk write, through h5py, into
   the variables ``netCDF4`` created). A file whose chunks cannot be encoded that way (profiles,
   whose chunks cross tiles; Zstandard, a filter plugin) is written through ``netCDF4`` here,
   each chunk compressed once by the HDF5 library.

The file is written under a temporary name inside the store and renamed when complete
(:meth:`.store.WorkStore.publish`); a killed run leaves only that temporary file, which the next run
deletes, and writes the whole file again from the stored blocks.
"""

from __future__ import annotations

import collections
import math
import os
import queue
import re
import shutil
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import netCDF4
import numpy as np

from .. import outputs as out_
from ..files import temp_path as _temp_path
from ..solver import layout
from ..files import write_failure
from ..parameters import DIMS
from .. import chunk_filters, netcdf_policy
from . import encode
from .dataset import chunk_shape, coordinates, global_attrs, grid_values, variable_encoding
from .store import BlockDamaged

# Points of one tile (times the profile length): its derived variables, a dozen grid-sized
# temporaries, stay near 200 MB.
TILE_POINTS = 1 << 21
# A tile spans the whole K axis (so that blocks can be tile-aligned, see .plan) when that makes
# it at most this many times TILE_POINTS.
WHOLE_K_FACTOR = 2
# Plug-edge values of finished blocks kept in memory until their group is written; beyond this,
# a group's blocks are read back from the store (blocks finishing out of group order).
PENDING_BYTES = 256 << 20
# A group with more points than this is regrouped through bucket files on disk, not in memory
# (its plug-edge values, 8 bytes a point, are held while its tiles are written: 256 MB).
GROUP_POINTS = 16 * TILE_POINTS
SCRATCH = "scratch"
BUCKET = np.dtype([("local", "<i4"), ("value", "<f8")])
# The per-integration arrays (StreamWriter.per_triple, .profiles) beyond this many bytes are
# mapped onto unlinked files in the store instead of held in memory: memory then follows the
# groups being written, and the system pages the rest out (10^8 integrations are 13.6 GB).
WRITER_MEMORY = 1 << 30


def bytes_per_triple(n_xi: int) -> int:
    """Bytes of :class:`StreamWriter`'s per-integration arrays for one integration."""
    return 8 * layout.N_R + 16 + 8 * layout.N_PROF * n_xi


class Tiles:
    """The grid cut into boxes of whole chunks (of :func:`.dataset.chunk_shape` for float64).

    Tiles are numbered in C order of the tile grid; :meth:`region` gives tile ``i`` as a
    :class:`.plan.Region`, :meth:`locate` the tile and the position inside it of grid points.
    """

    def __init__(self, shape, n_xi: int = 0):
        self.shape = tuple(int(n) for n in shape)
        chunks = chunk_shape(self.shape, 8)
        target = max(math.prod(chunks), TILE_POINTS // max(1, n_xi))
        tile = list(chunks)
        K = DIMS.index("K")
        whole_K = math.prod(chunks) // chunks[K] * self.shape[K] <= WHOLE_K_FACTOR * target
        if whole_K:
            tile[K] = self.shape[K]
        for i in reversed(range(len(tile))):  # grow along the trailing axes first (C order)
            if i == K and whole_K:
                continue
            rest = math.prod(tile) // tile[i]
            tile[i] = min(self.shape[i], chunks[i] * max(1, target // (rest * chunks[i])))
        self.tile = tuple(tile)
        self.grid = tuple(-(-n // t) for n, t in zip(self.shape, self.tile))
        self.count = math.prod(self.grid)

    def slices(self, i: int) -> tuple:
        """The box of tile ``i``: one slice per axis."""
        pos = np.unravel_index(i, self.grid)
        return tuple(slice(p * t, min(n, (p + 1) * t)) for p, t, n in zip(pos, self.tile, self.shape))

    def locate(self, flat: np.ndarray):
        """``(tile, local)`` of C-order grid indices ``flat``: the tile's number and the C-order
        index inside that tile (edge tiles are smaller)."""
        # Trailing axes a tile spans whole are one axis for this purpose: fewer passes over flat.
        j = len(self.shape)
        while j > 1 and self.tile[j - 1] == self.shape[j - 1]:
            j -= 1
        inner = math.prod(self.shape[j:])
        lead, rest = np.divmod(flat, inner)
        tile = np.zeros(flat.shape, dtype=np.int64)
        local = np.zeros(flat.shape, dtype=np.int64)
        for ix, t, g, n in zip(np.unravel_index(lead, self.shape[:j]), self.tile, self.grid,
                               self.shape):
            q, r = np.divmod(ix, t)
            tile = tile * g + q
            local = local * np.minimum(t, n - q * t) + r
        return tile, local * inner + rest


class Buckets:
    """Per-tile files of ``(local index, value)`` pairs: grid-sized values regrouped by tile on
    disk, with only one block in memory at a time."""

    def __init__(self, directory: str, tiles: Tiles):
        self.directory = directory
        self.tiles = tiles
        self._lock = threading.Lock()
        # Leftovers of a killed run are never trusted: the buckets are rebuilt from the blocks.
        shutil.rmtree(directory, ignore_errors=True)
        os.makedirs(directory)

    def _path(self, i: int) -> str:
        return os.path.join(self.directory, f"tile_{i:06d}.bin")

    def add(self, tile: np.ndarray, local: np.ndarray, values: np.ndarray) -> None:
        """Append ``values`` to the buckets of their tiles: ``(tile, local)`` of each value as
        :meth:`Tiles.locate` gives them."""
        # A small integer key sorts by radix (linear time) and stably.
        key = tile.astype(np.uint16) if self.tiles.count <= 1 << 16 else tile
        order = np.argsort(key, kind="stable")
        tile = tile[order]
        rec = np.empty(tile.size, dtype=BUCKET)
        rec["local"] = local[order]
        rec["value"] = values[order]
        bounds = np.flatnonzero(np.diff(tile)) + 1
        with self._lock:  # blocks are added from several threads (engine.assemble)
            for lo, hi in zip(np.concatenate(([0], bounds)), np.concatenate((bounds, [tile.size]))):
                with open(self._path(int(tile[lo])), "ab") as f:
                    f.write(rec[lo:hi].tobytes())

    def take(self, i: int, shape: tuple) -> np.ndarray:
        """Tile ``i``'s values on its box (every point is in exactly one block); the bucket file
        is deleted once read."""
        path = self._path(i)
        rec = np.fromfile(path, dtype=BUCKET)
        os.unlink(path)
        out = np.empty(math.prod(shape))
        seen = np.zeros(out.size, dtype=bool)
        seen[rec["local"]] = True
        if rec.size != out.size or not seen.all():  # a bug, never a user's error
            raise RuntimeError(f"tile {i}: {rec.size} plug-edge values for {out.size} points")
        out[rec["local"]] = rec["value"]
        return out.reshape(shape)

    def remove(self) -> None:
        shutil.rmtree(self.directory, ignore_errors=True)


def create_variables(nc, spec, plan, xi, sample: dict, compress: bool) -> None:
    """Dimensions, coordinates, global attributes and empty result variables of the file, with
    the encoding :func:`.dataset.variable_encoding` gives (as ``to_netcdf`` writes it).

    ``sample`` is one tile's :func:`.dataset.grid_values`: the variables' order, types and
    attributes.
    """
    nc.setncatts(global_attrs(spec, plan.reduce))
    for name, (dim, values, attrs) in coordinates(spec, xi).items():
        nc.createDimension(dim, values.size)
        _create(nc, name, (dim,), values.shape, values.dtype, attrs, True, compress)[:] = values
    for name, (dims, value, attrs) in sample.items():
        shape = plan.shape + ((xi.size,) if len(dims) > len(DIMS) else ())
        _create(nc, name, dims, shape, value.dtype, attrs, False, compress)


def _create(nc, name, dims, shape, dtype, attrs, is_coord, compress):
    enc = variable_encoding(name, shape, dtype, is_coord, compress)
    var = netcdf_policy.create_variable(nc, name, dtype, dims, enc)
    var.setncatts(attrs)
    return var


class StreamWriter:
    """The result file of a run, written group by group as the blocks finish (module docstring).

    Blocks are announced with :meth:`add` (from the solving threads, or the main thread on a
    cluster); a group complete is written by this object's thread, while other blocks are still
    being solved. :meth:`finish` writes what is left and closes the file (at :attr:`tmp`, inside
    the store, for the run to rename onto the output); :meth:`abort` stops and removes it.

    The file, its coordinates and its empty variables are made at once by ``netCDF4``. Then,
    when every result variable's chunks lie inside tiles and its filters are HDF5's built-in ones
    (:func:`cosserat_channel.chunk_filters.supported`), each tile is derived and its chunks encoded by ``encoder``
    (:func:`.encode.encode_tile` in the solving threads' pool or on the cluster's workers) and
    this object's thread only places the encoded chunks (h5py's ``write_direct_chunk``, which
    runs no filter again); otherwise the tiles are derived here and written through ``netCDF4``.

    Parameters
    ----------
    output : str
        The result file (named in errors).
    spec : SweepSpec
    plan : Plan
        Planned with ``tile=tiles.tile``.
    store : WorkStore
        The run's store: holds the temporary file, and every block (read back when needed).
    xi : ndarray or None
        Profile abscissae.
    tiles : Tiles
    compress : bool or str
        See :func:`.dataset.variable_encoding`.
    recompute : callable
        ``recompute(k)`` solves block ``k`` again and puts it into the store (a stored block
        found damaged when it is read back).
    encoder : object, optional
        ``encoder.submit(function, job)``: a future of ``function(job)`` (``.result()``), and
        ``encoder.slots``, how many tiles may be in flight. Without one, tiles are written
        through ``netCDF4`` in this object's thread.
    """

    def __init__(self, output, spec, plan, store, xi, tiles: Tiles, compress, recompute,
                 encoder=None):
        self.output, self.spec, self.plan, self.store = output, spec, plan, store
        self.xi, self.tiles, self.compress, self.recompute = xi, tiles, compress, recompute
        self.tmp = temp_path(store.directory, output)
        n = plan.n_triples
        mapped = n * bytes_per_triple(0 if xi is None else xi.size) > WRITER_MEMORY
        # Zeros, not empty: the rows of blocks not yet finished hold no garbage (a tile reads
        # only its own rows, once its blocks are stored).
        self.per_triple = {"res": self._array((n, layout.N_R), np.float64, mapped),
                           "steps": self._array((n, 2), np.int64, mapped)}
        self.profiles = None if xi is None else self._array((n, layout.N_PROF, xi.size),
                                                            np.float64, mapped)
        self.need_one_minus = out_.needs_plug_edge(spec.variables)
        self._left = np.bincount(plan.block_group, minlength=len(plan.groups))
        order = np.argsort(plan.block_group, kind="stable")
        bounds = np.searchsorted(plan.block_group[order], np.arange(len(plan.groups) + 1))
        self._blocks_of = [order[bounds[g]:bounds[g + 1]] for g in range(len(plan.groups))]
        self._pending: dict[int, np.ndarray] = {}
        self._pending_bytes = 0
        self._lock = threading.Lock()
        self._queue: queue.Queue = queue.Queue()
        self._stop = False
        self._error: BaseException | None = None
        self._nc = None  # the file open in netCDF4 (tiles written by the library)
        self._h5 = None  # or in h5py (encoded chunks placed)
        self._layouts: dict | None = None
        self.encoder = encoder
        self._inflight: collections.deque = collections.deque()
        self.tiles_written = 0
        self.busy = 0.0  # seconds this writer's thread spent placing, deriving and writing
        self.cpu = 0.0  # and its CPU seconds (the tile-deriving thread's not included)
        self.encode_cpu = 0.0  # CPU seconds of deriving and encoding tiles where they ran
        self._create()
        self._thread = threading.Thread(target=self._loop, name="cc-writer", daemon=True)
        self._thread.start()

    @property
    def direct(self) -> bool:
        """Whether the tiles are encoded by the encoder and placed as they are."""
        return self._layouts is not None

    def _create(self) -> None:
        """Make the file with its coordinates and empty variables; open it for the tiles."""
        # One point's values give the variables' names, order, types and attributes.
        one = self.plan.region((slice(0, 1),) * len(DIMS))
        with np.errstate(all="ignore"):
            sample = grid_values(self.spec, one, self.per_triple,
                                 np.zeros(one.shape) if self.need_one_minus else None, self.xi,
                                 self.profiles)
        try:
            with netCDF4.Dataset(self.tmp, "w", format="NETCDF4") as nc:
                create_variables(nc, self.spec, self.plan, self.xi, sample, self.compress)
            self._layouts = None if self.encoder is None else self._direct_layouts(list(sample))
            if self._layouts is not None:
                import h5py

                self._h5 = h5py.File(self.tmp, "r+")
            else:
                self._nc = netCDF4.Dataset(self.tmp, "a")
                self._nc.set_auto_maskandscale(False)
        except BaseException as exc:
            try:
                self._close()
            except (OSError, RuntimeError, ValueError):
                pass
            try:
                os.unlink(self.tmp)
            except OSError:
                pass
            if isinstance(exc, OSError) or type(exc) is RuntimeError:
                raise write_failure(self.output, exc) from None
            raise

    def _direct_layouts(self, names) -> dict | None:
        """``{name: Layout}`` of the result variables when every one can be encoded outside the
        library and its chunks lie inside tiles; None otherwise (or without h5py)."""
        try:
            import h5py
        except ImportError:
            return None
        layouts = {}
        with h5py.File(self.tmp, "r") as f:
            for name in names:
                ds = f[name]
                if ds.chunks is None:
                    return None
                plist = ds.id.get_create_plist()
                pipeline = tuple((plist.get_filter(i)[0], tuple(int(v) for v in
                                                                plist.get_filter(i)[2]))
                                 for i in range(plist.get_nfilters()))
                lay = encode.Layout(tuple(ds.chunks), pipeline, ds.fillvalue)
                if not (chunk_filters.supported(pipeline)
                        and encode.aligned(lay, self.tiles.tile, self.tiles.shape)):
                    return None
                layouts[name] = lay
        return layouts

    def _close(self) -> None:
        nc, h5 = self._nc, self._h5
        self._nc = self._h5 = None
        if nc is not None:
            nc.close()
        if h5 is not None:
            try:
                h5.close()
            except (OSError, RuntimeError, ValueError) as exc:
                raise hdf_error(exc) from None

    def _array(self, shape, dtype, mapped: bool) -> np.ndarray:
        """Zeros, in memory or mapped onto a file of the store that is unlinked at once (the
        mapping keeps its space while it lives; a killed run leaves nothing behind)."""
        if not mapped:
            return np.zeros(shape, dtype)
        path = temp_path(self.store.directory, "per-triple")
        array = np.memmap(path, dtype=dtype, mode="w+", shape=shape)
        try:
            os.unlink(path)
        except OSError:  # a system that cannot unlink an open file: the store's tidying does
            pass
        return array

    # -- called by the run ----------------------------------------------------------------------
    def add(self, k: int, block: dict | None = None) -> None:
        """Block ``k`` is finished: ``block`` its arrays as solved, or None to read them from the
        store (a block of an earlier run). Raises the writer's error if it has failed."""
        self._raise_if_failed()
        if block is None:
            block = self._read(k)
        triples = self.plan.blocks[k]
        self.per_triple["res"][triples] = block["res"]  # blocks hold disjoint triples
        self.per_triple["steps"][triples] = block["steps"]
        if self.profiles is not None:
            self.profiles[triples] = block["profiles"]
        g = int(self.plan.block_group[k])
        with self._lock:
            if self.need_one_minus:
                values = block["one_minus"]
                if self._pending_bytes + values.nbytes <= PENDING_BYTES:
                    self._pending[k] = values
                    self._pending_bytes += values.nbytes
            self._left[g] -= 1
            if self._left[g] == 0:
                self._queue.put(g)

    def finish(self) -> None:
        """Write the groups still queued and close the file; every block must have been added."""
        self._queue.put(None)
        self._thread.join()
        self._raise_if_failed()
        if self._left.any() or self.tiles_written != self.tiles.count:  # a bug, not a user's error
            raise RuntimeError(f"{self.tiles_written} of {self.tiles.count} tiles written, "
                               f"{int(self._left.sum())} blocks missing")
        try:
            self._close()
        except (OSError, RuntimeError) as exc:
            raise write_failure(self.output, exc) from None
        finally:
            self._nc = self._h5 = None

    def abort(self) -> None:
        """Stop the thread (after the group it is writing) and delete the unfinished file."""
        self._stop = True
        self._queue.put(None)
        self._thread.join()
        for fut in self._inflight:
            cancel = getattr(fut, "cancel", None)
            if cancel is not None:
                cancel()
        self._inflight.clear()
        try:
            self._close()
        except (OSError, RuntimeError, ValueError):
            pass
        finally:
            self._nc = self._h5 = None
        try:
            os.unlink(self.tmp)
        except OSError:
            pass

    # -- the writer's thread --------------------------------------------------------------------
    @property
    def failed(self) -> bool:
        """Whether writing has failed (the run then raises the error, see :meth:`add`)."""
        return self._error is not None

    def _raise_if_failed(self) -> None:
        if self._error is not None:
            raise self._error

    def _loop(self) -> None:
        try:
            while not self._stop:
                try:
                    # With tiles in flight, place the oldest while no group is waiting.
                    g = self._queue.get(block=not self._inflight)
                except queue.Empty:
                    self._timed(self._place_oldest)
                    continue
                if g is None or self._stop:
                    while self._inflight and not self._stop:
                        self._timed(self._place_oldest)
                    return
                self._timed(self._write_group, g)
        except BaseException as exc:  # noqa: BLE001 (handed to the run, which raises it)
            # As files.netcdf_output: the HDF5 library's RuntimeError and OSErrors are failures
            # to write the output; anything else is a bug and passes unchanged.
            if isinstance(exc, OSError) or type(exc) is RuntimeError:
                exc = write_failure(self.output, exc)
            self._error = exc

    def _timed(self, work, *args) -> None:
        t0, c0 = time.perf_counter(), time.thread_time()
        work(*args)
        self.busy += time.perf_counter() - t0
        self.cpu += time.thread_time() - c0

    def _read(self, k: int) -> dict:
        """Block ``k`` from the store, checked; computed again if it is damaged."""
        triples = self.plan.blocks[k]
        try:
            return self.store.get(k, triples)
        except BlockDamaged as exc:
            self.store.discard(k, str(exc))
            self.recompute(k)
            return self.store.get(k, triples)

    def _block_one_minus(self, k: int) -> np.ndarray:
        with self._lock:
            values = self._pending.pop(k, None)
            if values is not None:
                self._pending_bytes -= values.nbytes
        return values if values is not None else self._read(k)["one_minus"]

    def _write_group(self, g: int) -> None:
        tiles_g = self.plan.groups[g]
        take = self._place_one_minus(g) if self.need_one_minus else None
        if self._h5 is not None:
            for i in tiles_g:
                region = self.plan.region(self.tiles.slices(i))
                one_minus = None if take is None else take(i, region.shape)
                job = encode.tile_job(self.spec, region, self.per_triple, one_minus,
                                      self._layouts)
                self._inflight.append(self.encoder.submit(encode.encode_tile, job))
                del job, one_minus
                while len(self._inflight) > self.encoder.slots:
                    self._place_oldest()
            return

        def derive(i):
            region = self.plan.region(self.tiles.slices(i))
            one_minus = None if take is None else take(i, region.shape)
            return region, grid_values(self.spec, region, self.per_triple, one_minus, self.xi,
                                       self.profiles)

        # The next tile is derived in a second thread while HDF5 compresses this one (it does
        # not hold the GIL).
        with ThreadPoolExecutor(1, thread_name_prefix="cc-tile") as pool:
            ahead = pool.submit(derive, tiles_g[0])
            for j in range(len(tiles_g)):
                region, values = ahead.result()
                if j + 1 < len(tiles_g):
                    ahead = pool.submit(derive, tiles_g[j + 1])
                for name, (dims, value, _) in values.items():
                    self._nc[name][region.slices + (slice(None),) * (len(dims) - len(DIMS))] = value
                del values
                self.tiles_written += 1

    def _place_oldest(self) -> None:
        """Wait for the oldest tile in flight and place its encoded chunks into the file."""
        done = self._inflight[0].result()
        self._inflight.popleft()
        datasets = {}
        try:
            for name, offset, data in done["chunks"]:
                ds = datasets.get(name)
                if ds is None:
                    ds = datasets[name] = self._h5[name].id
                ds.write_direct_chunk(offset, data)
        except (OSError, RuntimeError, ValueError) as exc:
            raise hdf_error(exc) from None
        self.encode_cpu += done["cpu"]
        self.tiles_written += 1

    def _place_one_minus(self, g: int):
        """``take(tile, shape)``: the plug-edge values of group ``g``'s tiles, regrouped from
        its blocks in memory, or through bucket files for a group above :data:`GROUP_POINTS`."""
        tiles_g = [int(i) for i in self.plan.groups[g]]
        sizes = [math.prod(s.stop - s.start for s in self.tiles.slices(i)) for i in tiles_g]
        if sum(sizes) > GROUP_POINTS:
            buckets = Buckets(os.path.join(self.store.directory, SCRATCH), self.tiles)
            self._gather(g, lambda k: buckets.add(*self._tile_local(k), self._block_one_minus(k)))
            return buckets.take
        # The group's tiles one after the other in one array: each block's values land with one
        # scatter, wherever its points lie. Where a block's entries come in runs along K
        # (Plan.runs_along_K), each tile is held K innermost, (eps, L, A, N, K): a run is then
        # a row of nK adjacent values, where in the tile's own C order its values lie nA x nN
        # apart, each in a cache line of its own (the scatter was a miss per value); the tile is
        # handed out as a view in (eps, L, K, A, N), whose values the derivation reads
        # elementwise whatever their order in memory.
        start = np.full(self.tiles.count, -1, dtype=np.int64)
        start[tiles_g] = np.cumsum([0] + sizes[:-1])
        out = np.empty(sum(sizes))
        count = np.zeros(self.tiles.count, dtype=np.int64)
        lock = threading.Lock()
        nK = self.plan.shape[2]
        along_K = self.plan.runs_along_K

        def gather(k):
            values = self._block_one_minus(k)
            if along_K:
                rows, per_tile = self._group_rows(k, start)
                out.reshape(-1, nK)[rows] = values.reshape(-1, nK)
            else:
                where, per_tile = self._group_positions(k, start)
                out[where] = values
            with lock:
                count[:] += per_tile

        self._gather(g, gather)
        bad = [(i, n) for i, n in zip(tiles_g, sizes) if count[i] != n]
        if bad:  # blocks hold disjoint points: a bug, never a user's error
            raise RuntimeError(f"tile {bad[0][0]}: {count[bad[0][0]]} plug-edge values for "
                               f"{bad[0][1]} points")

        def take(i, shape):
            i = int(i)
            values = out[start[i]:start[i] + math.prod(shape)]
            if along_K:
                nE, nL, _, nA, nN = shape
                return np.moveaxis(values.reshape(nE, nL, nA, nN, nK), 4, 2)
            return values.reshape(shape)

        return take

    def _gather(self, g: int, gather) -> None:
        """``gather(k)`` for every block ``k`` of group ``g``, in two threads: reading, checking
        and placing a block is numpy and hashlib work that leaves the GIL."""
        with ThreadPoolExecutor(2, thread_name_prefix="cc-gather") as pool:
            for _ in pool.map(gather, self._blocks_of[g]):
                pass

    def _group_positions(self, k: int, start: np.ndarray):
        """``(where, per_tile)``: the position of each of block ``k``'s entries in its group's
        array, whose tile ``i`` begins at ``start[i]`` (C order), and how many entries each tile
        gets."""
        tile, local = self._tile_local(k)
        per_tile = np.bincount(tile, minlength=self.tiles.count)
        _within_group(k, per_tile, start)
        return start[tile] + local, per_tile

    def _group_rows(self, k: int, start: np.ndarray):
        """``(rows, per_tile)``: the row of each run of block ``k`` (:meth:`.plan.Plan.tile_runs`)
        in its group's array seen as rows of ``nK`` (its tiles, ``i`` from ``start[i]``, each
        held ``(eps, L, A, N, K)``), and how many entries each tile gets."""
        tile, local, stride = self.plan.tile_runs(k)
        nK = self.plan.shape[2]
        per_tile = np.bincount(tile, minlength=self.tiles.count) * nK
        _within_group(k, per_tile, start)
        # local is (slab * nK + K) * stride + position in (A, N), stride the A x N extent of the
        # tile; K innermost that is row slab * stride + position in (A, N).
        slab, within = np.divmod(local, nK * stride)
        return start[tile] // nK + slab * stride + within, per_tile

    def _tile_local(self, k: int):
        """``(tile, local)`` of block ``k``'s entries (:meth:`Tiles.locate` of its grid indices)."""
        found = self.plan.tile_local(k)
        return found if found is not None else self.tiles.locate(self.plan.inputs(k).flat)


def hdf_error(exc: BaseException) -> RuntimeError:
    """h5py's error writing the file, in the words of ``netCDF4``'s (``HDF error``) with the
    system's reason when HDF5 gives one (``File too large``), not its whole call record."""
    text = " ".join(str(exc).split())
    found = re.search(r"error message = '([^']*)'", text)
    reason = found.group(1) if found else text.split(" (")[0]
    return RuntimeError(f"HDF error ({reason})" if reason else "HDF error")


def temp_path(directory: str, output: str) -> str:
    """A fresh temporary file name for ``output`` inside ``directory`` (the store, whose opening
    deletes ``*.tmp`` leftovers of a killed run)."""
    return _temp_path(directory, output)


def _within_group(k: int, per_tile: np.ndarray, start: np.ndarray) -> None:
    """Raise if block ``k`` gives values to a tile outside its group (``start < 0``): a block's
    points lie in its group, so this is a bug, not an input's fault."""
    if per_tile[start < 0].any():
        raise RuntimeError(f"block {k} has plug-edge values outside its group")
