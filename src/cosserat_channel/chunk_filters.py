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
import threading
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
def _gather(src, fill, words):
    # words (C order) = a chunk whose leading box is src (any strides, zero ones included) and
    # the rest fill: an edge chunk padded as HDF5 pads it.
    c0, c1, c2, c3, c4 = words.shape
    s0, s1, s2, s3, s4 = src.shape
    flat = words.reshape(words.size)
    k = 0
    for i0 in range(c0):
        for i1 in range(c1):
            for i2 in range(c2):
                for i3 in range(c3):
                    m = s4 if i0 < s0 and i1 < s1 and i2 < s2 and i3 < s3 else 0
                    for i4 in range(m):
                        flat[k + i4] = src[i0, i1, i2, i3, i4]
                    for i4 in range(m, c4):
                        flat[k + i4] = fill
                    k += c4


@njit(**JIT)
def _shuffle_bytes(raw, itemsize, out):
    # HDF5's shuffle of whole elements (byte j of element i to j * count + i), one pass per j:
    # loops the compiler vectorizes.
    count = raw.size // itemsize
    for j in range(itemsize):
        base = j * count
        for i in range(count):
            out[base + i] = raw[itemsize * i + j]


@njit(**JIT)
def _fletcher32(half, last):
    # HDF5's H5_checksum_fletcher32 of bytes given as their 16-bit words read little-endian
    # (half) and, for an odd count, the last byte (last >= 0). HDF5 reads big-endian words,
    # sum1 += w; sum2 += sum1, both folded to 16 bits every 360 words (the most that cannot
    # overflow 32 bits), a last odd byte as the high byte of a word, and a final fold. Over a
    # block of b words that adds a1 = sum(w) to sum1 and b * sum1 + a2, a2 = sum((b - k) w_k),
    # to sum2: the same integers (a2 < 65535 * 360 * 361 / 2 < 2**32: 32-bit sums, which the
    # compiler vectorizes), so the same checksum.
    nw = half.size
    m16 = np.uint64(0xFFFF)
    sum1 = np.uint64(0)
    sum2 = np.uint64(0)
    for start in range(0, nw, 360):
        b = min(360, nw - start)
        a1 = np.uint32(0)
        a2 = np.uint32(0)
        block = half[start:start + b]
        for k in range(b):
            v = np.uint32(block[k])
            w = ((v & np.uint32(0xFF)) << np.uint32(8)) | (v >> np.uint32(8))
            a1 = np.uint32(a1 + w)
            a2 = np.uint32(a2 + np.uint32(np.uint32(b - k) * w))
        sum2 += np.uint64(b) * sum1 + np.uint64(a2)
        sum1 += np.uint64(a1)
        sum1 = (sum1 & m16) + (sum1 >> np.uint64(16))
        sum2 = (sum2 & m16) + (sum2 >> np.uint64(16))
    if last >= 0:
        sum1 += np.uint64(last) << np.uint64(8)
        sum2 += sum1
        sum1 = (sum1 & m16) + (sum1 >> np.uint64(16))
        sum2 = (sum2 & m16) + (sum2 >> np.uint64(16))
    sum1 = (sum1 & m16) + (sum1 >> np.uint64(16))
    sum2 = (sum2 & m16) + (sum2 >> np.uint64(16))
    return (sum2 << np.uint64(16)) | sum1


def fletcher32(data: np.ndarray) -> int:
    """HDF5's Fletcher-32 checksum of the bytes ``data`` (a contiguous uint8 array)."""
    even = data.size // 2 * 2
    return int(_fletcher32(data[:even].view(np.uint16), int(data[even]) if even < data.size else -1))


def shuffle(data: np.ndarray, itemsize: int) -> np.ndarray:
    """HDF5's shuffle of the bytes ``data`` for elements of ``itemsize`` bytes."""
    if itemsize <= 1:
        return data
    out = np.empty_like(data)
    whole = data.size // itemsize * itemsize
    _shuffle_bytes(data, int(itemsize), out)
    out[whole:] = data[whole:]
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


_buffers = threading.local()


def _scratch(shape: tuple):
    """This thread's buffers for a chunk of ``shape`` of 8-byte elements: its elements and its
    encoded bytes (with 4 to spare). Reused chunk after chunk: fresh megabytes cost the system
    a page fault per page, more than the copy, the shuffle and the checksum together."""
    found = getattr(_buffers, "chunk", None)
    if found is None or found[0].shape != shape:
        words = np.empty(shape, dtype=np.uint64)
        found = _buffers.chunk = (words, np.empty(words.nbytes + 4, dtype=np.uint8))
    return found


def encode_part(part: np.ndarray, shape: tuple, fill, pipeline) -> bytes:
    """The bytes HDF5 stores for a chunk of ``shape`` under ``pipeline`` whose leading box holds
    ``part`` (a view into a tile, any strides, broadcast ones included) and the rest ``fill`` (an
    edge chunk, padded as HDF5 pads it)."""
    n = math.prod(shape) * part.dtype.itemsize
    rest = tuple(pipeline)
    if (part.dtype.itemsize == 8 and part.ndim == 5 and rest
            and rest[0][0] == FILTER_FLETCHER32):
        shuffled = len(rest) > 1 and rest[1][0] == FILTER_SHUFFLE and rest[1][1] in ((), (8,))
        bits = np.asarray(fill, dtype=part.dtype).reshape(1).view(np.uint64)[0]
        words, data = _scratch(tuple(int(c) for c in shape))
        _gather(part.view(np.uint64), bits, words)
        raw = words.reshape(-1).view(np.uint8)
        if shuffled:
            _shuffle_bytes(raw, 8, data)
        else:
            data[:n] = raw
        total = int(_fletcher32(raw.view(np.uint16), -1))
        data[n:] = np.frombuffer(total.to_bytes(4, "little"), dtype=np.uint8)
        rest = rest[2:] if shuffled else rest[1:]
        return _run(data, n + 4, part.dtype.itemsize, rest, None)
    data = np.empty(n + 4, dtype=np.uint8)
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
