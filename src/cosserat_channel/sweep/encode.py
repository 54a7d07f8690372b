"""A tile of the result file derived and its chunks encoded wherever there is a core for it.

The result file's writer (:mod:`.writer`) cuts the grid into tiles of whole chunks. A
:class:`TileJob` carries everything one tile needs, and nothing grid-sized: the tile's axis
values, the per-integration values it reads (gathered by :func:`tile_job`), its plug-edge values
and, for each variable, the chunk shape and the HDF5 filter pipeline of the file. :func:`encode_tile`
derives the tile's values with :func:`.dataset.grid_values` (the function the in-memory result
uses, elementwise in the grid point: the same bits) and encodes every chunk as the HDF5 library
would: it runs in a thread of this process or on a ``dask.distributed`` worker, and the process
that writes the file only places the encoded chunks (``H5Dwrite_chunk``).

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

    Per-integration arrays given to :meth:`to_grid` are the tile's own rows (:func:`tile_job`):
    reduced, ``(u, a, n)`` in C order over the tile's distinct ``eta`` values ``u`` and its ``A``
    and ``N``, with ``inv[e, l]`` the ``u`` of each ``(eps, L)`` pair; unreduced, the box's points
    in C order.
    """

    def __init__(self, eps, L, K, A, N, reduce: bool, inv=None):
        self.eps, self.L, self.K, self.A, self.N = eps, L, K, A, N
        self.shape = (eps.size, L.size, K.size, A.size, N.size)
        self.reduce = reduce
        self.inv = inv

    def to_grid(self, per_triple: np.ndarray, spread: bool = True) -> np.ndarray:
        """As :meth:`.plan.Region.to_grid`, from the tile's own rows."""
        trailing = per_triple.shape[1:]
        if not self.reduce:
            return per_triple.reshape(self.shape + trailing).copy()
        nA, nN = self.shape[3:]
        by_pair = per_triple.reshape((-1, nA, nN) + trailing)[self.inv]
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

    A variable constant along an axis (``m_wall``, ``status``: along ``K``) comes as a broadcast
    view, read in place; its chunks that differ only in their position along that axis hold the
    same bytes, so each is encoded once and its bytes placed at every such position, and deflated
    as data that repeats (:func:`cosserat_channel.chunk_filters.deflate`).
    """
    from .dataset import grid_values

    c0 = time.thread_time()
    values = grid_values(job.spec, job.grid, job.per_triple, job.one_minus, spread=False)
    chunks = []
    for name, (_, value, _) in values.items():
        layout = job.layouts[name]
        value = np.asarray(value)
        shape = layout.chunks
        constant = [s == 0 for s in value.strides]
        # Its chunks hold each value as many times as they span such an axis.
        repeats = math.prod(c for c, z in zip(shape, constant) if z) > 1
        encoded = {}
        for index in np.ndindex(*(-(-m // c) for m, c in zip(value.shape, shape))):
            lo = tuple(i * c for i, c in zip(index, shape))
            part = value[tuple(slice(a, a + c) for a, c in zip(lo, shape))]
            # Same values, same padding (an edge chunk is stored whole, padded as HDF5 pads it):
            # the same bytes.
            key = (tuple(0 if z else i for z, i in zip(constant, index)), part.shape)
            data = encoded.get(key)
            if data is None:
                data = encoded[key] = encode_part(part, shape, layout.fill, layout.pipeline,
                                                  repeats)
            chunks.append((name, tuple(o + a for o, a in zip(job.origin, lo)), data))
        del value, encoded
    return {"chunks": chunks, "cpu": time.thread_time() - c0}


def aligned(layout: Layout, tile: tuple, shape: tuple) -> bool:
    """Whether every chunk of a variable laid out as ``layout`` lies inside one tile."""
    return len(layout.chunks) == len(DIMS) and all(
        t >= n or t % c == 0 for c, t, n in zip(layout.chunks, tile, shape))


def chunk_count(layout: Layout, shape: tuple) -> int:
    """Chunks of a variable of ``shape`` laid out as ``layout``."""
    return math.prod(-(-n // c) for n, c in zip(shape, layout.chunks))
