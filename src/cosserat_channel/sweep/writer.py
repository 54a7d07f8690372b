"""The result file written tile by tile, so that memory follows the tile, not the grid.

A result variable is grid-sized (10^8 points of float64 are 800 MB), but everything it is derived
from is per *triple* (a few per cent of the points with the similarity reduction), except the
plug edge ``1 - xi_p``, which has one value per grid point. So the file is written as follows:

1. every block is read once from the working store (:func:`.engine.assemble`); its per-triple
   arrays go into memory, its ``1 - xi_p`` values are appended to the *bucket* file of the tile
   they fall in (``scratch/`` inside the store: 12 bytes a point on disk, one block in memory);
2. for each tile, a box of the grid made of whole chunks of the file, the values are derived by
   :func:`.dataset.grid_values` (the function the in-memory result uses, elementwise, hence the
   same bits) and written with the ``netCDF4`` library into the file, each chunk compressed once.

Blocks cannot go into the file as they finish: the plan deals triples to blocks by cost across
the whole grid (:func:`.plan.block_plan`), so every block touches every chunk, and a chunk can
be compressed only once all blocks are in. The file is written under a temporary name inside the
store and renamed when complete (:meth:`.store.WorkStore.publish`).
"""

from __future__ import annotations

import math
import os
import shutil
import threading
from concurrent.futures import ThreadPoolExecutor

import netCDF4
import numpy as np

from ..parameters import DIMS
from .dataset import chunk_shape, coordinates, global_attrs, grid_values, variable_encoding

# Points of one tile (times the profile length): its derived variables, a dozen grid-sized
# temporaries, stay near 200 MB.
TILE_POINTS = 1 << 21
SCRATCH = "scratch"
BUCKET = np.dtype([("local", "<i4"), ("value", "<f8")])


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
        for i in reversed(range(len(tile))):  # grow along the trailing axes first (C order)
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

    def add(self, flat: np.ndarray, values: np.ndarray) -> None:
        """Append the values at grid indices ``flat`` to the buckets of their tiles."""
        tile, local = self.tiles.locate(flat)
        # A small integer key sorts by radix (linear time) and stably.
        key = tile.astype(np.uint16) if self.tiles.count <= 1 << 16 else tile
        order = np.argsort(key, kind="stable")
        tile = tile[order]
        rec = np.empty(flat.size, dtype=BUCKET)
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
    # xarray's default fill value for floats is NaN; "_FillValue: None" means none at all.
    fill = enc.pop("_FillValue", np.nan if np.dtype(dtype).kind == "f" else None)
    codec = enc.get("compression", "zlib" if enc.get("zlib") else None)
    var = nc.createVariable(name, dtype, dims, fill_value=fill, compression=codec,
                            complevel=enc.get("complevel", 4), shuffle=enc.get("shuffle", False),
                            chunksizes=enc.get("chunksizes"),
                            fletcher32=enc.get("fletcher32", False))
    var.set_auto_maskandscale(False)  # values go in as they are, NaN included
    var.setncatts(attrs)
    return var


def write_tiles(path, spec, plan, per_triple, xi, profiles, tiles: Tiles,
                buckets: Buckets | None, compress: bool = True) -> None:
    """Write the result file at ``path`` tile by tile (see the module docstring).

    The next tile's values are derived in a second thread while this one writes (the HDF5
    library compresses without holding the GIL): two tiles in memory, both cores busy.
    """

    def derive(i):
        region = plan.region(tiles.slices(i))
        one_minus = None if buckets is None else buckets.take(i, region.shape)
        return region, grid_values(spec, region, per_triple, one_minus, xi, profiles)

    with netCDF4.Dataset(path, "w", format="NETCDF4") as nc, \
            ThreadPoolExecutor(1, thread_name_prefix="cc-tile") as pool:
        ahead = pool.submit(derive, 0)
        for i in range(tiles.count):
            region, values = ahead.result()
            if i + 1 < tiles.count:
                ahead = pool.submit(derive, i + 1)
            if i == 0:
                create_variables(nc, spec, plan, xi, values, compress)
            for name, (dims, value, _) in values.items():
                nc[name][region.slices + (slice(None),) * (len(dims) - len(DIMS))] = value
            del values
