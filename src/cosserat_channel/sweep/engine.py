"""Run a sweep: spec -> plan -> blocks solved in parallel -> working store -> NetCDF.

:func:`run_sweep` is the whole pipeline; ``cosserat-channel run`` is a thin wrapper around it.

Parallelism: each block is one :func:`batch.solve_batch` call, which holds no GIL, so dask's
threaded scheduler keeps every core busy without pickling anything; ``scheduler=ADDRESS`` sends
the same blocks to a ``dask.distributed`` cluster instead, and the results come back to this
process, which alone writes the store and the file (workers need no shared file system). Every
finished block is saved at once (see :mod:`.store`), so a killed run resumes where it stopped.

On a cluster each task carries its own block's inputs (:meth:`.plan.Plan.inputs`), nothing
scattered: a task whose worker dies is simply run again on another (or on the worker a nanny
starts in its place). Losing the scheduler ends the run with :class:`SchedulerLost`; the
finished blocks are in the store and the same command resumes.

The result file is written tile by tile (:mod:`.writer`), so memory follows the block and the
tile sizes, not the grid; the disk space it needs is checked before anything is computed. Blocks
are planned tile-aligned where the grid allows it (:class:`.plan.Plan`'s groups), and a group's
tiles are written while the other blocks are solved.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import re
import stat
import sys
import threading
import time

import numpy as np

from .. import __version__
from ..integrate import stepping
from .. import netcdf_policy
from .. import outputs as out_
from ..solver import batch, layout, stage1, stage2
from .. import status as st
from ..files import FILE, format_size, output_kind, space_problem
from . import writer as writer_
from .dataset import build_dataset
from .plan import (DEFAULT_BLOCKS, MAX_BLOCK_ENTRIES, BlockInputs, Plan, count_triples,
                   plan_memory)
from .spec import SweepError, SweepSpec, load_sweep
from .store import FORMAT, BlockDamaged, WorkStore, check_writable, partial_dir
from .writer import BUCKET, StreamWriter, Tiles

# Seconds to wait for a scheduler to answer before the run is refused (nothing created yet).
CONNECT_TIMEOUT = 5.0
# Seconds a cluster may have no worker at all before the run ends (SchedulerLost): long enough
# for a nanny or a batch system to bring lost workers back, short enough not to look hung.
NO_WORKERS_TIMEOUT = 120.0
_ADDRESS = re.compile(r"^(?:[a-z][a-z0-9+.-]*://)?\S+$")


class SchedulerLost(RuntimeError):
    """The dask cluster can no longer run the blocks: its scheduler went away mid-run, or it has
    had no worker for ``no_workers_timeout`` seconds. The finished blocks are kept in the store."""

log = logging.getLogger("cosserat_channel.sweep")


def run_sweep(path_or_mapping, output=None, *, workers=None, scheduler=None, reduce=True,
              block_size=None, progress=None, compress=None, overwrite=False,
              no_workers_timeout=None):
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
    progress : bool, optional
        Progress bar on stderr; default when stderr is a terminal.
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

    Returns
    -------
    xarray.Dataset
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
        try:
            # Decided under the store's lock: a run of the same output that finished meanwhile
            # put its result in place before it let the lock go.
            if store.created and not overwrite and _kept(output, spec, store):
                import xarray as xr

                return xr.open_dataset(output, chunks={})
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
        import xarray as xr

        return xr.open_dataset(output, chunks={})
    return ds


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
    if progress is None:
        progress = sys.stderr.isatty()

    def recompute(k):
        store.put(k, _block_task(plan, k, (spec.rtol, spec.atol, xi)))

    writer = None
    if output is not None:
        writer = StreamWriter(output, spec, plan, store, xi, Tiles(spec.shape, 0 if xi is None
                                                                   else xi.size),
                              compress, recompute)
    cpu = []  # the solving threads' CPU seconds per block: inputs, kernels, storing
    if todo and client is None:
        import dask.diagnostics  # noqa: F401 (imported and the kernels loaded before the clock)

        warm_up()
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
                 "CPU until the file was complete), %d of %d tiles written during it; writer "
                 "busy %.2f s (%.2f s CPU), %.2f s after the solve", output, t1 - t0, sum(cpu),
                 n_workers, time.process_time() - c0, during, writer.tiles.count, writer.busy,
                 writer.cpu, t2 - t1)
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


def disk_needed(spec: SweepSpec, n_triples: int, xi, output: str) -> int:
    """Bytes the run will still put on disk at its peak: the result file uncompressed (an upper
    bound), the working store's blocks, the tile buckets and the writer's mapped arrays
    (:mod:`.writer`), less what an earlier run of the same output already left in the store.
    ``n_triples``: the integrations (:func:`.plan.count_triples`, an upper bound will do)."""
    n_xi = 0 if xi is None else xi.size
    plug_edge = out_.needs_plug_edge(spec.variables)
    result = spec.size * _bytes_per_point(spec, n_xi)
    store = n_triples * (8 * layout.N_R + 16 + 8 + 8 * layout.N_PROF * n_xi)
    if plug_edge:
        store += spec.size * (8 + BUCKET.itemsize)
    held = n_triples * writer_.bytes_per_triple(n_xi)
    if held > writer_.WRITER_MEMORY:
        store += held
    have = 0
    for root, _, files in os.walk(partial_dir(output)):
        have += sum(os.lstat(os.path.join(root, f)).st_size for f in files)
    return max(0, result + store - have)


def _bytes_per_point(spec: SweepSpec, n_xi: int) -> int:
    """Bytes of one grid point in the result: its variables (float64 outputs, int32 counters),
    status, and the profiles' four float64 rows."""
    return 1 + sum(8 if v in out_.OUTPUTS else 4 for v in spec.variables) + 4 * 8 * n_xi


# What a run holds besides its plan and the writer's per-integration arrays: the tiles being
# derived and written (.writer: a dozen tile-sized temporaries, near 200 MB, two tiles at once)
# and, per worker, the block being solved and stored (its eps K entries with their grid
# indices, owners and plug-edge values).
TILE_MEMORY = 2 * (200 << 20)
BLOCK_BYTES_PER_ENTRY = 64


def memory_needed(spec: SweepSpec, n_triples: int, xi, output, reduce: bool,
                  workers: int) -> int:
    """Bytes a run holds at its peak, from the grid's counts alone (``n_triples`` from
    :func:`.plan.count_triples`): the plan, the per-integration arrays the writer (or, without
    a file, the in-memory result) keeps, the tiles in flight and the blocks being solved."""
    n_xi = 0 if xi is None else xi.size
    need = plan_memory(spec.shape, n_triples, reduce)
    held = n_triples * writer_.bytes_per_triple(n_xi)
    if output is None:  # everything in memory, the grid-sized result twice while it is built
        need += held + 2 * spec.size * _bytes_per_point(spec, n_xi)
    else:  # beyond WRITER_MEMORY the writer maps its arrays onto the disk
        need += (held if held <= writer_.WRITER_MEMORY else 0) + TILE_MEMORY
    # A block holds whole integrations, about 1/DEFAULT_BLOCKS of the grid up to
    # MAX_BLOCK_ENTRIES entries (.plan), and at least one integration's entries.
    per_triple = -(-spec.size // max(1, n_triples))
    entries = min(spec.size, max(per_triple, min(MAX_BLOCK_ENTRIES,
                                                 -(-spec.size // DEFAULT_BLOCKS))))
    return need + workers * entries * BLOCK_BYTES_PER_ENTRY


def available_memory() -> int | None:
    """Bytes this process may still take: the system's MemAvailable, or the memory left under
    the cgroup's limit (a batch job's, a container's) when that is less; None when unknown."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            current = int(f.read().strip())
        if limit != "max":
            found.append(max(0, int(limit) - current))
    except (OSError, ValueError):
        pass
    return min(found) if found else None


def memory_problem(need: int) -> str | None:
    """Why ``need`` bytes will not fit in memory (one line), or None when they will (or when the
    system cannot say)."""
    free = available_memory()
    if free is None or need <= free:
        return None
    return (f"grid: the run needs about {format_size(need)} of memory and {format_size(free)} "
            "is available; split the sweep into smaller ones (fewer distinct eps L, A and N "
            "values each), or run it where there is more")


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
# One block
# ---------------------------------------------------------------------------------------------
def solve_block(inp: BlockInputs, rtol: float, atol: float, xi=None, stage2=True,
                plug_edge=True) -> dict:
    """Run :func:`batch.solve_batch` on one block; returns the arrays the store keeps.

    ``stage2`` / ``plug_edge``: whether the sweep's variables need the velocity stage and the
    eq:13 root (:func:`outputs.needs_stage2`); what is not needed is not computed.
    """
    need = (stage2, plug_edge)
    n = inp.eta.size
    res = np.empty((n, layout.N_R))
    stats = np.zeros((n, 2, stepping.N_STATS), dtype=np.int64)
    one_minus = np.empty(inp.eps_K.size)
    xi_k = np.empty(0) if xi is None else xi
    prof = np.empty((n, layout.N_PROF, xi_k.size))
    try:
        _batch(inp, slice(0, n), rtol, atol, xi_k, res, stats, one_minus, prof, need)
    except ArithmeticError:
        # The kernel raised on some triple (a bug at a boundary of the domain, e.g. an axis
        # margin of exactly 0): redo the block triple by triple so that only that triple is lost,
        # reported as integration_failed, instead of the whole run.
        for i in range(n):
            try:
                _batch(inp, slice(i, i + 1), rtol, atol, xi_k, res, stats, one_minus, prof, need)
            except ArithmeticError as exc:
                log.warning("kernel raised %s at eta=%r, A=%r, N=%r; reported as "
                            "integration_failed", type(exc).__name__, float(inp.eta[i]),
                            float(inp.A[i]), float(inp.N[i]))
                res[i] = np.nan
                res[i, layout.R_STATUS] = st.INTEGRATION_FAILED
                stats[i] = 0
                one_minus[inp.offsets[i]:inp.offsets[i + 1]] = np.nan
                prof[i] = np.nan
    out = {
        "res": res,
        "steps": stats[:, :, stepping.STAT_ACCEPTED].copy(),
        "one_minus": one_minus,
    }
    if xi is not None:
        out["profiles"] = prof
    return out


def _batch(inp: BlockInputs, sl: slice, rtol, atol, xi_k, res, stats, one_minus, prof,
           need) -> None:
    """solve_batch on triples ``sl`` of the block (views: results land in the block's arrays)."""
    lo, hi = inp.offsets[sl.start], inp.offsets[sl.stop]
    offsets = inp.offsets[sl.start:sl.stop + 1] - lo
    batch.solve_batch(inp.eta[sl], inp.A[sl], inp.N[sl], inp.eps_K[lo:hi], offsets, rtol, atol,
                      stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, res[sl], stats[sl],
                      one_minus[lo:hi], xi_k, prof[sl], need[0], need[1])


def _block_task(plan: Plan, k: int, args) -> dict:
    # Build the inputs inside the task: a block's eps K arrays exist only while it runs.
    out = solve_block(plan.inputs(k), *args)
    out["triples"] = plan.blocks[k]
    return out


def warm_up() -> None:
    """Load (or compile) the kernels once, here, before threads or workers race to do it."""
    inp = BlockInputs(np.array([0.3]), np.array([1 / 3]), np.array([1.0]), np.array([0.05]),
                      np.array([0, 1]), np.array([0]))
    solve_block(inp, 1e-6, 1e-10, np.array([0.0, 1.0]))
    solve_block(inp, 1e-6, 1e-10, None)


# ---------------------------------------------------------------------------------------------
# Schedulers
# ---------------------------------------------------------------------------------------------
def _run_threads(plan, todo, store, args, workers, progress, writer=None, cpu=None) -> None:
    import dask
    from dask.diagnostics import ProgressBar

    warm_up()

    failure = []

    def task(k):
        # Once writing has failed the run ends with that error, but only after the blocks in
        # flight are stored: raising from one task would return while other threads still write
        # theirs, leaving temporary files in the store.
        if failure:
            return
        c0 = time.thread_time()
        out = _block_task(plan, k, args)
        store.put(k, out)
        if cpu is not None:
            cpu.append(time.thread_time() - c0)
        if writer is not None:
            try:
                writer.add(k, out)
            except BaseException as exc:  # noqa: BLE001 (raised below, once every task is done)
                failure.append(exc)

    # dask's threaded scheduler runs independent tasks in descending order of their keys: the
    # keys count down so that blocks run in plan order, group after group, and each group's
    # tiles are written soon after it starts.
    n = len(todo)
    tasks = [dask.delayed(task, pure=False)(k, dask_key_name=f"block-{n - 1 - i:09d}-{k}")
             for i, k in enumerate(todo)]
    if progress:
        with ProgressBar(out=sys.stderr, dt=0.5):
            dask.compute(*tasks, scheduler="threads", num_workers=workers)
    else:
        dask.compute(*tasks, scheduler="threads", num_workers=workers)
    if failure:
        raise failure[0]


def connect(scheduler, timeout: float = CONNECT_TIMEOUT):
    """``(client, own)`` for a scheduler address (or a ``distributed.Client``, ``own`` False).

    SweepError in one line when the address is malformed or nothing answers there within
    ``timeout`` seconds.
    """
    from dask.distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    address = scheduler.strip() if isinstance(scheduler, str) else scheduler
    if not isinstance(address, str) or not _ADDRESS.match(address):
        raise SweepError(f"scheduler: {scheduler!r} is not a dask scheduler address; expected "
                         "e.g. tcp://host:8786")
    client = Client.__new__(Client)
    try:
        client.__init__(address, timeout=timeout, set_as_default=False)
        return client, True
    # Whatever the comm layer raises for an address it cannot use: TypeError for tls:// without
    # dask's TLS configuration, for ucx:// without UCX, ValueError for a malformed host.
    except Exception as exc:  # noqa: BLE001
        _discard(client)
        reason = " ".join(str(exc).split()) or type(exc).__name__
        if isinstance(exc, (OSError, TimeoutError)):
            raise SweepError(f"scheduler: no dask scheduler answers at {address!r} within "
                             f"{timeout:g} s ({reason}); start one (dask scheduler) or check "
                             "the address") from None
        raise SweepError(f"scheduler: cannot connect to {address!r} ({reason}); check the "
                         "address and its protocol (tcp:// needs no set-up)") from None


def _discard(client) -> None:
    """Stop a client whose constructor failed. Left alone, its ``__del__`` waits for a
    connection that never came (10 s at exit) and prints a traceback."""
    try:
        client.status = "closed"  # close() and __del__ then have nothing to do
        client._loop_runner.stop()
    except Exception:  # noqa: BLE001 (failed before these existed: nothing to stop)
        pass


def _solve_remote(inp: BlockInputs, args) -> dict:
    c0 = time.thread_time()
    out = solve_block(inp, *args)
    out["cpu"] = time.thread_time() - c0  # the worker thread's, returned with the block
    return out


def cluster_threads(client) -> int:
    """Threads of all the cluster's workers (at least 1): the workers of its CPU accounting."""
    workers = client.scheduler_info().get("workers", {})
    return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))


def _run_distributed(plan, todo, store, args, client, progress, writer=None, cpu=None,
                     no_workers_timeout=NO_WORKERS_TIMEOUT) -> int:
    """Run the blocks on the cluster of ``client``; returns its threads (:func:`cluster_threads`),
    and appends each block's CPU seconds on its worker to ``cpu``."""
    from dask.distributed import CancelledError, KilledWorker

    address = client.scheduler.address
    try:
        with client.as_current():  # as_completed and the progress bar find it
            _submit_and_store(plan, todo, store, args, client, progress, writer, cpu,
                              _WorkerWatch(client, no_workers_timeout))
            return cluster_threads(client)
    except KilledWorker as exc:
        raise SchedulerLost(f"a block killed every worker that ran it ({exc}); see the workers' "
                            "logs") from None
    except (CancelledError, OSError, TimeoutError) as exc:
        # A block that cannot be written (a full disk) is the store's error, not the cluster's.
        if client.status == "running" and not isinstance(exc, CancelledError):
            raise
        raise SchedulerLost(f"lost the dask scheduler at {address} "
                            f"({type(exc).__name__})") from None


class _WorkerWatch:
    """Whether a cluster has had no worker for ``timeout`` seconds (asked at most once a second).

    Tasks wait on a cluster without workers for ever, silently: the run would hang. A scheduler
    that does not answer is not this watch's concern (its futures are cancelled, see
    :func:`_run_distributed`).
    """

    def __init__(self, client, timeout: float):
        self.client, self.timeout = client, timeout
        self._asked = -math.inf
        self._since = None  # when the cluster was first seen without a worker

    def check(self) -> None:
        """Raise :class:`SchedulerLost` once the cluster has had no worker for ``timeout``."""
        now = time.monotonic()
        if now - self._asked < min(1.0, self.timeout / 4) or self.client.status != "running":
            return
        self._asked = now
        try:
            n = len(self.client.nthreads())
        except Exception:  # noqa: BLE001 (an unreachable scheduler: the futures say so)
            return
        if n:
            self._since = None
        elif self._since is None:
            self._since = now
        elif now - self._since >= self.timeout:
            raise SchedulerLost(
                f"the dask cluster at {self.client.scheduler.address} has had no worker for "
                f"{self.timeout:g} s (all lost, none started)")


def _submit_and_store(plan, todo, store, args, client, progress, writer=None, cpu=None,
                      watch: _WorkerWatch | None = None) -> None:
    from dask.distributed import as_completed

    client.run(warm_up)
    tag = plan.digest()[:12]  # keys unique per plan: a shared cluster may hold older runs
    futures = []
    for k in todo:
        # The block's own inputs, without the grid indices only this process needs.
        inp = dataclasses.replace(plan.inputs(k), flat=np.empty(0, dtype=np.int64))
        futures.append(client.submit(_solve_remote, inp, args, key=f"cc-block-{tag}-{k}"))
    key_to_block = {f.key: k for f, k in zip(futures, todo)}
    if progress:
        _progress_thread(futures)
    pending = as_completed(futures)
    while not pending.is_empty():
        ready = pending.next_batch(block=False)
        if not ready:
            if watch is not None:
                watch.check()
            time.sleep(0.05)
            continue
        for fut in ready:
            k = key_to_block[fut.key]
            out = _result(fut, watch)
            seconds = out.pop("cpu")
            if cpu is not None:
                cpu.append(seconds)
            out["triples"] = plan.blocks[k]
            store.put(k, out)
            if writer is not None:
                writer.add(k, out)
            fut.release()


def _result(fut, watch: _WorkerWatch | None):
    """``fut.result()``, watching the cluster meanwhile: a finished task whose worker is lost
    before its result is fetched runs again, and waits for a worker like any other."""
    while True:
        try:
            return fut.result(timeout=0.5)
        except TimeoutError:  # dask.distributed's is the built-in one
            if watch is not None:
                watch.check()


def _progress_thread(futures) -> None:
    """dask.distributed's own progress bar, in a thread while this one stores the blocks."""
    from dask.distributed import progress

    def show():
        try:
            progress(futures, multi=False)
        except Exception:  # noqa: BLE001 (a lost scheduler ends the bar; the run says why)
            pass

    threading.Thread(target=show, name="cc-progress", daemon=True).start()


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
