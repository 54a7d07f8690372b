"""A tile of the result file derived and its chunks encoded wherever there is a core for it.

The result file's writer (:mod:`.writer`) cuts the grid into tiles of whole chunks. A
:class:`TileJob` carries everything one tile needs, and nothing grid-sized: the tile's axis
values, the per-integration values it reads (gathered by :func:`tile_job`), its plug-edge values
and, for each variable, the chunk shape and the HDF5 filter pipeline of the file. :func:`encode_tile`
derives the tile's values, a column of chunks at a time, with :func:`.dataset.grid_values` (the
function the in-memory result uses, elementwise in the grid point: the same bits) and encodes
every chunk as the HDF5 library would: it runs in a thread of this process or on a
``dask.distributed`` worker, and the process that writes the file only places the encoded chunks
(``H5Dwrite_chunk``).

The filters themselves (HDF5's, byte for byte) are :mod:`cosserat_channel.chunk_filters`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..chunk_filters import encode_part
from ..parameters import DIMS


@dataclass(frozen=True)
class Layout:
    """How one variable of the file is stored: chunk shape, HDF5 filters in order, the value
    its edge chunks are padded with."""

    chunks: tuple
    pipeline: tuple
    fill: object = 0


class TileGrid:
    """A box of the grid that carries its own per-integration index: what
    :func:`.dataset.grid_values` needs of a grid (``eps``, ``L``, ``K``, ``A``, ``N``, ``shape``,
    ``reduce``, :meth:`to_grid`), without the plan.

    Per-integration arrays given to :meth:`to_grid` are a tile's own rows (:func:`tile_job`):
    reduced, ``(u, a, n)`` in C order over the tile's distinct ``eta`` values ``u`` and its ``A``
    and ``N``, with ``inv[e, l]`` the ``u`` of each ``(eps, L)`` pair of this box; unreduced, the
    tile's points in C order. ``rows`` is the shape of that tile and ``lo`` the first index of
    this box in it (a box of a tile, :meth:`box`, reads the tile's rows where they lie); by
    default, the box is the tile.
    """

    def __init__(self, eps, L, K, A, N, reduce: bool, inv=None, rows=None, lo=None):
        self.eps, self.L, self.K, self.A, self.N = eps, L, K, A, N
        self.shape = (eps.size, L.size, K.size, A.size, N.size)
        self.reduce = reduce
        self.inv = inv
        self.rows = self.shape if rows is None else tuple(rows)
        self.lo = (0,) * len(self.shape) if lo is None else tuple(lo)

    def box(self, slices: tuple) -> "TileGrid":
        """The box ``slices`` of this one (a slice per axis, step 1), reading the same rows."""
        start = tuple(s.indices(n)[0] for s, n in zip(slices, self.shape))
        axes = (v[s] for v, s in zip((self.eps, self.L, self.K, self.A, self.N), slices))
        inv = self.inv[slices[0], slices[1]] if self.reduce else None
        return TileGrid(*axes, self.reduce, inv, self.rows,
                        tuple(o + a for o, a in zip(self.lo, start)))

    def to_grid(self, per_triple: np.ndarray, spread: bool = True) -> np.ndarray:
        """As :meth:`.plan.Region.to_grid`, from the tile's own rows."""
        trailing = per_triple.shape[1:]
        box = tuple(slice(o, o + n) for o, n in zip(self.lo, self.shape))
        if not self.reduce:
            return per_triple.reshape(self.rows + trailing)[box].copy()
        nA, nN = self.rows[3:]
        by_pair = per_triple.reshape((-1, nA, nN) + trailing)[:, box[3], box[4]][self.inv]
        if not spread:
            return by_pair[:, :, None]
        out = np.empty(self.shape + trailing, dtype=per_triple.dtype)
        out[...] = by_pair[:, :, None]
        return out


@dataclass
class TileJob:
    """One tile's derivation and encoding: everything :func:`encode_tile` needs, picklable."""

    spec: object
    grid: TileGrid
    origin: tuple
    per_triple: dict
    one_minus: np.ndarray | None
    layouts: dict


def tile_job(spec, region, per_triple: dict, one_minus, layouts: dict) -> TileJob:
    """The :class:`TileJob` of ``region`` (a :class:`.plan.Region`): its rows of the run's
    per-integration arrays ``per_triple`` gathered, its plug-edge values ``one_minus``."""
    p = region.plan
    se, sl, sk, sa, sn = region.slices
    if p.reduce:
        nA, nN = p.shape[3:]
        u, inv = np.unique(p.inv.reshape(p.shape[:2])[se, sl], return_inverse=True)
        a = np.arange(nA)[sa]
        n = np.arange(nN)[sn]
        rows = ((u[:, None, None] * nA + a[None, :, None]) * nN + n[None, None, :]).ravel()
        local = {k: v[rows] for k, v in per_triple.items()}
        inv = inv.reshape(region.shape[:2])
    else:
        local = {k: v.reshape(p.shape + v.shape[1:])[se, sl, sk, sa, sn].reshape((-1,) + v.shape[1:])
                 for k, v in per_triple.items()}
        inv = None
    grid = TileGrid(region.eps, region.L, region.K, region.A, region.N, p.reduce, inv)
    origin = tuple(s.start or 0 for s in region.slices)
    return TileJob(spec, grid, origin, local, one_minus, layouts)


def encode_tile(job: TileJob) -> dict:
    """``{"chunks": [(name, offset, bytes), ...], "cpu": seconds}``: every chunk of the tile,
    encoded, ``offset`` the chunk's first grid index in the file.

    The values are derived a column of chunks at a time: :func:`.dataset.grid_values` on the box
    of one chunk's extent along every axis but ``K`` and the tile's along ``K``
    (:meth:`TileGrid.box`). Its arrays, a few chunks each, stay in the caches from their
    derivation to their encoding, where a whole tile's are many times the caches. A column, not
    one chunk: the work that does not depend on ``K`` (the status, the wall values) and the
    derivation's per-call work are done once per column, not at every chunk.

    A variable constant along an axis (``m_wall``, ``status``: along ``K``) comes as a broadcast
    view, read in place; its chunks that differ only in their position along that axis hold the
    same bytes, so each is encoded once and its bytes placed at every such position, and deflated
    as data that repeats (:func:`cosserat_channel.chunk_filters.deflate`).
    """
    from .dataset import grid_values

    c0 = time.thread_time()
    grid = job.grid

    def values_of(slices):
        one_minus = None if job.one_minus is None else job.one_minus[slices]
        return grid_values(job.spec, grid.box(slices), job.per_triple, one_minus, spread=False)

    K = DIMS.index("K")
    # Each variable's chunks listed together, in the file's order of variables.
    by_name = {name: [] for name in job.layouts}
    # Variables chunked alike are derived together (in a result file, every grid variable).
    by_shape = {}
    for name, layout in job.layouts.items():
        by_shape.setdefault(layout.chunks, []).append(name)
    for shape, names in by_shape.items():
        counts = tuple(-(-m // c) for m, c in zip(grid.shape, shape))
        # The columns of chunks along K: their first chunk's index, K's 0.
        for column in np.ndindex(*(1 if i == K else n for i, n in enumerate(counts))):
            lo = tuple(i * c for i, c in zip(column, shape))
            box = tuple(slice(None) if i == K else slice(a, min(a + c, m))
                        for i, (a, c, m) in enumerate(zip(lo, shape, grid.shape)))
            values = values_of(box)
            for name in names:
                layout = job.layouts[name]
                value = np.asarray(values[name][1])
                constant = [s == 0 for s in value.strides]
                # Its chunks hold each value as many times as they span such an axis.
                repeats = math.prod(c for c, z in zip(shape, constant) if z) > 1
                encoded = {}
                for k in range(counts[K]):
                    along = slice(k * shape[K], (k + 1) * shape[K])
                    part = value[(slice(None),) * K + (along,)]
                    # Same values, same padding (an edge chunk is stored whole, padded as HDF5
                    # pads it): the same bytes.
                    key = (0 if constant[K] else k, part.shape)
                    data = encoded.get(key)
                    if data is None:
                        data = encoded[key] = encode_part(part, shape, layout.fill,
                                                          layout.pipeline, repeats)
                    offset = tuple(o + (along.start if i == K else a)
                                   for i, (o, a) in enumerate(zip(job.origin, lo)))
                    by_name[name].append((name, offset, data))
            del values
    chunks = [c for name in job.layouts for c in by_name[name]]
    return {"chunks": chunks, "cpu": time.thread_time() - c0}


def aligned(layout: Layout, tile: tuple, shape: tuple) -> bool:
    """Whether every chunk of a variable laid out as ``layout`` lies inside one tile."""
    return len(layout.chunks) == len(DIMS) and all(
        t >= n or t % c == 0 for c, t, n in zip(layout.chunks, tile, shape))


def chunk_count(layout: Layout, shape: tuple) -> int:
    """Chunks of a variable of ``shape`` laid out as ``layout``."""
    return math.prod(-(-n // c) for n, c in zip(shape, layout.chunks))
