"""HDF5's chunk filters, byte for byte, outside the library: a chunk encoded here is what
HDF5 would store, so a writer places it as it is (``H5Dwrite_chunk``) wherever it was encoded.

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

Kernels in Numba (no GIL), so that encoding runs in parallel threads.
"""

from __future__ import annotations

import zlib

import numpy as np
from numba import njit

from ._jit import JIT

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
    return run_filters(data, n, chunk.dtype.itemsize, pipeline)


def run_filters(buf: np.ndarray, n: int, itemsize: int, pipeline) -> bytes:
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
