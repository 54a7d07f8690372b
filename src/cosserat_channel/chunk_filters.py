"""HDF5's chunk filters, byte for byte, outside the library: a chunk encoded here is what
HDF5 would store, so a writer places it as it is (``H5Dwrite_chunk``) wherever it was encoded.

The filters are HDF5's own, applied in the order the file's pipeline lists them (netCDF-C sets
Fletcher-32 first, then shuffle, then deflate):

- Fletcher-32 (HDF5 filter 3): HDF5's ``H5_checksum_fletcher32`` of the chunk's bytes (big-endian
  16-bit words, both sums folded to 16 bits), appended as 4 little-endian bytes;
- shuffle (filter 2): byte ``j`` of every element together, elements of the variable's size;
  bytes beyond the last whole element (the checksum's) stay where they are;
- deflate (filter 1): a zlib stream (:func:`deflate`), from ISA-L (``isal``: an ordinary zlib
  stream every reader opens, at several times zlib's speed) or, where ``isal`` cannot be imported,
  from ``zlib`` at the pipeline's level.

:func:`encode_part` runs the first two in one pass over a chunk's values, read in place from the
tile (edge chunks padded), for 8-byte elements: the checksum, the shuffle and the copy into the
chunk's buffer are each a pass over the bytes otherwise.

A pipeline with any other filter (Zstandard's plugin, say) is not encoded here: :func:`supported`
says so, and the writer lets the HDF5 library write that file.

Kernels in Numba (no GIL), so that encoding runs in parallel threads.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
from numba import njit

from ._jit import JIT

try:  # ISA-L's deflate (a dependency; zlib where its wheel cannot be installed or loaded)
    from isal import igzip_lib as _isal
except ImportError:  # pragma: no cover (depends on the installation)
    _isal = None
# Which deflate this process runs (the benchmark says it).
DEFLATE = "zlib" if _isal is None else "ISA-L (isal)"
# ISA-L's deflate for the pipeline's zlib level 1: its level 2 with its small hash tables, within
# 0.5 % of zlib 1's size on the sweeps' float chunks (its level 1 is up to 1.7 % larger) at the
# same speed, 7x zlib's. Its fast levels miss the repeats of a chunk whose rows repeat (a variable
# constant along K: 5x zlib's size there); a chunk they shrink below REPETITIVE of its size is
# deflated again by its level 3, a lazy matcher, 10-15 % below zlib 1, and the smaller kept.
ISAL_LEVEL = 2
ISAL_LAZY = 3
REPETITIVE = 0.25

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
def copy_box(src, dst):
    # dst[:a, :b, :c, :d, :e] = src (5-D, any strides): numpy's copy of a box of short rows
    # spends more on its loop than on the bytes.
    n0, n1, n2, n3, n4 = src.shape
    for i0 in range(n0):
        for i1 in range(n1):
            for i2 in range(n2):
                for i3 in range(n3):
                    for i4 in range(n4):
                        dst[i0, i1, i2, i3, i4] = src[i0, i1, i2, i3, i4]


@njit(**JIT)
def _pack8(src, shape, fill, shuffled, out):
    # A chunk of ``shape`` whose leading box is ``src`` (8-byte elements as uint64, any strides,
    # zero ones included) and the rest ``fill``, in C order: its bytes (little-endian) into
    # ``out``, shuffled (HDF5's, byte j of element i at j * count + i) or not, and their
    # Fletcher-32 returned, as _fletcher32 computes it over the unshuffled bytes.
    c0, c1, c2, c3, c4 = shape
    s0, s1, s2, s3, s4 = src.shape
    count = c0 * c1 * c2 * c3 * c4
    words = np.empty(count, dtype=np.uint64)
    k = 0
    for i0 in range(c0):
        for i1 in range(c1):
            for i2 in range(c2):
                for i3 in range(c3):
                    m = s4 if i0 < s0 and i1 < s1 and i2 < s2 and i3 < s3 else 0
                    for i4 in range(m):
                        words[k + i4] = src[i0, i1, i2, i3, i4]
                    for i4 in range(m, c4):
                        words[k + i4] = fill
                    k += c4
    # Each element is four big-endian 16-bit words (its bytes swapped in pairs: lanes of x), and
    # HDF5's block of 360 words between folds is 90 elements. Within a block the sums are those
    # of the word-by-word loop, added four words at a time: the same integers (a block's sums
    # stay below 2**32, which is why HDF5 folds every 360 words), so the same checksum.
    lanes = np.uint64(0x00FF00FF00FF00FF)
    m16 = np.uint64(0xFFFF)
    sum1 = np.uint64(0)
    sum2 = np.uint64(0)
    for start in range(0, count, 90):
        for i in range(start, min(count, start + 90)):
            w = words[i]
            if shuffled:
                for j in range(8):
                    out[j * count + i] = np.uint8((w >> np.uint64(8 * j)) & np.uint64(0xFF))
            else:
                for j in range(8):
                    out[8 * i + j] = np.uint8((w >> np.uint64(8 * j)) & np.uint64(0xFF))
            x = ((w & lanes) << np.uint64(8)) | ((w >> np.uint64(8)) & lanes)
            w0 = x & m16
            w1 = (x >> np.uint64(16)) & m16
            w2 = (x >> np.uint64(32)) & m16
            w3 = x >> np.uint64(48)
            sum2 += np.uint64(4) * sum1 + np.uint64(4) * w0 + np.uint64(3) * w1 + np.uint64(2) * w2 + w3
            sum1 += w0 + w1 + w2 + w3
        sum1 = (sum1 & m16) + (sum1 >> np.uint64(16))
        sum2 = (sum2 & m16) + (sum2 >> np.uint64(16))
    sum1 = (sum1 & m16) + (sum1 >> np.uint64(16))
    sum2 = (sum2 & m16) + (sum2 >> np.uint64(16))
    return (sum2 << np.uint64(16)) | sum1


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
    """A zlib stream of ``data`` for a pipeline's deflate ``level``: zlib's at that level, or,
    with ISA-L and ``level`` >= 1, ISA-L's (module constants: its size is zlib 1's, give or take
    half a per cent, at several times the speed)."""
    level = int(level)
    if _isal is None or level < 1:
        return zlib.compress(data, level)
    out = _isal.compress(data, ISAL_LEVEL if level == 1 else ISAL_LAZY, _isal.COMP_ZLIB,
                         _isal.MEM_LEVEL_SMALL)
    if level == 1 and len(out) < REPETITIVE * len(data):
        lazy = _isal.compress(data, ISAL_LAZY, _isal.COMP_ZLIB)
        if len(lazy) < len(out):
            out = lazy
    return out


def supported(pipeline) -> bool:
    """Whether :func:`encode` applies every filter of ``pipeline`` (``(id, values)`` pairs)."""
    return all(f in SUPPORTED for f, _ in pipeline)


def encode(chunk: np.ndarray, pipeline) -> bytes:
    """The bytes HDF5 stores for ``chunk`` (a whole chunk, C order) under ``pipeline``."""
    n = chunk.nbytes
    # Room for the checksum after the values: the checksum filter then appends without a copy.
    data = np.empty(n + 4, dtype=np.uint8)
    data[:n].view(chunk.dtype).reshape(chunk.shape)[...] = chunk
    return run_filters(data, n, chunk.dtype.itemsize, pipeline)


def encode_part(part: np.ndarray, shape: tuple, fill, pipeline) -> bytes:
    """The bytes HDF5 stores for a chunk of ``shape`` under ``pipeline`` whose leading box holds
    ``part`` (a view into a tile, any strides, broadcast ones included) and the rest ``fill`` (an
    edge chunk, padded as HDF5 pads it)."""
    n = math.prod(shape) * part.dtype.itemsize
    data = np.empty(n + 4, dtype=np.uint8)
    rest = tuple(pipeline)
    if (part.dtype.itemsize == 8 and part.ndim == 5 and rest
            and rest[0][0] == FILTER_FLETCHER32):
        shuffled = len(rest) > 1 and rest[1][0] == FILTER_SHUFFLE and rest[1][1] in ((), (8,))
        bits = np.asarray(fill, dtype=part.dtype).reshape(1).view(np.uint64)[0]
        total = _pack8(part.view(np.uint64), tuple(int(c) for c in shape), bits, shuffled, data)
        data[n:] = np.frombuffer(int(total).to_bytes(4, "little"), dtype=np.uint8)
        rest = rest[2:] if shuffled else rest[1:]
        return _run(data, n + 4, part.dtype.itemsize, rest, None)
    whole = data[:n].view(part.dtype).reshape(shape)
    if part.shape != tuple(shape):
        whole[...] = fill
    copy_box(part, whole)
    return run_filters(data, n, part.dtype.itemsize, pipeline)


def run_filters(buf: np.ndarray, n: int, itemsize: int, pipeline) -> bytes:
    """The pipeline run on the first ``n`` bytes of ``buf`` (which has 4 bytes to spare)."""
    return _run(buf, n, itemsize, pipeline, buf)


def _run(buf, n, itemsize, pipeline, room) -> bytes:
    data = buf[:n]
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
            data = deflate(data, values[0] if values else 6)
        else:
            raise ValueError(f"HDF5 filter {f} is not encoded outside the library")
        room = None
    return data if isinstance(data, bytes) else data.tobytes()
