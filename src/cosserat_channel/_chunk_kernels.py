"""The Numba kernels of :mod:`cosserat_channel.chunk_filters` (HDF5's chunk filters): no GIL, so
that chunks are encoded in parallel threads. Imported on first use, by the functions there.
"""

import numpy as np
from numba import njit

from ._jit import JIT


@njit(**JIT)
def _shuffle_bytes(raw, itemsize, out):
    # HDF5's shuffle of whole elements (byte j of element i to j * count + i). Eight-byte elements
    # (every float variable) element after element, each one's bytes read once and stored to the
    # eight planes: one pass over the chunk, about 3.5x the speed of a pass per plane, which
    # reads the whole chunk eight times. Other sizes one pass per j (a loop over a size known
    # only at run time inside would not be unrolled: slower still).
    count = raw.size // itemsize
    if itemsize == 8:
        for i in range(count):
            b = 8 * i
            for j in range(8):
                out[j * count + i] = raw[b + j]
        return
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
