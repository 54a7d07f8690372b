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

:func:`encode_part` reads a chunk's values where they lie in the tile (edge chunks padded,
broadcast views included) into a buffer of its thread, reused chunk after chunk, and runs the
filters there.

A pipeline with any other filter (Zstandard's plugin, say) is not encoded here: :func:`supported`
says so, and the writer lets the HDF5 library write that file.

The kernels are Numba's (no GIL: encoding runs in parallel threads), in :mod:`._chunk_kernels`,
imported on first use: a process that only places encoded chunks (the client of a cluster) never
loads numba.
"""

from __future__ import annotations

import math
import threading
import zlib

import numpy as np

try:  # ISA-L's deflate (a dependency; zlib where its wheel cannot be installed or loaded)
    from isal import igzip_lib as _isal
except ImportError:  # pragma: no cover (depends on the installation)
    _isal = None
# Which deflate this process runs (the benchmark says it).
DEFLATE = "zlib" if _isal is None else "ISA-L (isal)"
# ISA-L's deflate for the pipeline's zlib level 1: its level 2 with its small hash tables, within
# 0.5 % of zlib 1's size on the sweeps' float chunks (its level 1 is up to 1.7 % larger) at the
# same speed, 7x zlib's. Its fast levels miss the long repeats of a chunk whose rows repeat (a
# variable constant along K: 5x zlib's size there); its level 0 finds them, at about 10x their
# speed on such data and 1.3x zlib 1's size (its lazy level 3 is 10 % below zlib 1 but as slow
# as zlib: 2.0 s of CPU on a 10^8-point sweep against 0.6 s, for 1.1 % of its file). A chunk the
# fast level shrinks below REPETITIVE of its size is deflated again by level 0 and the smaller
# kept, unless the caller can tell that it does not repeat that way (:func:`encode_part`). Other
# zlib levels: the lazy level 3.
ISAL_LEVEL = 2
ISAL_REPEATS = 0
ISAL_LAZY = 3
REPETITIVE = 0.25

FILTER_DEFLATE = 1
FILTER_SHUFFLE = 2
FILTER_FLETCHER32 = 3
SUPPORTED = (FILTER_DEFLATE, FILTER_SHUFFLE, FILTER_FLETCHER32)


def fletcher32(data: np.ndarray) -> int:
    """HDF5's Fletcher-32 checksum of the bytes ``data`` (a contiguous uint8 array)."""
    from ._chunk_kernels import _fletcher32

    even = data.size // 2 * 2
    return int(_fletcher32(data[:even].view(np.uint16), int(data[even]) if even < data.size else -1))


def shuffle(data: np.ndarray, itemsize: int, out: np.ndarray | None = None) -> np.ndarray:
    """HDF5's shuffle of the bytes ``data`` for elements of ``itemsize`` bytes (into the first
    ``data.size`` bytes of ``out`` when given)."""
    if itemsize <= 1:
        return data
    from ._chunk_kernels import _shuffle_bytes

    out = np.empty_like(data) if out is None else out[:data.size]
    whole = data.size // itemsize * itemsize
    _shuffle_bytes(data, int(itemsize), out)
    out[whole:] = data[whole:]
    return out


def deflate(data, level: int, repeats=False) -> bytes:
    """A zlib stream of ``data`` for a pipeline's deflate ``level``: zlib's at that level, or,
    with ISA-L and ``level`` >= 1, ISA-L's (module constants: at level 1 its size is zlib 1's,
    give or take half a per cent, at several times the speed).

    ``repeats``: True when the caller knows that the data holds each of its values several times
    over (a chunk of a variable constant along an axis), False when it does not know: either
    way, when the fast level's output is below REPETITIVE of the data, the data is deflated again
    by the level that finds long repeats, and the smaller kept. A callable: asked, only then,
    whether the data repeats that way (the retry wins nothing on data that shrinks for another
    reason, runs of one value)."""
    level = int(level)
    if _isal is None or level < 1:
        return zlib.compress(data, level)
    if level > 1:
        return _isal.compress(data, ISAL_LAZY, _isal.COMP_ZLIB, _isal.MEM_LEVEL_SMALL)
    out = _isal.compress(data, ISAL_LEVEL, _isal.COMP_ZLIB, _isal.MEM_LEVEL_SMALL)
    if len(out) < REPETITIVE * len(data) and (not callable(repeats) or repeats()):
        again = _isal.compress(data, ISAL_REPEATS, _isal.COMP_ZLIB)
        if len(again) < len(out):
            out = again
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
    """This thread's buffers for a chunk of ``shape`` of 8-byte elements: its bytes with 4 to
    spare for the checksum (and its elements, a view of them), and as many for the shuffle's
    output. Reused chunk after chunk: fresh megabytes cost the system a page fault per page, more
    than the copy, the shuffle and the checksum together."""
    found = getattr(_buffers, "chunk", None)
    if found is None or found[0].shape != shape:
        n = math.prod(shape) * 8
        raw = np.empty(n + 4, dtype=np.uint8)
        found = _buffers.chunk = (raw[:n].view(np.uint64).reshape(shape), raw,
                                  np.empty(n + 4, dtype=np.uint8))
    return found


def encode_part(part: np.ndarray, shape: tuple, fill, pipeline, repeats: bool = False) -> bytes:
    """The bytes HDF5 stores for a chunk of ``shape`` under ``pipeline`` whose leading box holds
    ``part`` (a view into a tile, any strides, broadcast ones included) and the rest ``fill`` (an
    edge chunk, padded as HDF5 pads it). ``repeats``: see :func:`deflate`; without it, a chunk
    that the fast level shrinks below REPETITIVE is deflated again only if ``part`` is constant
    along an axis (:func:`constant_along_an_axis`), the repeats the fast levels miss."""
    if not repeats:
        def repeats():
            return constant_along_an_axis(part)

    n = math.prod(shape) * part.dtype.itemsize
    if part.dtype.itemsize == 8:
        bits = np.asarray(fill, dtype=part.dtype).reshape(1).view(np.uint64)[0]
        words, raw, spare = _scratch(tuple(int(c) for c in shape))
        _place(part.view(np.uint64), bits, words)
        return _run(raw, n, 8, pipeline, raw, spare, repeats)
    data = np.empty(n + 4, dtype=np.uint8)
    whole = data[:n].view(part.dtype).reshape(shape)
    _place(part, fill, whole)
    return _run(data, n, part.dtype.itemsize, pipeline, data, None, repeats)


def _place(part: np.ndarray, fill, whole: np.ndarray) -> None:
    """``whole`` (a chunk) = ``part`` in its leading box and ``fill`` in the rest: an edge chunk
    padded as HDF5 pads it. numpy's copy, which follows the part's layout (runs of a column,
    zero strides of a broadcast view): three to forty times the speed of a compiled loop over the
    chunk's elements."""
    if part.shape != whole.shape:
        whole[...] = fill
        whole = whole[tuple(slice(0, n) for n in part.shape)]
    np.copyto(whole, part)


def constant_along_an_axis(part: np.ndarray) -> bool:
    """Whether ``part`` holds the same bits at every position along one of its axes (NaN
    included)."""
    bits = part.view(f"u{part.dtype.itemsize}")
    for axis, n in enumerate(bits.shape):
        if n > 1:
            rest = (slice(None),) * axis
            if np.array_equal(bits[rest + (slice(1, None),)], bits[rest + (slice(0, n - 1),)]):
                return True
    return False


def run_filters(buf: np.ndarray, n: int, itemsize: int, pipeline) -> bytes:
    """The pipeline run on the first ``n`` bytes of ``buf`` (which has 4 bytes to spare)."""
    return _run(buf, n, itemsize, pipeline, buf)


def _run(buf, n, itemsize, pipeline, room, spare=None, repeats=False) -> bytes:
    # room: buf itself while the data is still its first n bytes, for the checksum to append
    # to; spare: where the shuffle may write (a thread's reused buffer), else a fresh array.
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
            data = shuffle(data, values[0] if values else itemsize, spare)
            spare = None  # it holds the data now
        elif f == FILTER_DEFLATE:
            data = deflate(data, values[0] if values else 6, repeats)
        else:
            raise ValueError(f"HDF5 filter {f} is not encoded outside the library")
        room = None
    return data if isinstance(data, bytes) else data.tobytes()
