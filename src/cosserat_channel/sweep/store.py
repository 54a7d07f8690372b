"""Nothing lost on a crash: the working store of a run, and the atomic write of its result.

A run writing ``OUT.nc`` keeps its finished work in ``OUT.nc.partial/``::

    OUT.nc.partial/
      cosserat-channel-store   the marker written when the store is made: only a directory
                           holding it is ever adopted (resumed, cleaned, deleted); any other
                           OUT.nc.partial (a user's directory, a symbolic link, a file) is refused
      manifest.json        sweep sha256, grid shape, reduction, block size, plan digest, version
      lock                 flock'ed by the live run: two runs never share a store
      block_00000.npz      one file per finished block: triples, res, steps, one_minus[, profiles],
      ...                  and the sha256 digest of all of them (see below)
      scratch/             while the result is written: the plug-edge values regrouped by tile
                           (see .writer), rebuilt from the blocks by every run that gets there

Every file is written under a temporary name and ``os.replace``'d, so a block file is either
complete or absent, whatever kills the process (``kill -9`` included; the files are not fsync'ed,
so a power cut may still lose the last blocks, which are then simply recomputed).

A block is trusted only if its ``digest`` field is the sha256 of its arrays *and* of the store's
identity (format, sweep sha256, plan sha256, package version) and its index: a block damaged on
disk (flipped bytes, truncation), edited (``res * 1.5`` saved back), moved to another index or
copied from another sweep's store fails the check, is logged as a warning, deleted and computed
again, on resume and at assembly alike; it never reaches the result and never raises. This guards
against damage and accidents, not against someone who recomputes the digest on purpose. Because
the digest binds each block to its sweep and plan, an unreadable manifest is not fatal either: it
is written anew and every block that still checks out is reused; nor is an edited one: when the
manifest does not match the run, the blocks decide (one that checks out under the run's own
manifest proves the store the run's, see ``engine._proven_plan``). Running the
same command again finds the finished blocks and computes only the rest; the plan is a function of
the sweep file and the manifest's options, so the result is the one an uninterrupted run gives.
A store made by another sweep file (or other options, or another package version) is never
reused or mixed: none of its blocks checks out, and the run stops with a one-line message saying
what to do.

The result goes to a temporary file inside the store and is ``os.replace``'d onto ``OUT.nc`` only
when complete: an existing ``OUT.nc`` is replaced whole or left alone. Then the store is removed,
and only then its lock let go. A run takes the lock before it decides anything about ``OUT.nc``
(:meth:`WorkStore.open`), so it sees the result of a run that finished meanwhile.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import logging
import os
import shutil
import stat

import numpy as np

from ..files import (
    STORE_MARKER,
    atomic_output,
    describe,
    name_problem,
    netcdf_output,
    output_problem,
    write_npz,
)
from .spec import SweepError

MANIFEST = "manifest.json"
LOCK = "lock"
# Present when the run that made the store was asked to replace the output (``overwrite``): a
# resumed run finishes the job it was given, so a plain rerun of a killed ``--overwrite`` run
# still replaces the earlier file, and a run never asked to replace never does.
OVERWRITE = "overwrite"
FORMAT = 1
BLOCK_FIELDS = ("triples", "res", "steps", "one_minus")
DIGEST = "digest"
# The manifest entries a block's digest binds it to.
IDENTITY = ("format", "sweep_sha256", "plan_sha256", "cosserat_channel_version")

log = logging.getLogger("cosserat_channel.sweep")


class BlockDamaged(Exception):
    """A block file that is missing, unreadable, or whose digest does not match its content."""


def partial_dir(output: str) -> str:
    """The working store of ``output``."""
    return os.fspath(output) + ".partial"


# What the marker holds: a directory is adopted as a store only if its marker says exactly this.
MARKER_TEXT = b"a working store of cosserat-channel, deleted when its run finishes\n"


def check_writable(output: str) -> None:
    """Raise :class:`SweepError` unless ``output`` (and its store beside it) can be created: a
    regular file, since the result is renamed onto it from the store, and no ``OUT.nc.partial``
    beside it but a store (:func:`foreign_store`). Whether a file already at ``output`` is kept
    is decided under the store's lock (see :mod:`.engine`)."""
    problem = output_problem(output, stream=False, overwrite=True) or \
        name_problem(partial_dir(output)) or foreign_store(partial_dir(output))
    if problem:
        raise SweepError(problem)


def foreign_store(d: str) -> str | None:
    """Why ``d`` may not be used as a working store (one line), or None when it is one (a
    directory, not a link, holding the marker written when it was made) or does not exist."""
    if not os.path.lexists(d):
        return None
    how = "it is left alone: move it away, or choose another -o"
    if os.path.islink(d):
        return f"{d} is a symbolic link, not a working store of cosserat-channel; {how}"
    if not os.path.isdir(d):
        return f"{d} exists and is not a working store of cosserat-channel (not a directory); {how}"
    if not _is_marker(os.path.join(d, STORE_MARKER)):
        return (f"{d} is a directory that cosserat-channel did not make (it holds no "
                f"{STORE_MARKER} marker), not a working store; {how}")
    return None


def _not_a_file(path: str) -> str | None:
    """What is at ``path`` (not following a link) if it exists and is not a regular file."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    return None if stat.S_ISREG(mode) else describe(mode)


def _check_entry(path: str, role: str) -> None:
    """SweepError naming ``path``, an entry of a store, if it is there and not a regular file."""
    what = _not_a_file(path)
    if what is not None:
        raise SweepError(f"{path} is {what}, not {role} written by a run: move it out of the "
                         "working store and run again (the finished blocks are kept)")


def _is_marker(path: str) -> bool:
    try:
        st = os.lstat(path)
        # A regular file of the right size only: opening a FIFO would wait for ever.
        if not stat.S_ISREG(st.st_mode) or st.st_size != len(MARKER_TEXT):
            return False
        with open(path, "rb") as f:
            return f.read() == MARKER_TEXT
    except OSError:
        return False


def _write_bytes(tmp: str, data: bytes) -> None:
    with open(tmp, "wb") as f:
        f.write(data)


def block_digest(identity: dict, k: int, arrays: dict) -> str:
    """sha256 of a block: the store's identity, its index, and every array (name, type, shape,
    bytes) in name order."""
    h = hashlib.sha256()
    h.update(json.dumps([identity.get(key) for key in IDENTITY] + [int(k)]).encode())
    for name in sorted(arrays):
        if name == DIGEST:
            continue
        a = np.ascontiguousarray(arrays[name])
        h.update(json.dumps([name, a.dtype.str, list(a.shape)]).encode())
        h.update(a.reshape(-1).view(np.uint8) if a.size else b"")  # the bytes, not a copy
    return h.hexdigest()


class WorkStore:
    """Finished blocks of one run: on disk under ``OUT.nc.partial/``, or in memory (no output).

    Open with :meth:`open`, which refuses a store of another sweep; ``close`` releases the lock.
    """

    def __init__(self, directory: str | None, manifest: dict):
        self.directory = directory
        self.manifest = manifest
        self.created = False  # True when this run made the store (nothing to resume)
        # Whether publish may replace a file at the output (the run's overwrite): else a file
        # that appeared there while the run worked is kept.
        self.replace_output = False
        # Why the manifest on disk does not fit this run (None when it does); the blocks' digests
        # decide then whether the store is this run's (see engine._proven_plan).
        self.disagreement: str | None = None
        self.recorded: dict | None = None  # the manifest found on disk
        self._memory: dict[int, dict] = {}
        self._lock = None

    @classmethod
    def open(cls, output: str | None, manifest: dict, given_block_size: bool) -> "WorkStore":
        """Open (or create) the store for ``output`` with this ``manifest``, and lock it.

        The lock is taken first and everything else is decided under it. When the block size
        was not given explicitly, the existing store's is adopted (the caller re-plans with
        ``store.manifest["block_size"]``), so a plain rerun always resumes. A manifest that
        differs from this run's is not trusted either way: :attr:`disagreement` says how, and
        the caller asks the blocks (:meth:`proves`), whose digests bind them to their sweep and
        plan, before it resumes (:meth:`rewrite_manifest`) or refuses with that message.
        """
        if output is None:
            return cls(None, manifest)
        d = partial_dir(output)
        store = cls(d, manifest)
        try:
            store._take_lock(output)
            _check_entry(os.path.join(d, MANIFEST), "the manifest")
            old = None if store.created else _read_manifest(d)
            store.recorded = old
            if old is not None:
                try:
                    store.manifest = _reconcile(old, manifest, output, d, given_block_size)
                except SweepError as exc:
                    store.disagreement = str(exc)
            elif not store.created:
                # Every block is bound to its sweep and plan by its digest (see the module
                # docstring), so a new manifest cannot let a foreign block through.
                log.warning("working store %s has no readable %s; writing it anew (blocks that "
                            "check out are kept, the rest are recomputed)", d, MANIFEST)
            if old is None:
                text = json.dumps(manifest, indent=1, sort_keys=True).encode()
                atomic_output(os.path.join(d, MANIFEST), lambda tmp: _write_bytes(tmp, text),
                              stream=False)
            for name in os.listdir(d):
                # Left by a killed run; never a finished block. Only files: what else is there
                # was not made by a run (see get).
                if name.endswith(".tmp") and _not_a_file(os.path.join(d, name)) is None:
                    os.unlink(os.path.join(d, name))
        except OSError as exc:
            store.close()
            raise SweepError(f"cannot use working store {d!r}: {exc.strerror or exc}") from None
        except BaseException:
            store.close()
            raise
        return store

    def _take_lock(self, output: str) -> None:
        """Create the store if it is missing (``self.created``) and lock it; SweepError if another
        run holds the lock."""
        path = os.path.join(self.directory, LOCK)
        for _ in range(100):
            try:
                os.mkdir(self.directory)
                self.created = True
                atomic_output(os.path.join(self.directory, STORE_MARKER),
                              lambda tmp: _write_bytes(tmp, MARKER_TEXT), stream=False)
            except FileExistsError:
                self.created = False
                # Nothing is created in a directory that is not a store: not even the lock file.
                problem = foreign_store(self.directory)
                if problem:
                    raise SweepError(problem) from None
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            except FileNotFoundError:
                continue  # the store was removed meanwhile by the run that finished it
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
                    raise SweepError(
                        f"another run is writing {output!r} (its working store {self.directory!r} "
                        "is locked); wait for it or choose another -o"
                    ) from None
                raise
            # A run that finishes removes its store: the lock taken must still be the store's.
            try:
                ours = os.path.samestat(os.fstat(fd), os.stat(path))
            except FileNotFoundError:
                ours = False
            if ours:
                self._lock = fd
                return
            os.close(fd)
        raise SweepError(f"cannot lock working store {self.directory!r}: it keeps being removed "
                         "by another run; run again")

    def rewrite_manifest(self, manifest: dict) -> None:
        """Make ``manifest`` the store's, on disk too (blocks are checked against it from now)."""
        self.manifest = manifest
        self.disagreement = None
        text = json.dumps(manifest, indent=1, sort_keys=True).encode()
        atomic_output(os.path.join(self.directory, MANIFEST), lambda tmp: _write_bytes(tmp, text),
                      stream=False)

    def blocks_on_disk(self) -> list[int]:
        """Indices of the block files present, in order."""
        found = []
        for name in os.listdir(self.directory):
            if name.startswith("block_") and name.endswith(".npz") and name[6:-4].isdigit():
                found.append(int(name[6:-4]))
        return sorted(found)

    def proves(self, manifest: dict, blocks: list[np.ndarray], limit: int = 8) -> bool:
        """Whether a block of the store checks out under ``manifest`` and the plan's ``blocks``
        (the first ``limit`` block files are tried): the store is then that run's."""
        saved = self.manifest
        self.manifest = manifest
        try:
            for k in [k for k in self.blocks_on_disk() if k < len(blocks)][:limit]:
                try:
                    self.get(k, blocks[k])
                    return True
                except BlockDamaged:
                    continue
            return False
        finally:
            self.manifest = saved

    def close(self) -> None:
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None

    # -- blocks -------------------------------------------------------------------------------
    def _block_path(self, k: int) -> str:
        return os.path.join(self.directory, f"block_{k:05d}.npz")

    def done(self, blocks: list[np.ndarray]) -> set[int]:
        """Indices of the blocks already finished whose digest checks out.

        Every block file is read whole and checked (:meth:`get`); one that fails is logged,
        deleted and left to be computed again.
        """
        if self.directory is None:
            return set(self._memory)
        finished = set()
        for k, triples in enumerate(blocks):
            if not os.path.lexists(self._block_path(k)):
                continue
            try:
                self.get(k, triples)
            except BlockDamaged as exc:
                self.discard(k, str(exc))
                continue
            finished.add(k)
        return finished

    def put(self, k: int, result: dict) -> None:
        """Keep block ``k``'s result (atomically on disk, with its digest: ``result["digest"]``
        when the process that solved the block computed it, :func:`block_digest` under
        :meth:`identity`, else computed here)."""
        if self.directory is None:
            self._memory[k] = result
            return
        arrays = {f: v for f, v in result.items() if f != DIGEST}
        arrays[DIGEST] = np.array(result.get(DIGEST) or block_digest(self.manifest, k, arrays))
        write_npz(self._block_path(k), arrays, stream=False)

    def identity(self) -> dict | None:
        """What a block's digest binds it to (:data:`IDENTITY` of the manifest), for a digest
        computed elsewhere (:func:`block_digest`); None for a store in memory (no digests)."""
        return None if self.directory is None else {key: self.manifest.get(key)
                                                    for key in IDENTITY}

    def get(self, k: int, triples: np.ndarray | None = None) -> dict:
        """Block ``k``'s result; :class:`BlockDamaged` unless it is complete, its digest matches
        and (when given) its triples are ``triples``.

        Something at the block's name that is not a regular file (a FIFO, whose reading would
        wait for ever, a directory, a device, a link) was not written by a run and is not
        touched: :class:`SweepError` naming it.
        """
        if self.directory is None:
            return self._memory[k]
        path = self._block_path(k)
        _check_entry(path, "a block")
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {f: z[f] for f in z.files}
        except FileNotFoundError:
            raise BlockDamaged("missing") from None
        # Whatever a damaged file makes the zip and npy readers raise (BadZipFile on a CRC
        # error, ValueError, OSError, EOFError, zlib.error, ...): the block is not usable.
        except Exception as exc:  # noqa: BLE001
            raise BlockDamaged(f"unreadable ({type(exc).__name__}: {exc})") from None
        missing = [f for f in (*BLOCK_FIELDS, DIGEST) if f not in arrays]
        if missing:
            raise BlockDamaged(f"field(s) {', '.join(missing)} missing")
        stored = arrays.pop(DIGEST)
        if stored.shape != () or stored.dtype.kind != "U" or \
                str(stored) != block_digest(self.manifest, k, arrays):
            raise BlockDamaged("digest does not match the content")
        if triples is not None and not np.array_equal(arrays["triples"], triples):
            raise BlockDamaged("holds other triples than the plan's")
        return arrays

    def discard(self, k: int, why: str) -> None:
        """Delete a damaged block (with a warning) so that it is computed again."""
        log.warning("block %d of working store %s is damaged (%s); computing it again", k,
                    self.directory, why)
        try:
            os.unlink(self._block_path(k))
        except FileNotFoundError:
            pass

    # -- the result ---------------------------------------------------------------------------
    def allow_replace(self, overwrite: bool) -> None:
        """Set :attr:`replace_output`: True when this run is asked to ``overwrite``, or when the
        run that made the store was (recorded in the store, so that resuming it finishes the job
        it was given)."""
        if self.directory is None:
            self.replace_output = overwrite
            return
        path = os.path.join(self.directory, OVERWRITE)
        if overwrite:
            atomic_output(path, lambda tmp: _write_bytes(tmp, b"replace the output\n"),
                          stream=False)
        try:
            recorded = stat.S_ISREG(os.lstat(path).st_mode)
        except FileNotFoundError:
            recorded = False
        self.replace_output = overwrite or recorded

    def publish(self, output: str, write) -> None:
        """``write(path)`` the result inside the store, then rename it onto ``output``: without
        replacing a file there unless :attr:`replace_output` (a file that appeared meanwhile is
        kept, the result beside it: :class:`files.OutputAppeared`)."""
        # The temporary file lives inside the store, so a killed write leaves nothing beside
        # the output and the next run sweeps it away with the store's other leftovers.
        # A failed write (netCDF4's RuntimeError on a full disk included) is a WriteError; the
        # store stays, so the same command writes the file again without solving anything.
        netcdf_output(output, write, tmp_dir=self.directory, stream=False,
                      replace=self.replace_output)

    def remove(self) -> None:
        """Delete the store (after the result is in place), then let its lock go: a run that
        takes the lock afterwards finds the store gone (see :meth:`_take_lock`)."""
        if self.directory is not None:
            _unlink_blocks(self.directory)
            shutil.rmtree(self.directory, ignore_errors=True)
        self.close()


def _unlink_blocks(d: str) -> None:
    """Delete the block files of store ``d`` in a few threads, the latest first. Deleting a file
    whose pages the system is writing to disk waits for that write: the waits on several files
    overlap, and the latest blocks are still in memory (134 files of 6.6 MB written beside a
    1.2 GB file, as a 10^8-point sweep leaves them: a fifth to a half of the time of deleting
    them one by one)."""
    from concurrent.futures import ThreadPoolExecutor

    try:
        names = sorted((n for n in os.listdir(d) if n.startswith("block_")), reverse=True)
    except OSError:
        return

    def unlink(name):
        try:
            os.unlink(os.path.join(d, name))
        except OSError:  # whatever is left, rmtree meets (and ignores) again
            pass

    with ThreadPoolExecutor(4, thread_name_prefix="cc-store") as pool:
        list(pool.map(unlink, names))


def _read_manifest(d: str) -> dict | None:
    """The store's manifest, or None when it is missing or damaged (see :meth:`WorkStore.open`)."""
    try:
        with open(os.path.join(d, MANIFEST), "rb") as f:
            manifest = json.loads(f.read().decode("utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict):
        return None
    if not isinstance(manifest.get("block_size"), int) or isinstance(manifest["block_size"], bool) \
            or manifest["block_size"] < 1:
        return None
    return manifest


def _reconcile(old: dict, new: dict, output: str, d: str, given_block_size: bool) -> dict:
    """The manifest to resume with, or SweepError naming why the old store cannot be reused."""
    how = f"delete {d} to start over, or choose another -o"
    if old.get("format") != FORMAT:
        raise SweepError(f"{d} has an unknown store format {old.get('format')!r}; {how}")
    if old.get("sweep_sha256") != new["sweep_sha256"]:
        raise SweepError(
            f"{d} holds an unfinished run of a different sweep file (sha256 "
            f"{str(old.get('sweep_sha256'))[:12]}..., this one {new['sweep_sha256'][:12]}...) for "
            f"{output}; {how}"
        )
    if old.get("cosserat_channel_version") != new["cosserat_channel_version"]:
        raise SweepError(
            f"{d} was written by cosserat-channel {old.get('cosserat_channel_version')}, this is "
            f"{new['cosserat_channel_version']}; {how}"
        )
    if old.get("reduced") != new["reduced"]:
        flag = "without" if old.get("reduced") else "with"
        raise SweepError(f"{d} was started {flag} --no-reduce; rerun the same way, or {how}")
    if given_block_size and old.get("block_size") != new["block_size"]:
        raise SweepError(
            f"{d} was started with --block-size {old.get('block_size')}; rerun with that (or "
            f"without --block-size), or {how}"
        )
    if old.get("shape") != new["shape"]:
        raise SweepError(f"{d} has grid shape {old.get('shape')}, this sweep {new['shape']}; {how}")
    return old
