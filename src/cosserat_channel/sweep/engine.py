"""Run a sweep: spec -> plan -> blocks solved in parallel -> working store -> NetCDF.

:func:`run_sweep` is the whole pipeline; ``cosserat-channel run`` is a thin wrapper around it.

The pieces: a block is solved by :mod:`.block`, the blocks run on a pool of threads or a
``dask.distributed`` cluster (:mod:`.schedulers`), the disk and memory a run needs are checked
first (:mod:`.budget`). The results come back to this process, which alone writes the store and
the file (workers need no shared file system); the file's tiles are derived and their chunks
encoded where the blocks are solved (:mod:`.encode`), and this process places the encoded
chunks. Every finished block is saved at once (see :mod:`~cosserat_channel.sweep.store`), so a
killed run resumes where it stopped.

The result file is written tile by tile (:mod:`.writer`), so memory follows the block and the
tile sizes, not the grid; the disk space it needs is checked before anything is computed. Blocks
are planned tile-aligned where the grid allows it (:class:`.plan.Plan`'s groups), and a group's
tiles are written while the other blocks are solved.
"""

from __future__ import annotations

import logging
import math
import os
import stat
import time

import numpy as np

from .. import __version__
from .. import netcdf_policy
from .. import outputs as out_
from ..solver import layout
from ..files import FILE, output_kind, space_problem
from .dataset import build_dataset
from .budget import disk_needed, memory_needed, memory_problem
from .plan import Plan, count_triples
from .schedulers import (NO_WORKERS_TIMEOUT, BlockCount, ClusterEncoder, LocalEncoder,
                         _run_distributed, _run_threads, connect)
from .spec import SweepError, SweepSpec, load_sweep
from .store import FORMAT, BlockDamaged, WorkStore, check_writable
from .writer import StreamWriter, Tiles

log = logging.getLogger("cosserat_channel.sweep")


def run_sweep(path_or_mapping, output=None, *, workers=None, scheduler=None, reduce=True,
              block_size=None, progress=None, compress=None, overwrite=False,
              no_workers_timeout=None, open_result=True):
    """Solve every point of a sweep and return the labelled result (and write it to NetCDF).

    Parameters
    ----------
    path_or_mapping : str, path, mapping or SweepSpec
        A sweep file (see :mod:`.spec`), its parsed mapping, or a loaded spec.
    output : str, optional
        NetCDF file to write; default the sweep's ``[output] path`` (relative to the current
        directory). With neither, nothing is written and the Dataset is only returned.
    workers : int, optional
        Threads for the local scheduler (default ``os.cpu_count()``).
    scheduler : str or distributed.Client, optional
        Address of a ``dask.distributed`` scheduler (or a client) to run the blocks on.
    reduce : bool
        One integration per distinct ``(eps L, A, N)`` (default) or one per grid point; both give
        identical values, the second only serves to check and to measure the first.
    block_size : int, optional
        Integrations per block (default: about max(128, 16 x workers) blocks; a resumed run
        keeps the block size it started with).
    progress : callable, optional
        ``progress(done, total, text)`` (the package's progress protocol), called with the
        blocks stored so far (those of an earlier run included) at the start and after each
        block. None (default) or False: quiet. ``cosserat-channel run`` passes its status line.
    compress : str or bool, optional
        Codec of the large NetCDF variables (:mod:`cosserat_channel.netcdf_policy`):
        ``"zlib"`` (level 1 with shuffle, what every netCDF-4 reader opens), ``"zstd"``
        (Zstandard level -1: less CPU, for readers with netCDF-C's zstd filter) or ``"none"``;
        True is the default codec, False none. Default: the sweep's ``[output] compress``, else
        ``"zlib"``.
    overwrite : bool
        Compute again and replace ``output`` when it is a file already. Without it a finished
        result of this sweep is kept and returned (nothing computed), any other file is refused;
        an unfinished run of this sweep (its working store) is resumed either way.
    no_workers_timeout : float, optional
        With ``scheduler``: seconds the cluster may have no worker before the run ends with
        :class:`SchedulerLost` (default :data:`NO_WORKERS_TIMEOUT`).
    open_result : bool
        With a file written: return it opened (default), or None (``cosserat-channel run``, which
        does not read it, so that it never imports xarray for it).

    Returns
    -------
    xarray.Dataset or None
        Dims ``(eps, L, K, A, N)`` (plus ``xi`` with profiles), the requested variables, ``status``.

    Raises
    ------
    SweepError
        (a ``ValueError``) for an invalid sweep, an unwritable output, another file at the output
        (without ``overwrite``), or a working store of a different sweep in the way; nothing has
        been computed then.
    """
    t_start = time.perf_counter()
    spec = path_or_mapping
    if not isinstance(spec, SweepSpec):
        spec = load_sweep(path_or_mapping)
    if output is None:
        output = spec.output_path
    if output is not None:
        output = os.fspath(output)
        check_writable(output)
    if workers is not None and (int(workers) != workers or workers < 1):
        raise SweepError(f"workers must be a positive integer; got {workers!r}")
    n_workers = int(workers or os.cpu_count() or 1)
    if not (progress is None or progress is False or callable(progress)):
        raise SweepError(f"progress must be a callable progress(done, total, text) or None; got "
                         f"{progress!r}")
    try:
        compress = netcdf_policy.codec(spec.compress if compress is None else compress)
    except ValueError as exc:
        raise SweepError(str(exc)) from None
    if no_workers_timeout is None:
        no_workers_timeout = NO_WORKERS_TIMEOUT
    if not 0 < no_workers_timeout < math.inf:
        raise SweepError(f"no_workers_timeout must be a positive number of seconds; got "
                         f"{no_workers_timeout!r}")
    xi = _profile_xi(spec)
    # Memory and disk are checked from the grid's counts, before the plan (grid-sized) is made.
    n_triples = count_triples(spec.coords(), reduce)
    problem = memory_problem(memory_needed(spec, n_triples, xi, output, reduce, n_workers))
    if problem is None and output is not None:
        problem = space_problem(output, disk_needed(spec, n_triples, xi, output))
    if problem:
        raise SweepError(problem)
    try:
        plan = Plan(spec.coords(), reduce=reduce, block_size=block_size, workers=n_workers,
                    tile=_tile(spec, xi, output))
    except ValueError as exc:
        raise SweepError(str(exc)) from None
    # The cluster is reached before any store exists: a wrong address leaves nothing behind.
    client, own_client = (None, False) if scheduler is None else connect(scheduler)
    try:
        store = WorkStore.open(output, _manifest(spec, plan),
                               given_block_size=block_size is not None)
        store.allow_replace(overwrite)
        try:
            # Decided under the store's lock: a run of the same output that finished meanwhile
            # put its result in place before it let the lock go.
            if store.created and not overwrite and _kept(output, spec, store):
                return _opened(output) if open_result else None
            ds, times = _run(spec, plan, store, xi, output, client, n_workers, reduce,
                             progress, compress, no_workers_timeout,
                             given_block_size=block_size is not None)
        finally:
            store.close()
    finally:
        if own_client:
            client.close()
    log.info(
        "%s: solve %.2f s (%d blocks computed), assemble and write %.2f s, total %.2f s",
        output or "(not written)", times[0], times[1], times[2], time.perf_counter() - t_start,
    )
    if output is not None:
        return _opened(output) if open_result else None
    return ds


def _opened(output: str):
    """The result file ``output``, opened lazily (dask arrays), with ``ds.cosserat``."""
    import xarray as xr

    from ..results import accessor  # noqa: F401 (registers ds.cosserat)

    return xr.open_dataset(output, chunks={})


KEPT = ("{output} is already the finished result of this sweep; kept (add --overwrite to compute "
        "it again)")


def finished_result(output: str, spec: SweepSpec) -> bool:
    """True if ``output`` is already the finished result of ``spec``, False if there is no file
    there; :class:`SweepError` (the file kept) if it is another file.

    Whether a working store beside it makes it a run to resume is for the caller to decide."""
    if output_kind(output) != FILE:
        return False
    sha = None
    try:
        import netCDF4

        with netCDF4.Dataset(output) as nc:
            sha = getattr(nc, "sweep_sha256", None)
    except (OSError, ValueError, RuntimeError):
        pass
    if sha == spec.sha256:
        return True
    what = "the result of another sweep" if sha else "not a result of 'run'"
    raise SweepError(f"{output} exists ({what}); kept: add --overwrite to replace it, or choose "
                     "another -o")


def _kept(output, spec, store) -> bool:
    """:func:`finished_result` for a run that has just made its store: True (and the store, empty,
    removed) if the finished result is kept; SweepError (the store removed) if another file is."""
    try:
        kept = finished_result(output, spec)
    except SweepError:
        store.remove()
        raise
    if kept:
        store.remove()
        log.info(KEPT.format(output=output))
    return kept


def _tile(spec, xi, output):
    """The tile shape of the result file (None without a file: nothing to align to)."""
    return None if output is None else Tiles(spec.shape, 0 if xi is None else xi.size).tile


def _run(spec, plan, store, xi, output, client, n_workers, reduce, progress, compress,
         no_workers_timeout=NO_WORKERS_TIMEOUT, given_block_size=False):
    """Solve what the store lacks, writing the file as groups complete, then finish it; returns
    (Dataset or None, (solve s, blocks computed, assemble and write s))."""
    if store.disagreement is None and store.manifest["block_size"] != plan.block_size:
        plan = Plan(spec.coords(), reduce=reduce, block_size=store.manifest["block_size"],
                    tile=_tile(spec, xi, output))
    if store.disagreement is not None or store.manifest["plan_sha256"] != plan.digest():
        plan = _proven_plan(spec, plan, store, xi, output, reduce, given_block_size)
    done = store.done(plan.blocks)
    todo = [k for k in range(len(plan.blocks)) if k not in done]
    log.info(
        "%s points, %s integrations (%s) in %d blocks of <= %d; "
        "%d done before, %d to compute%s",
        f"{plan.size:,}", f"{plan.n_triples:,}", "reduced" if plan.reduce else "unreduced",
        len(plan.blocks), plan.block_size, len(done), len(todo),
        f" (resuming {store.directory})" if done else "",
    )
    progress = BlockCount(None if progress is False else progress, len(done), len(plan.blocks))

    def recompute(k):
        from .block import _block_task

        store.put(k, _block_task(plan, k, (spec.rtol, spec.atol, xi)))

    writer = encoder = None
    if output is not None:
        # Tiles are derived and encoded where the blocks are solved: beside the solving threads,
        # or on the cluster's workers.
        encoder = (LocalEncoder(n_workers) if client is None
                   else ClusterEncoder(client, no_workers_timeout))
        try:
            writer = StreamWriter(output, spec, plan, store, xi,
                                  Tiles(spec.shape, 0 if xi is None else xi.size), compress,
                                  recompute, encoder)
        except BaseException:
            if encoder is not None:
                encoder.close()
            raise
    cpu = []  # the solving threads' CPU seconds per block: inputs, kernels, storing
    if todo and client is None:
        from .block import warm_up

        warm_up()  # the kernels loaded before the clock
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if writer is not None:
            for k in sorted(done):
                writer.add(k)
        if todo:
            args = (spec.rtol, spec.atol, xi, out_.needs_stage2(spec.variables),
                    out_.needs_plug_edge(spec.variables))
            if client is None:
                _run_threads(plan, todo, store, args, n_workers, progress, writer, cpu)
            else:
                n_workers = _run_distributed(plan, todo, store, args, client, progress, writer,
                                             cpu, no_workers_timeout)
        t1 = time.perf_counter()
        during = 0 if writer is None else writer.tiles_written
        ds = assemble(spec, plan, store, xi, recompute=recompute, output=output,
                      compress=compress, writer=writer)
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    finally:
        if encoder is not None:
            encoder.close()
    t2 = time.perf_counter()
    if output is not None:
        store.remove()
    # The solving threads' CPU time (the blocks' inputs, the kernels, storing the blocks; on a
    # cluster the workers' threads, as each task measured it) over the workers: what the solve
    # alone takes on free cores. The solve phase's wall time would count the writing done
    # meanwhile as solving; what assembling and writing add is the rest of the wall time.
    solve = sum(cpu) / n_workers if cpu else t1 - t0
    if writer is not None:
        log.info("%s: solve phase %.2f s (solving threads %.2f s CPU on %d workers; the process %.2f s "
                 "CPU until the file was complete), %d of %d tiles written during it; tiles "
                 "derived and encoded %s in %.2f s CPU; writer busy %.2f s (%.2f s CPU), %.2f s "
                 "after the solve", output, t1 - t0, sum(cpu), n_workers,
                 time.process_time() - c0, during, writer.tiles.count,
                 "where solved" if writer.direct else "by the writer", writer.encode_cpu,
                 writer.busy, writer.cpu, t2 - t1)
    return ds, (solve, len(todo), t2 - t0 - solve)


def _proven_plan(spec, plan, store, xi, output, reduce, given_block_size) -> Plan:
    """The plan of this run that the store's blocks prove theirs, when its manifest does not
    match this run (edited, or written by another run); the manifest is then written anew.

    The blocks' digests bind them to the sweep, the plan and the package version, so a block
    that checks out under this run's manifest was made by this run's plan: the store is resumed.
    Tried: this run's block size and, unless one was given, the one the manifest records and the
    first block's. A store without blocks holds nothing to lose and is taken over. Otherwise
    SweepError: the manifest's disagreement with this run, or another build's plan."""
    refusal = store.disagreement or (
        f"{store.directory} was planned differently (another cosserat-channel build?); "
        f"delete {store.directory} to start over, or choose another -o")
    sizes = [plan.block_size]
    if not given_block_size:
        sizes += [(store.recorded or {}).get("block_size"), _first_block_size(store)]
    tried = set()
    for size in sizes:
        if not isinstance(size, int) or isinstance(size, bool) or size < 1 or size in tried:
            continue
        tried.add(size)
        p = plan if size == plan.block_size else Plan(spec.coords(), reduce=reduce,
                                                      block_size=size, tile=_tile(spec, xi, output))
        manifest = _manifest(spec, p)
        if not store.blocks_on_disk() or store.proves(manifest, p.blocks):
            log.warning("working store %s: its manifest does not match this run, but its blocks' "
                        "digests show they are this run's; manifest written anew, blocks that "
                        "check out kept", store.directory)
            store.rewrite_manifest(manifest)
            return p
    raise SweepError(refusal)


def _first_block_size(store) -> int | None:
    """How many integrations block 0 holds (a hint of the block size), or None."""
    path = os.path.join(store.directory, "block_00000.npz")
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return None
        with np.load(path, allow_pickle=False) as z:
            return int(z["triples"].shape[0])
    except Exception:  # noqa: BLE001 (a damaged block gives no hint; its digest fails later)
        return None


def _manifest(spec: SweepSpec, plan: Plan) -> dict:
    return {
        "format": FORMAT,
        "sweep_sha256": spec.sha256,
        "shape": list(plan.shape),
        "reduced": plan.reduce,
        "block_size": plan.block_size,
        "n_blocks": len(plan.blocks),
        "plan_sha256": plan.digest(),
        "cosserat_channel_version": __version__,
    }


def _profile_xi(spec):
    return None if not spec.profile_points else np.linspace(0.0, 1.0, spec.profile_points)


# ---------------------------------------------------------------------------------------------
# Blocks -> grid
# ---------------------------------------------------------------------------------------------
def assemble(spec: SweepSpec, plan: Plan, store: WorkStore, xi=None, recompute=None,
             output=None, compress=True, writer: StreamWriter | None = None):
    """Build the result once every block is in the store: in memory (``output`` None, returns
    the Dataset), or by finishing ``writer``'s file (the groups not yet written) and renaming
    it onto ``output`` (returns None).

    Each block read from the store is checked against its digest (:meth:`WorkStore.get`); one
    that fails (damaged on disk since the run began) is computed again by ``recompute(k)`` when
    given, and otherwise raises :class:`SweepError`.
    """
    if output is not None:
        def publish(path):
            writer.finish()
            os.replace(writer.tmp, path)

        store.publish(output, publish)
        return None
    n = plan.n_triples
    per_triple = {"res": np.empty((n, layout.N_R)), "steps": np.empty((n, 2), dtype=np.int64)}
    profiles = np.empty((n, layout.N_PROF, xi.size)) if xi is not None else None
    one_minus = np.empty(plan.size) if out_.needs_plug_edge(spec.variables) else None
    for k, triples in enumerate(plan.blocks):
        try:
            b = store.get(k, triples)
        except BlockDamaged as exc:
            if recompute is None:
                raise SweepError(f"block {k} of {store.directory} is damaged ({exc})") from None
            store.discard(k, str(exc))
            recompute(k)
            b = store.get(k, triples)
        per_triple["res"][triples] = b["res"]  # blocks hold disjoint triples and grid points
        per_triple["steps"][triples] = b["steps"]
        if profiles is not None:
            profiles[triples] = b["profiles"]
        if one_minus is not None:
            one_minus[plan.inputs(k).flat] = b["one_minus"]
    if one_minus is not None:
        one_minus = one_minus.reshape(plan.shape)
    return build_dataset(spec, plan, per_triple, one_minus, xi, profiles)
