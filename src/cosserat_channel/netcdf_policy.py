"""How every NetCDF file of the package is encoded: codec, checksums, fill values, chunks.

The one home of that policy. Sweep results (``sweep.dataset``, ``sweep.writer``), query subsets
(``results.render``), boundaries and atlases all take their encoding from :func:`encoding` (or
:func:`variable_encoding` per variable), and a writer that creates variables with ``netCDF4``
itself translates it with :func:`create_variable`.

- **Codec.** zlib (deflate) level 1 with the HDF5 shuffle filter by default: every netCDF-4
  reader opens it (netCDF-C of any version, ``ncdump``, h5py/h5netcdf, HDF5's own tools, MATLAB,
  R), where Zstandard needs netCDF-C >= 4.9 built with its filter plugin (Debian's ``ncdump``
  4.9.0 stops with "Filter error: undefined filter", and h5netcdf cannot read it). Shuffle groups
  the bytes of the doubles by significance, so zlib finds the repeated exponent bytes: smaller
  files for less CPU than zlib alone (docs/performance.md, "Sweeps at scale"). ``"zstd"``
  (Zstandard level -1: about half zlib's CPU to write, larger files) is for readers known to
  have the filter; ``"none"`` writes raw chunks.
- **Checksums.** An HDF5 Fletcher-32 checksum on every array variable: a chunk damaged on disk
  fails to read (netCDF4 raises ``RuntimeError: NetCDF: HDF error``) instead of returning changed
  numbers. It needs chunked storage, which HDF5 picks for variables given no chunk sizes.
- **Fill values.** None on coordinates and integer variables (status codes, counters: every
  value is real); NaN on floating-point data (a point without that output).
- **Compression only where it pays:** arrays of more than :data:`MIN_COMPRESSED` values.

Pure Python and numpy: reading or writing a file never imports numba through here.
"""

from __future__ import annotations

import math

import numpy as np

# Accepted spellings of ``compress`` (the API, ``run --compress``, a sweep's [output] compress).
CODECS = ("zlib", "zstd", "none")
DEFAULT_CODEC = "zlib"
# The encoding keys of each codec, as xarray spells them. The netCDF4 library applies shuffle
# with zlib only (it drops it for zstd, whose fast levels gain little from it anyway).
_CODEC_KEYS = {
    "zlib": {"zlib": True, "complevel": 1, "shuffle": True},
    "zstd": {"compression": "zstd", "complevel": -1},
    "none": {},
}
# Arrays this small are stored as they are: compression would save bytes no one notices.
MIN_COMPRESSED = 4096


def codec(compress) -> str:
    """The codec name for ``compress``: one of :data:`CODECS`, ``True`` (the default codec) or
    ``False``/``None`` (``"none"``). ValueError names the allowed values otherwise."""
    if compress is True:
        return DEFAULT_CODEC
    if compress is False or compress is None:
        return "none"
    if isinstance(compress, str) and compress in CODECS:
        return compress
    raise ValueError(f"compress must be one of {', '.join(CODECS)} (or True/False); "
                     f"got {compress!r}")


def variable_encoding(shape, dtype, *, coordinate: bool = False, compress=True,
                      chunks=None) -> dict:
    """The encoding of one variable (xarray's ``to_netcdf`` spelling) under the module's policy.

    Parameters
    ----------
    shape : tuple of int
    dtype : numpy dtype or its spelling
    coordinate : bool
        A coordinate variable: no fill value, never compressed.
    compress : str or bool
        See :func:`codec`.
    chunks : tuple of int, optional
        Chunk sizes of a data variable (default: the library's choice).
    """
    dtype = np.dtype(dtype)
    e = {}
    if coordinate or dtype.kind in "iub":
        e["_FillValue"] = None
    elif dtype.kind == "f":
        e["_FillValue"] = np.nan
    name = codec(compress)
    if (name != "none" and not coordinate and dtype.kind in "fiu"
            and math.prod(shape) > MIN_COMPRESSED):
        e.update(_CODEC_KEYS[name])
    if len(shape) > 0 and dtype.kind in "fiub":
        e["fletcher32"] = True
        # Checksummed arrays are stored in chunks; given sizes hold compressed or not (a writer
        # that encodes chunks itself relies on them).
        if chunks is not None and not coordinate:
            e["chunksizes"] = tuple(int(c) for c in chunks)
    return e


def encoding(ds, compress=True, chunks=None) -> dict:
    """``{name: encoding}`` of every variable of the Dataset ``ds`` (:func:`variable_encoding`).

    ``chunks``: None, or ``chunks(name, shape, dtype)`` giving a variable's chunk sizes.
    """
    return {name: variable_encoding(var.shape, var.dtype, coordinate=name in ds.coords,
                                    compress=compress,
                                    chunks=None if chunks is None else chunks(name, var.shape,
                                                                              var.dtype))
            for name, var in ds.variables.items()}


def create_variable(nc, name: str, dtype, dims, enc: dict):
    """``nc.createVariable`` (netCDF4) with the encoding ``enc`` of :func:`variable_encoding`.

    Values are written as they are (no masking or scaling: NaN stays NaN).
    """
    # "_FillValue": None (xarray: no attribute) is netCDF4's fill_value=None too.
    fill = enc.get("_FillValue")
    codec_name = enc.get("compression", "zlib" if enc.get("zlib") else None)
    var = nc.createVariable(name, dtype, dims, fill_value=fill,
                            compression=codec_name, complevel=enc.get("complevel", 4),
                            shuffle=enc.get("shuffle", False), chunksizes=enc.get("chunksizes"),
                            fletcher32=enc.get("fletcher32", False))
    var.set_auto_maskandscale(False)
    return var
