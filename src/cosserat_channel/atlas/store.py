"""Atlas files: the Dataset layout, writing (checksummed NetCDF) and reading, the cache's path;
the traces an interrupted build keeps beside its output (``ATLAS.nc.partial``). Imports numpy and
xarray, never numba (reading kept traces imports the solver: only a build does)."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import stat
import threading
import zipfile
from pathlib import Path

import numpy as np

from .. import status as st
from ..parameters import ParameterError
from .interpolant import Atlas
from .settings import FORMAT, FORMATS


def cache_path():
    """Where ``atlas --cache`` writes and ``plot --regime`` looks: ``atlas.nc`` in the package's
    cache directory (:func:`cosserat_channel.cache_dir`)."""
    from .. import cache_dir

    return str(cache_dir() / "atlas.nc")


# The whole-plane atlas that comes with the package (package data, built by ``make atlas``).
SHIPPED = Path(__file__).resolve().parent / "data" / "whole_plane.nc"


def shipped_path():
    """The whole-plane atlas that comes with the package, or None if this copy has none."""
    return str(SHIPPED) if SHIPPED.is_file() else None


# Where the digest of the shipped atlas is recorded: a module of its own, rewritten by
# ``make atlas`` (record_shipped_digest) in the same step that rewrites the file.
SHIPPED_DIGEST_MODULE = Path(__file__).resolve().parent / "shipped_digest.py"


def file_digest(path) -> str:
    """SHA-256 (hex) of the bytes of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def _is_shipped(path) -> bool:
    try:
        return SHIPPED.is_file() and os.path.samefile(path, SHIPPED)
    except OSError:
        return False


def shipped_problem() -> str | None:
    """Why the shipped atlas is not the file this package was built with (one line), or None
    when its digest is the one recorded in the code (:data:`SHIPPED_DIGEST_MODULE`)."""
    from .shipped_digest import SHA256

    try:
        found = file_digest(SHIPPED)
    except OSError as exc:
        return f"cannot read the shipped atlas {str(SHIPPED)!r} ({exc.strerror or exc})"
    if found == SHA256:
        return None
    return (f"the shipped atlas {str(SHIPPED)!r} is not the file this package records (sha256 "
            f"{found[:12]}..., recorded {SHA256[:12]}...): it was changed after it was built, so "
            "it is not used ('make atlas' in a source tree builds it again)")


def record_shipped_digest() -> str:
    """Record the digest of the shipped atlas in :data:`SHIPPED_DIGEST_MODULE` (what
    ``make atlas`` does after writing the file); returns it."""
    from ..files import write_text

    digest = file_digest(SHIPPED)
    write_text(SHIPPED_DIGEST_MODULE, (
        '"""The SHA-256 of the whole-plane atlas the package carries (data/whole_plane.nc), as\n'
        '``make atlas`` wrote it, recorded by that same step (:func:`.store.record_shipped_digest`).\n'
        'The file is used only when it matches (:func:`.store.shipped_problem`)."""\n'
        "\n"
        f'SHA256 = "{digest}"\n'))
    return digest


def default_atlas(A_range=None, N_range=None, note=None):
    """The atlas the commands use when none is given, as ``(atlas, path, which)``.

    The cached atlas (``atlas --cache``) first, then the shipped one: the first that can be read
    and covers ``A_range x N_range`` (any box when they are None). ``which`` is ``"cached"`` or
    ``"shipped"``; ``(None, None, None)`` when neither answers there. ``note(text)``, if given,
    is told about an atlas file that cannot be read.
    """
    for which, path in (("cached", cache_path()), ("shipped", shipped_path())):
        if path is None or not os.path.isfile(path):
            continue
        try:
            atlas = _load_once(path)
        except ParameterError as exc:
            if note is not None:
                note(f"the {which} atlas is not usable ({exc}); not used")
            continue
        if A_range is None or atlas.covers(A_range, N_range):
            return atlas, path, which
    return None, None, None


_LOADED = {}  # path -> (its stat key, the atlas): classify() without an atlas reads it once
# One load at a time: HDF5 as the netCDF4 wheels build it is not thread-safe (two threads reading
# an atlas at once can crash the process), and a thread that waited finds the atlas loaded.
_LOAD_LOCK = threading.Lock()


def _load_once(path):
    """:func:`load_atlas`, read again only when the file changed (size or modification time);
    safe to call from several threads."""
    with _LOAD_LOCK:
        st_ = os.stat(path)
        key = (st_.st_mtime_ns, st_.st_size, st_.st_ino)
        hit = _LOADED.get(path)
        if hit is None or hit[0] != key:
            hit = _LOADED[path] = (key, load_atlas(path))
        return hit[1]


def describe(atlas, path, which=None):
    """One line naming an atlas: which one (``"cached"``, ``"shipped"``), its file, tolerance,
    box and the version that built it."""
    a0, a1, n0, n1 = atlas.box
    version = atlas.attrs.get("cosserat_channel_version", "unknown")
    return (f"{which + ' atlas ' if which else 'atlas '}{path} (tol {atlas.tol:g}, A in "
            f"[{a0:g}, {a1:g}], N in [{n0:g}, {n1:g}], built by cosserat-channel {version})")


def to_dataset(atlas):
    """The atlas as an :class:`xarray.Dataset` (what :func:`save_atlas` writes)."""
    import xarray as xr

    s = atlas.samples
    return xr.Dataset(
        {
            "sample_A": ("sample", s["A"], {"long_name": "A of a trace"}),
            "sample_N": ("sample", s["N"], {"long_name": "N of a trace"}),
            "sample_low": ("sample", s["low"].astype(np.int8), {
                "long_name": "1 if the lowest traced eta has a solution"}),
            "sample_n": ("sample", s["n"].astype(np.int8), {
                "long_name": "changes of feasibility found in the traced eta range"}),
            "sample_transitions": (("sample", "transition"), s["transitions"], {
                "long_name": "eta where feasibility changes, ascending (NaN-padded)"}),
            "sample_bands": (("sample", "transition"), s["bands"], {
                "long_name": "relative distance from the transition within which the "
                             "solver's status is not reliable (NaN-padded)"}),
            "leaf_level": ("leaf", atlas.leaf_level.astype(np.int8), {
                "long_name": "depth of the leaf below its root cell"}),
            "leaf_i": ("leaf", atlas.leaf_i.astype(np.int32), {
                "long_name": "index of the leaf along A at its depth"}),
            "leaf_j": ("leaf", atlas.leaf_j.astype(np.int32), {
                "long_name": "index of the leaf along N at its depth"}),
            "leaf_low": ("leaf", atlas.leaf_low.astype(np.int8), {
                "long_name": "1 if the lowest traced eta of the leaf has a solution"}),
            "leaf_n": ("leaf", atlas.leaf_n.astype(np.int8), {
                "long_name": "transitions in the leaf; -1: unresolved (undecided)"}),
            "leaf_error": ("leaf", atlas.leaf_error, {
                "long_name": "error estimate of the leaf's log eta interpolant"}),
            "leaf_coefficients": (("leaf", "transition", "cheb_A", "cheb_N"), atlas.coef, {
                "long_name": "tensor Chebyshev coefficients of log eta on the leaf"}),
            "leaf_degree": (("leaf", "direction"), atlas.leaf_degree.astype(np.int8), {
                "long_name": "Chebyshev degree of the leaf along A and N"}),
            "leaf_transition_error": (("leaf", "transition"), atlas.leaf_transition_error, {
                "long_name": "error estimate of each transition of the leaf"}),
            "leaf_band": ("leaf", atlas.leaf_band, {
                "long_name": "largest noise band of the traces at the leaf's nodes"}),
        },
        attrs={"title": "cosserat-channel solvability atlas", "format": FORMAT,
               "Conventions": st.CONVENTIONS, "A_min": atlas.box[0], "A_max": atlas.box[1], "N_min": atlas.box[2],
               "N_max": atlas.box[3], "roots_A": atlas.roots[0], "roots_N": atlas.roots[1],
               "degree": atlas.degree, "max_depth": atlas.max_depth, "tol": atlas.tol,
               "eta_min": atlas.eta_range[0], "eta_max": atlas.eta_range[1], **atlas.attrs},
    )


# What an atlas file may declare, checked before anything is built from it: the raster of
# leaves (roots_A * roots_N * 4^max_depth cells, int32) is the largest thing a reader makes
# (what ``boundary`` and ``classify`` look leaves up in): 2^26 cells are 256 MB, and the
# default box at the deepest build (6 x 3 roots, depth 8) is 1.2 million.
MAX_RASTER_CELLS = 1 << 26
MAX_FILE_DEGREE = 64  # a leaf's Chebyshev degree (check_build_arguments' largest max_degree)
MAX_FILE_TRANSITIONS = 64  # transitions of one edge
# Dimensions of an atlas file and their largest sizes: leaves at most the raster's cells, samples
# (the traces) the nodes of every leaf at the largest degree.
_MAX_DIMS = {"leaf": MAX_RASTER_CELLS, "sample": MAX_RASTER_CELLS,
             "transition": MAX_FILE_TRANSITIONS, "cheb_A": MAX_FILE_DEGREE + 1,
             "cheb_N": MAX_FILE_DEGREE + 1, "direction": 2}


def _declared_integer(a: dict, name: str, lo: int, hi: int) -> int:
    """The integer attribute ``name`` of an atlas, inside ``[lo, hi]``; ParameterError naming
    it and its range otherwise (a string, a fraction, NaN, an array)."""
    v = a.get(name)
    try:
        f = float(np.asarray(v).item())
        ok = f.is_integer() and lo <= f <= hi
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise ParameterError(f"its attribute {name} must be an integer in [{lo}, {hi}]; "
                             f"got {_shown(v)}")
    return int(f)


def _shown(v) -> str:
    """An attribute's value as a message shows it (a numpy scalar as a plain number)."""
    v = v.tolist() if isinstance(v, np.ndarray | np.generic) else v
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _declared_float(a: dict, name: str) -> float:
    v = a.get(name)
    try:
        f = float(np.asarray(v).item())
    except (TypeError, ValueError, OverflowError):
        f = float("nan")
    if not np.isfinite(f):
        raise ParameterError(f"its attribute {name} must be a finite number; got {_shown(v)}")
    return f


def check_declared(a: dict, sizes: dict) -> None:
    """ParameterError (one clause naming the attribute or dimension and its allowed range) when
    an atlas file's attributes ``a`` or dimension ``sizes`` are beyond what an atlas can be:
    checked before its arrays are read or anything is built from them."""
    from .settings import MAX_DEPTH_LIMIT, TOL_MAX, TOL_MIN

    for dim, size in sizes.items():
        top = _MAX_DIMS.get(dim)
        if top is None:
            raise ParameterError(f"it has a dimension {dim!r} that no atlas has")
        if size > top:
            raise ParameterError(f"its dimension {dim} has {size:,} entries, beyond the "
                                 f"{top:,} an atlas can have")
    _declared_integer(a, "degree", 1, MAX_FILE_DEGREE)
    depth = _declared_integer(a, "max_depth", 0, MAX_DEPTH_LIMIT)
    ra = _declared_integer(a, "roots_A", 1, MAX_RASTER_CELLS)
    rn = _declared_integer(a, "roots_N", 1, MAX_RASTER_CELLS)
    if ra * rn << (2 * depth) > MAX_RASTER_CELLS:
        raise ParameterError(f"its roots_A x roots_N x 4^max_depth = {ra} x {rn} x 4^{depth} "
                             f"cells are beyond the {MAX_RASTER_CELLS:,} an atlas can have")
    a0, a1, n0, n1 = (_declared_float(a, k) for k in ("A_min", "A_max", "N_min", "N_max"))
    if not (a0 < a1 and n0 < n1):
        raise ParameterError(f"its box must have A_min < A_max and N_min < N_max; got A "
                             f"[{a0:g}, {a1:g}], N [{n0:g}, {n1:g}]")
    tol = _declared_float(a, "tol")
    if not TOL_MIN <= tol <= TOL_MAX:
        raise ParameterError(f"its attribute tol must be in [{TOL_MIN:g}, {TOL_MAX:g}]; got "
                             f"{tol!r}")
    lo, hi = _declared_float(a, "eta_min"), _declared_float(a, "eta_max")
    if not 0 < lo < hi:
        raise ParameterError(f"its eta range must be 0 < eta_min < eta_max; got {lo:g}, {hi:g}")


def _check_leaves(atlas) -> None:
    """ParameterError when the leaves of ``atlas`` do not lie in its quadtree, or their arrays
    do not fit together (each is indexed by the others when the atlas is used)."""
    n = atlas.leaf_level.shape
    arrays = {"leaf_i": atlas.leaf_i, "leaf_j": atlas.leaf_j, "leaf_low": atlas.leaf_low,
              "leaf_n": atlas.leaf_n, "leaf_error": atlas.leaf_error}
    for name, arr in arrays.items():
        if arr.shape != n:
            raise ParameterError(f"its {name} has shape {arr.shape}, leaf_level {n}")
    level = atlas.leaf_level
    if level.size and not ((level >= 0) & (level <= atlas.max_depth)).all():
        raise ParameterError(f"its leaf_level must be in [0, max_depth = {atlas.max_depth}]")
    for name, idx, roots in (("leaf_i", atlas.leaf_i, atlas.roots[0]),
                             ("leaf_j", atlas.leaf_j, atlas.roots[1])):
        if idx.size and not ((idx >= 0) & (idx < np.left_shift(roots, level))).all():
            raise ParameterError(f"its {name} must be in [0, roots << leaf_level)")
    t = atlas.coef.shape[1] if atlas.coef.ndim == 4 else -1
    if atlas.coef.ndim != 4 or atlas.coef.shape[0] != n[0]:
        raise ParameterError(f"its leaf_coefficients have shape {atlas.coef.shape}; expected "
                             f"({n[0]}, transition, cheb_A, cheb_N)")
    if atlas.leaf_n.size and not ((atlas.leaf_n >= -1) & (atlas.leaf_n <= t)).all():
        raise ParameterError(f"its leaf_n must be in [-1, {t}] (the transitions it holds)")
    deg = atlas.leaf_degree
    if deg.shape != (n[0], 2) or (deg.size and not (
            (deg >= 0).all() and (deg[:, 0] < atlas.coef.shape[2]).all()
            and (deg[:, 1] < atlas.coef.shape[3]).all())):
        raise ParameterError("its leaf_degree does not fit its leaf_coefficients")


def from_dataset(ds):
    """The inverse of :meth:`to_dataset`; ParameterError if ``ds`` is not an atlas."""
    if ds.attrs.get("format") not in FORMATS:
        raise ParameterError(f"not a solvability atlas (format {ds.attrs.get('format')!r}, "
                             f"expected {FORMAT!r})")
    a = dict(ds.attrs)
    check_declared(a, dict(ds.sizes))
    keys = ("title", "format", "A_min", "A_max", "N_min", "N_max", "roots_A", "roots_N",
            "degree", "max_depth", "tol", "eta_min", "eta_max")
    v = {k: np.asarray(ds[k].values) for k in ds.data_vars}
    return Atlas(
        box=(float(a["A_min"]), float(a["A_max"]), float(a["N_min"]), float(a["N_max"])),
        roots=(int(a["roots_A"]), int(a["roots_N"])), degree=int(a["degree"]),
        max_depth=int(a["max_depth"]), tol=float(a["tol"]),
        eta_range=(float(a["eta_min"]), float(a["eta_max"])),
        leaf_level=v["leaf_level"].astype(np.int64), leaf_i=v["leaf_i"].astype(np.int64),
        leaf_j=v["leaf_j"].astype(np.int64), leaf_low=v["leaf_low"].astype(np.int8),
        leaf_n=v["leaf_n"].astype(np.int8), leaf_error=v["leaf_error"].astype(float),
        coef=v["leaf_coefficients"].astype(float),
        samples={"A": v["sample_A"], "N": v["sample_N"], "low": v["sample_low"],
                 "n": v["sample_n"], "transitions": v["sample_transitions"],
                 **({"bands": v["sample_bands"]} if "sample_bands" in v else {})},
        attrs={k: val for k, val in a.items() if k not in keys},
        leaf_degree=v["leaf_degree"].astype(np.int64) if "leaf_degree" in v else None,
        leaf_band=v["leaf_band"].astype(float) if "leaf_band" in v else None,
        leaf_transition_error=(v["leaf_transition_error"].astype(float)
                               if "leaf_transition_error" in v else None),
    )


def save_atlas(atlas, path, replace=True):
    """Write ``atlas`` to ``path`` (NetCDF, checksummed) through :func:`files.write_dataset`
    (``replace`` False: never over a file there, :func:`files.atomic_output`)."""
    from ..files import write_dataset

    write_dataset(path, to_dataset(atlas), replace=replace)


def _read(path):
    """The atlas file at ``path``, its declared attributes and sizes checked
    (:func:`check_declared`) before its arrays are read: a small file must not declare
    gigabytes."""
    import xarray as xr

    try:
        ds = xr.open_dataset(path)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ParameterError(f"cannot read atlas {str(path)!r}: {' '.join(str(exc).split())}") \
            from None
    with ds:
        if ds.attrs.get("format") in FORMATS:
            try:
                check_declared(dict(ds.attrs), dict(ds.sizes))
            except ParameterError as exc:
                raise ParameterError(f"{str(path)!r} is not a usable atlas: {exc}") from None
        try:
            return ds.load()
        except (OSError, ValueError, RuntimeError) as exc:
            raise ParameterError(f"cannot read atlas {str(path)!r}: "
                                 f"{' '.join(str(exc).split())}") from None


def load_atlas(path):
    """Read an atlas written by :func:`save_atlas`; ParameterError (one line) if it is not one,
    or if it is the shipped atlas and its content is not what the package records
    (:func:`shipped_problem`)."""
    if _is_shipped(path):
        problem = shipped_problem()
        if problem:
            raise ParameterError(problem)
    ds = _read(path)
    try:
        atlas = from_dataset(ds)
    except (KeyError, ParameterError, ValueError, TypeError) as exc:
        raise ParameterError(f"{str(path)!r} is not a solvability atlas ({exc})") from None
    try:
        _check_leaves(atlas)
    except ParameterError as exc:
        raise ParameterError(f"{str(path)!r} is not a usable atlas: {exc}") from None
    problem = values_problem(atlas)
    if problem:
        raise ParameterError(f"{str(path)!r} is a damaged atlas: {problem}")
    return atlas


def values_problem(atlas) -> str | None:
    """What makes the numbers of ``atlas`` unusable (one clause), or None: a transition of a
    resolved leaf whose coefficients are not finite, an error estimate that is NaN."""
    n = np.asarray(atlas.leaf_n)
    coef = np.asarray(atlas.coef)
    present = np.arange(coef.shape[1])[None, :] < n[:, None]
    finite = np.isfinite(coef).all(axis=(2, 3)) if coef.ndim == 4 else np.isfinite(coef)
    bad = np.flatnonzero((present & ~finite).any(axis=1))
    if bad.size:
        return f"{bad.size} resolved leaves (the first: leaf {bad[0]}) have non-finite coefficients"
    err = np.asarray(atlas.leaf_error)
    if np.isnan(err).any():
        return f"{int(np.isnan(err).sum())} leaves have a NaN error estimate"
    return None


# The kept traces of an interrupted build: one .npz file beside the atlas it was to write.
PARTIAL_FORMAT = "cosserat-channel atlas traces 1"
_EDGE_SCALARS = ("eta_max", "kind", "eta_min", "status_above", "continued")
_EDGE_ARRAYS = ("transitions", "bands", "tangential", "smooth", "slopes")  # one per transition


def partial_path(output):
    """Where a build writing ``output`` keeps its traces when it is interrupted."""
    return os.fspath(output) + ".partial"


def traces_key(A_range, N_range, tol, degree, max_depth, eta_range, max_degree, roots=None,
               uniform=False) -> dict:
    """Everything the traces of :func:`build_atlas` depend on: its arguments (as
    :func:`check_build_arguments` returns them), the package's version and the digest of its
    sources. Kept traces are resumed only by a build with the same key."""
    from .. import __version__, source_digest

    return {"format": PARTIAL_FORMAT, "cosserat_channel_version": __version__,
            "sources": source_digest(), "A": [float(v) for v in A_range],
            "N": [float(v) for v in N_range], "tol": float(tol), "degree": int(degree),
            "max_degree": int(max_degree), "max_depth": int(max_depth),
            "eta_range": [float(v) for v in eta_range],
            "roots": None if roots is None else [int(v) for v in roots],
            "uniform": bool(uniform)}


def save_traces(path, traces, key):
    """Write ``traces`` (:func:`build_atlas`'s, by ``(A, N)``) with ``key``
    (:func:`traces_key`) to ``path``, a regular file, through :func:`files.write_npz`."""
    from ..files import write_npz

    trs = list(traces.values())
    edges = [tr.edge for tr in trs]
    arrays = {"key": np.array(json.dumps(key, sort_keys=True)),
              "A": np.array([k[0] for k in traces], dtype=float),
              "N": np.array([k[1] for k in traces], dtype=float),
              "low": np.array([tr.low for tr in trs], dtype=bool),
              "solves": np.array([tr.solves for tr in trs], dtype=np.int64),
              "n": np.array([e.transitions.size for e in edges], dtype=np.int64)}
    for name in _EDGE_SCALARS:
        arrays[name] = np.array([getattr(e, name) for e in edges])
    for name in _EDGE_ARRAYS:
        arrays[name] = np.concatenate([np.asarray(getattr(e, name)) for e in edges]
                                      + [np.empty(0)])

    write_npz(path, arrays, stream=False)


def load_traces(path, key):
    """The traces kept at ``path`` by a build with ``key`` (:func:`traces_key`), by ``(A, N)``,
    or None when there is nothing at ``path``.

    ParameterError (one line, naming ``path``) when ``path`` is not a regular file (a directory,
    a FIFO, a device, a symbolic link: never opened or followed), cannot be read as kept traces,
    or holds another build's (naming the arguments that differ). The file is left as it is.
    """
    from ..files import describe
    from ..regimes.edge import Edge
    from .tracer import _Trace

    path = os.fspath(path)
    move = "move it away, or choose another output"
    try:
        mode = os.lstat(path).st_mode
    except OSError as exc:
        if isinstance(exc, FileNotFoundError) or exc.errno in (errno.ENAMETOOLONG, errno.ENOTDIR):
            return None  # nothing there, nor can there be
        raise ParameterError(f"cannot look at {path!r}: {exc.strerror}; it is left alone: "
                             f"{move}") from None
    if not stat.S_ISREG(mode):
        raise ParameterError(f"{path!r} is {describe(mode)}, not the traces of an interrupted "
                             f"atlas; it is left alone: {move}")
    try:
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as z:
            v = {name: z[name] for name in z.files}
        theirs = json.loads(str(v["key"]))
        n = v["n"].astype(np.int64)
        m = len(n)
        if not (all(v[f].shape == (m,) for f in ("A", "N", "low", "solves", *_EDGE_SCALARS))
                and all(v[f].shape == (int(n.sum()),) for f in _EDGE_ARRAYS)
                and isinstance(theirs, dict)):
            raise ValueError("its arrays do not fit together")
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise ParameterError(f"{path!r} cannot be read as the traces of an interrupted atlas "
                             f"({' '.join(str(exc).split())}); it is kept: {move}") from None
    if theirs != json.loads(json.dumps(key, sort_keys=True)):
        diff = [f"{k} {theirs.get(k)!r} there, {key.get(k)!r} here"
                for k in sorted(set(key) | set(theirs)) if theirs.get(k) != key.get(k)]
        raise ParameterError(f"{path!r} holds the traces of another atlas ({'; '.join(diff)}); "
                             f"it is kept: rerun with its arguments to resume it, or {move}")
    out, at = {}, np.concatenate([[0], np.cumsum(n)])
    for k in range(m):
        per = {f: v[f][at[k]:at[k + 1]] for f in _EDGE_ARRAYS}
        e = Edge(float(v["A"][k]), float(v["N"][k]), float(v["eta_max"][k]), int(v["kind"][k]),
                 float(v["eta_min"][k]), int(v["status_above"][k]),
                 per["transitions"].astype(float), per["bands"].astype(float),
                 per["tangential"].astype(bool), per["smooth"].astype(bool),
                 per["slopes"].astype(float), bool(v["continued"][k]))
        out[(e.A, e.N)] = _Trace(bool(v["low"][k]), e.transitions, e.bands, e,
                                 int(v["solves"][k]))
    return out
