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
import os
import re
import sys
import threading
import time

import numpy as np

from .. import __version__
from ..integrate import rk45
from .. import netcdf_policy
from .. import outputs as out_
from ..solver import batch, layout, stage1, stage2
from .. import status as st
from ..files import space_problem
from .dataset import build_dataset
from .plan import BlockInputs, Plan
from .spec import SweepError, SweepSpec, load_sweep
from .store import FORMAT, BlockDamaged, WorkStore, check_writable, partial_dir
from .writer import BUCKET, StreamWriter, Tiles

# Seconds to wait for a scheduler to answer before the run is refused (nothing created yet).
CONNECT_TIMEOUT = 5.0
_ADDRESS = re.compile(r"^(?:[a-z][a-z0-9+.-]*://)?\S+$")


class SchedulerLost(RuntimeError):
    """The dask scheduler went away mid-run; the finished blocks are kept in the store."""

log = logging.getLogger("cosserat_channel.sweep")


def run_sweep(path_or_mapping, output=None, *, workers=None, scheduler=None, reduce=True,
              block_size=None, progress=None, compress=None):
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

    Returns
    -------
    xarray.Dataset
        Dims ``(eps, L, K, A, N)`` (plus ``xi`` with profiles), the requested variables, ``status``.

    Raises
    ------
    SweepError
        (a ``ValueError``) for an invalid sweep, an unwritable output, or a working store of a
        different sweep in the way; nothing has been computed then.
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
    xi = _profile_xi(spec)
    try:
        plan = Plan(spec.coords(), reduce=reduce, block_size=block_size, workers=n_workers,
                    tile=_tile(spec, xi, output))
    except ValueError as exc:
        raise SweepError(str(exc)) from None
    if output is not None:
        problem = space_problem(output, disk_needed(spec, plan, xi, output))
        if problem:
            raise SweepError(problem)
    # The cluster is reached before any store exists: a wrong address leaves nothing behind.
    client, own_client = (None, False) if scheduler is None else connect(scheduler)
    try:
        store = WorkStore.open(output, _manifest(spec, plan),
                               given_block_size=block_size is not None)
        try:
            ds, times = _run(spec, plan, store, xi, output, client, n_workers, reduce,
                             progress, compress)
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


def _tile(spec, xi, output):
    """The tile shape of the result file (None without a file: nothing to align to)."""
    return None if output is None else Tiles(spec.shape, 0 if xi is None else xi.size).tile


def _run(spec, plan, store, xi, output, client, n_workers, reduce, progress, compress):
    """Solve what the store lacks, writing the file as groups complete, then finish it; returns
    (Dataset or None, (solve s, blocks computed, assemble and write s))."""
    if store.manifest["block_size"] != plan.block_size:
        plan = Plan(spec.coords(), reduce=reduce, block_size=store.manifest["block_size"],
                    tile=_tile(spec, xi, output))
    if store.manifest["plan_sha256"] != plan.digest():
        raise SweepError(
            f"{store.directory} was planned differently (another cosserat-channel build?); "
            f"delete {store.directory} to start over, or choose another -o"
        )
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
                                             cpu)
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


def disk_needed(spec: SweepSpec, plan: Plan, xi, output: str) -> int:
    """Bytes the run will still put on disk at its peak: the result file uncompressed (an upper
    bound), the working store's blocks and the tile buckets (:mod:`.writer`), less what an
    earlier run of the same output already left in the store."""
    n_xi = 0 if xi is None else xi.size
    plug_edge = out_.needs_plug_edge(spec.variables)
    per_point = 1 + sum(8 if v in out_.OUTPUTS else 4 for v in spec.variables)  # + status
    result = plan.size * (per_point + 4 * 8 * n_xi)
    store = plan.n_triples * (8 * layout.N_R + 16 + 8 + 8 * layout.N_PROF * n_xi)
    if plug_edge:
        store += plan.size * (8 + BUCKET.itemsize)
    have = 0
    for root, _, files in os.walk(partial_dir(output)):
        have += sum(os.path.getsize(os.path.join(root, f)) for f in files)
    return max(0, result + store - have)


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
    stats = np.zeros((n, 2, rk45.N_STATS), dtype=np.int64)
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
        "steps": stats[:, :, rk45.STAT_ACCEPTED].copy(),
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
    try:
        return Client(address, timeout=timeout, set_as_default=False), True
    except (OSError, TimeoutError, ValueError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise SweepError(f"scheduler: no dask scheduler answers at {address!r} within "
                         f"{timeout:g} s ({reason}); start one (dask scheduler) or check the "
                         "address") from None


def _solve_remote(inp: BlockInputs, args) -> dict:
    c0 = time.thread_time()
    out = solve_block(inp, *args)
    out["cpu"] = time.thread_time() - c0  # the worker thread's, returned with the block
    return out


def cluster_threads(client) -> int:
    """Threads of all the cluster's workers (at least 1): the workers of its CPU accounting."""
    workers = client.scheduler_info().get("workers", {})
    return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))


def _run_distributed(plan, todo, store, args, client, progress, writer=None, cpu=None) -> int:
    """Run the blocks on the cluster of ``client``; returns its threads (:func:`cluster_threads`),
    and appends each block's CPU seconds on its worker to ``cpu``."""
    from dask.distributed import CancelledError, KilledWorker

    address = client.scheduler.address
    try:
        with client.as_current():  # as_completed and the progress bar find it
            _submit_and_store(plan, todo, store, args, client, progress, writer, cpu)
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


def _submit_and_store(plan, todo, store, args, client, progress, writer=None, cpu=None) -> None:
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
    for fut in as_completed(futures):
        k = key_to_block[fut.key]
        out = fut.result()
        seconds = out.pop("cpu")
        if cpu is not None:
            cpu.append(seconds)
        out["triples"] = plan.blocks[k]
        store.put(k, out)
        if writer is not None:
            writer.add(k, out)
        fut.release()


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
