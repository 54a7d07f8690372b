"""A tile of the result file derived and its chunks encoded wherever there is a core for it.

The result file's writer (:mod:`.writer`) cuts the grid into tiles of whole chunks. A
:class:`TileJob` carries everything one tile needs, and nothing grid-sized: the tile's axis
values, the per-integration values it reads (gathered by :func:`tile_job`), its plug-edge values
and, for each variable, the chunk shape and the HDF5 filter pipeline of the file. :func:`encode_tile`
derives the tile's values with :func:`.dataset.grid_values` (the function the in-memory result
uses, elementwise in the grid point: the same bits) and encodes every chunk as the HDF5 library
would: it runs in a thread of this process or on a ``dask.distributed`` worker, and the process
that writes the file only places the encoded chunks (``H5Dwrite_chunk``).

The filters are HDF5's own, applied in the order the file's pipeline lists them (netCDF-C sets
Fletcher-32 first, then shuffle, then deflate):

- Fletcher-32 (HDF5 filter 3): HDF5's ``H5_checksum_fletcher32`` of the chunk's bytes (big-endian
  16-bit words, both sums folded to 16 bits), appended as 4 little-endian bytes;
- shuffle (filter 2): byte ``j`` of every element together, elements of the variable's size;
  bytes beyond the last whole element (the checksum's) stay where they are;
- deflate (filter 1): a zlib stream at the pipeline's level, from ISA-L (``isal``, several times
  zlib's speed, an ordinary zlib stream every reader opens) when it is installed, else ``zlib``.

A pipeline with any other filter (Zstandard's plugin, say) is not encoded here: :func:`supported`
says so, and the writer lets the HDF5 library write that file.
"""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass

import numpy as np
from numba import njit

from .._jit import JIT
from ..parameters import DIMS

try:  # ISA-L's deflate: an optional extra (``pip install cosserat-channel[fast]``)
    from isal import isal_zlib as _fast_zlib
except ImportError:  # pragma: no cover (depends on the installation)
    _fast_zlib = None
# Which deflate this process runs (the benchmark says it).
DEFLATE = "zlib" if _fast_zlib is None else "ISA-L (isal)"

FILTER_DEFLATE = 1
FILTER_SHUFFLE = 2
FILTER_FLETCHER32 = 3
SUPPORTED = (FILTER_DEFLATE, FILTER_SHUFFLE, FILTER_FLETCHER32)


@njit(**JIT)
def _fletcher32(data):
    # HDF5's H5_checksum_fletcher32, step for step: big-endian 16-bit words, both sums folded to
    # 16 bits every 360 words (the most that cannot overflow 32 bits), a last odd byte as the
    # high byte of a word, and a final fold.
    n = data.size // 2
    sum1 = np.uint32(0)
    sum2 = np.uint32(0)
    i = 0
    while n > 0:
        t = min(n, 360)
        n -= t
        for _ in range(t):
            sum1 += (np.uint32(data[i]) << np.uint32(8)) | np.uint32(data[i + 1])
            sum2 += sum1
            i += 2
        sum1 = (sum1 & np.uint32(0xFFFF)) + (sum1 >> np.uint32(16))
        sum2 = (sum2 & np.uint32(0xFFFF)) + (sum2 >> np.uint32(16))
    if data.size % 2:
        sum1 += np.uint32(data[i]) << np.uint32(8)
        sum2 += sum1
        sum1 = (sum1 & np.uint32(0xFFFF)) + (sum1 >> np.uint32(16))
        sum2 = (sum2 & np.uint32(0xFFFF)) + (sum2 >> np.uint32(16))
    sum1 = (sum1 & np.uint32(0xFFFF)) + (sum1 >> np.uint32(16))
    sum2 = (sum2 & np.uint32(0xFFFF)) + (sum2 >> np.uint32(16))
    return (sum2 << np.uint32(16)) | sum1


@njit(**JIT)
def _shuffle(data, itemsize, out):
    # HDF5's shuffle: byte j of element i to j * count + i; the bytes past the last whole
    # element stay in place. Written in runs: each output run is written in order.
    count = data.size // itemsize
    for j in range(itemsize):
        base = j * count
        for i in range(count):
            out[base + i] = data[i * itemsize + j]
    for k in range(count * itemsize, data.size):
        out[k] = data[k]


@njit(**JIT)
def _shuffle8(words, out):
    # _shuffle for 8-byte elements read as little-endian words: one read of each element.
    count = words.size
    for i in range(count):
        w = words[i]
        for j in range(8):
            out[j * count + i] = np.uint8((w >> np.uint64(8 * j)) & np.uint64(0xFF))


@njit(**JIT)
def _copy_box(src, dst):
    # dst[:a, :b, :c, :d, :e] = src (5-D, any strides): numpy's copy of a box of short rows
    # spends more on its loop than on the bytes.
    n0, n1, n2, n3, n4 = src.shape
    for i0 in range(n0):
        for i1 in range(n1):
            for i2 in range(n2):
                for i3 in range(n3):
                    for i4 in range(n4):
                        dst[i0, i1, i2, i3, i4] = src[i0, i1, i2, i3, i4]


def fletcher32(data: np.ndarray) -> int:
    """HDF5's Fletcher-32 checksum of the bytes ``data`` (a contiguous uint8 array)."""
    return int(_fletcher32(data))


def shuffle(data: np.ndarray, itemsize: int) -> np.ndarray:
    """HDF5's shuffle of the bytes ``data`` for elements of ``itemsize`` bytes."""
    if itemsize <= 1:
        return data
    out = np.empty_like(data)
    whole = data.size // 8 * 8
    if itemsize == 8 and data.ctypes.data % 8 == 0:
        _shuffle8(data[:whole].view(np.uint64), out)
        out[whole:] = data[whole:]
    else:
        _shuffle(data, int(itemsize), out)
    return out


def deflate(data, level: int) -> bytes:
    """A zlib stream of ``data`` at ``level`` (ISA-L's when installed: levels 0-3)."""
    if _fast_zlib is not None:
        return _fast_zlib.compress(data, min(int(level), 3))
    return zlib.compress(data, int(level))


def supported(pipeline) -> bool:
    """Whether :func:`encode` applies every filter of ``pipeline`` (``(id, values)`` pairs)."""
    return all(f in SUPPORTED for f, _ in pipeline)


def encode(chunk: np.ndarray, pipeline) -> bytes:
    """The bytes HDF5 stores for ``chunk`` (a whole chunk, C order) under ``pipeline``."""
    n = chunk.nbytes
    # Room for the checksum after the values: the checksum filter then appends without a copy.
    data = np.empty(n + 4, dtype=np.uint8)
    data[:n].view(chunk.dtype).reshape(chunk.shape)[...] = chunk
    return _filters(data, n, chunk.dtype.itemsize, pipeline)


def _filters(buf: np.ndarray, n: int, itemsize: int, pipeline) -> bytes:
    """The pipeline run on the first ``n`` bytes of ``buf`` (which has 4 bytes to spare)."""
    data, room = buf[:n], buf
    for f, values in pipeline:
        if f == FILTER_FLETCHER32:
            total = data.size + 4
            if room is None:
                room = np.empty(total, dtype=np.uint8)
                room[:data.size] = data
            room[data.size:total] = np.frombuffer(fletcher32(data).to_bytes(4, "little"),
                                                  dtype=np.uint8)
            data = room[:total]
        elif f == FILTER_SHUFFLE:
            data = shuffle(data, values[0] if values else itemsize)
        elif f == FILTER_DEFLATE:
            data = np.frombuffer(deflate(data, values[0] if values else 6), dtype=np.uint8)
        else:
            raise ValueError(f"HDF5 filter {f} is not encoded outside the library")
        room = None
    return data.tobytes()


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
    encoded, ``offset`` the chunk's first grid index in the file."""
    from .dataset import grid_values

    c0 = time.thread_time()
    values = grid_values(job.spec, job.grid, job.per_triple, job.one_minus)
    chunks = []
    for name, (_, value, _) in values.items():
        layout = job.layouts[name]
        value = np.asarray(value)
        shape = layout.chunks
        n = math.prod(shape) * value.dtype.itemsize
        for index in np.ndindex(*(-(-m // c) for m, c in zip(value.shape, shape))):
            lo = tuple(i * c for i, c in zip(index, shape))
            part = value[tuple(slice(a, a + c) for a, c in zip(lo, shape))]
            data = np.empty(n + 4, dtype=np.uint8)
            whole = data[:n].view(value.dtype).reshape(shape)
            if part.shape != shape:  # an edge chunk: stored whole, padded as HDF5 pads it
                whole[...] = layout.fill
            _copy_box(part, whole)
            offset = tuple(o + a for o, a in zip(job.origin, lo))
            chunks.append((name, offset, _filters(data, n, value.dtype.itemsize,
                                                  layout.pipeline)))
        del value
    return {"chunks": chunks, "cpu": time.thread_time() - c0}


def aligned(layout: Layout, tile: tuple, shape: tuple) -> bool:
    """Whether every chunk of a variable laid out as ``layout`` lies inside one tile."""
    return len(layout.chunks) == len(DIMS) and all(
        t >= n or t % c == 0 for c, t, n in zip(layout.chunks, tile, shape))


def chunk_count(layout: Layout, shape: tuple) -> int:
    """Chunks of a variable of ``shape`` laid out as ``layout``."""
    return math.prod(-(-n // c) for n, c in zip(shape, layout.chunks))
