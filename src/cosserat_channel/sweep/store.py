"""Nothing lost on a crash: the working store of a run, and the atomic write of its result.

A run writing ``OUT.nc`` keeps its finished work in ``OUT.nc.partial/``::

    OUT.nc.partial/
      manifest.json        sweep sha256, grid shape, reduction, block size, plan digest, version
      lock                 flock'ed by the live run: two runs never share a store
      block_00000.npz      one file per finished block: triples, res, steps, one_minus[, profiles]
      ...

Every file is written under a temporary name and ``os.replace``'d, so a block file is either
complete or absent, whatever kills the process (``kill -9`` included; the files are not fsync'ed,
so a power cut may still lose the last blocks, which are then simply recomputed). Running the
same command again finds the finished blocks and computes only the rest; the plan is a function of
the sweep file and the manifest's options, so the result is the one an uninterrupted run gives.
A store made by another sweep file (or other options, or another package version) is never
reused or mixed: the run stops with a one-line message saying what to do.

The result goes to a temporary file inside the store and is ``os.replace``'d onto ``OUT.nc`` only
when complete: an existing ``OUT.nc`` is replaced whole or left alone. Then the store is removed.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import zipfile

import numpy as np

from ..files import atomic_output, output_problem
from .spec import SweepError

MANIFEST = "manifest.json"
LOCK = "lock"
FORMAT = 1
BLOCK_FIELDS = ("triples", "res", "steps", "one_minus")


def partial_dir(output: str) -> str:
    """The working store of ``output``."""
    return os.fspath(output) + ".partial"


def check_writable(output: str) -> None:
    """Raise :class:`SweepError` unless ``output`` (and its store beside it) can be created."""
    problem = output_problem(output)
    if problem:
        raise SweepError(problem)


def _write_bytes(tmp: str, data: bytes) -> None:
    with open(tmp, "wb") as f:
        f.write(data)


def _save_block(tmp: str, result: dict) -> None:
    # Through a file object: np.savez would append ".npz" to a path without it.
    with open(tmp, "wb") as f:
        np.savez(f, **result)


class WorkStore:
    """Finished blocks of one run: on disk under ``OUT.nc.partial/``, or in memory (no output).

    Open with :meth:`open`, which refuses a store of another sweep; ``close`` releases the lock.
    """

    def __init__(self, directory: str | None, manifest: dict):
        self.directory = directory
        self.manifest = manifest
        self._memory: dict[int, dict] = {}
        self._lock = None

    @classmethod
    def open(cls, output: str | None, manifest: dict, given_block_size: bool) -> "WorkStore":
        """Open (or create) the store for ``output`` with this ``manifest``.

        A store whose manifest differs is refused, naming the difference; when the block size
        was not given explicitly, the existing store's is adopted (the caller re-plans with
        ``store.manifest["block_size"]``), so a plain rerun always resumes.
        """
        if output is None:
            return cls(None, manifest)
        d = partial_dir(output)
        if os.path.isdir(d):
            old = _read_manifest(d, output)
            manifest = _reconcile(old, manifest, output, d, given_block_size)
        store = cls(d, manifest)
        try:
            os.makedirs(d, exist_ok=True)
            store._take_lock(output)
            path = os.path.join(d, MANIFEST)
            if not os.path.exists(path):
                text = json.dumps(manifest, indent=1, sort_keys=True).encode()
                atomic_output(path, lambda tmp: _write_bytes(tmp, text))
            for name in os.listdir(d):
                if name.endswith(".tmp"):  # left by a killed run; never a finished block
                    os.unlink(os.path.join(d, name))
        except OSError as exc:
            store.close()
            raise SweepError(f"cannot use working store {d!r}: {exc.strerror or exc}") from None
        return store

    def _take_lock(self, output: str) -> None:
        fd = os.open(os.path.join(self.directory, LOCK), os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
                raise SweepError(
                    f"another run is writing {output!r} (its working store {self.directory!r} is "
                    "locked); wait for it or choose another -o"
                ) from None
            raise
        self._lock = fd

    def close(self) -> None:
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None

    # -- blocks -------------------------------------------------------------------------------
    def _block_path(self, k: int) -> str:
        return os.path.join(self.directory, f"block_{k:05d}.npz")

    def done(self, blocks: list[np.ndarray]) -> set[int]:
        """Indices of the blocks already finished (and matching the plan's triples)."""
        if self.directory is None:
            return set(self._memory)
        finished = set()
        for k, triples in enumerate(blocks):
            path = self._block_path(k)
            if not os.path.exists(path):
                continue
            try:
                with np.load(path) as z:
                    ok = all(f in z.files for f in BLOCK_FIELDS)
                    ok = ok and np.array_equal(z["triples"], triples)
            except (OSError, ValueError, zipfile.BadZipFile, EOFError):
                ok = False
            if ok:
                finished.add(k)
            else:  # cannot happen with atomic renames; recompute rather than trust it
                os.unlink(path)
        return finished

    def put(self, k: int, result: dict) -> None:
        """Keep block ``k``'s result (atomically on disk)."""
        if self.directory is None:
            self._memory[k] = result
            return
        atomic_output(self._block_path(k), lambda tmp: _save_block(tmp, result))

    def get(self, k: int) -> dict:
        """Block ``k``'s result."""
        if self.directory is None:
            return self._memory[k]
        with np.load(self._block_path(k)) as z:
            return {f: z[f] for f in z.files}

    # -- the result ---------------------------------------------------------------------------
    def publish(self, output: str, write) -> None:
        """``write(path)`` the result inside the store, then rename it onto ``output``."""
        # The temporary file lives inside the store, so a killed write leaves nothing beside
        # the output and the next run sweeps it away with the store's other leftovers.
        atomic_output(output, write, tmp_dir=self.directory)

    def remove(self) -> None:
        """Delete the store (after the result is in place)."""
        self.close()
        if self.directory is not None:
            shutil.rmtree(self.directory, ignore_errors=True)


def _read_manifest(d: str, output: str) -> dict:
    try:
        with open(os.path.join(d, MANIFEST)) as f:
            return json.load(f)
    except (OSError, ValueError):
        raise SweepError(
            f"{d!r} is not a readable working store of {output!r} (no valid {MANIFEST}); "
            "delete it to start over, or choose another -o"
        ) from None


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
