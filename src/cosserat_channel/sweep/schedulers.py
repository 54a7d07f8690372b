"""Where the blocks run: a pool of threads on this machine, or a ``dask.distributed`` cluster.

Each block is one :func:`.block.solve_block` call, which holds no GIL, so a pool of threads
keeps every core busy without pickling anything. On a cluster each task carries its own block's
inputs (:meth:`.plan.Plan.inputs`), nothing scattered: a task whose worker dies is simply run
again on another. The results come back to this process, which alone writes the store and the
file; the file's tiles are derived and encoded beside the solving threads (:class:`LocalEncoder`)
or on the cluster's workers (:class:`ClusterEncoder`). Losing the scheduler, or every worker for
``no_workers_timeout`` seconds, ends the run with :class:`SchedulerLost`; the finished blocks are
in the store and the same command resumes.
"""

from __future__ import annotations

import logging
import math
import re
import threading
import time


from . import sources
from .plan import BlockInputs, PackedInputs
from .spec import SweepError
from .store import DIGEST, block_digest

log = logging.getLogger("cosserat_channel.sweep")


# Seconds to wait for a scheduler to answer before the run is refused (nothing created yet).
CONNECT_TIMEOUT = 5.0
# Seconds a cluster may have no worker at all before the run ends (SchedulerLost): long enough
# for a nanny or a batch system to bring lost workers back, short enough not to look hung.
NO_WORKERS_TIMEOUT = 120.0
_ADDRESS = re.compile(r"^(?:[a-z][a-z0-9+.-]*://)?\S+$")
# Seconds between looks at a future's state while it runs, and the first and the longest wait
# for the result of a finished one (longer: its worker may be lost, and the cluster is looked at).
POLL = 0.02
FETCH_FIRST = 5.0
FETCH_TIMEOUT = 60.0


class SchedulerLost(RuntimeError):
    """The dask cluster can no longer run the blocks: its scheduler went away mid-run, or it has
    had no worker for ``no_workers_timeout`` seconds. The finished blocks are kept in the store."""


class ForeignWorker(SchedulerLost):
    """A worker that joined the cluster mid-run runs other package sources than this process
    (:mod:`.sources`): its block is not stored and the run ends; the finished blocks are kept."""


class BlockCount:
    """The blocks stored so far as ``progress(done, total, "blocks solved")`` (the package's
    progress protocol), once at the start and after each block from whichever thread stores it;
    nothing without a callback (``progress`` None)."""

    def __init__(self, progress, done: int, total: int):
        self.progress, self.done, self.total = progress, done, total
        self._lock = threading.Lock()
        self._report()

    def __call__(self) -> None:
        with self._lock:
            self.done += 1
            self._report()

    def _report(self) -> None:
        if self.progress is not None:
            self.progress(self.done, self.total, "blocks solved")


def _run_threads(plan, todo, store, args, workers, progress: BlockCount, writer=None,
                 cpu=None) -> None:
    from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait

    from .block import _block_task

    # The kernels are loaded: the engine warms them up before its clock starts (engine._run).
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
        progress()
        if cpu is not None:
            cpu.append(time.thread_time() - c0)
        if writer is not None:
            try:
                writer.add(k, out)
            except BaseException as exc:  # noqa: BLE001 (raised below, once every task is done)
                failure.append(exc)

    # The blocks are independent: a pool of threads is all the scheduling they need (dask's
    # threaded scheduler did the same, after a quarter of a second importing dask before the
    # first block). Its queue is first in, first out: blocks run in plan order, group after
    # group, and each group's tiles are written soon after it starts. A block that raises (or a
    # Ctrl-C) ends the run with its error; blocks not yet started are dropped, and those in
    # flight finish and are stored before the error goes on, so that nothing writes into the
    # store or the file while the caller cleans up.
    pool = ThreadPoolExecutor(workers, thread_name_prefix="cc-solve")
    try:
        futures = [pool.submit(task, k) for k in todo]
        wait(futures, return_when=FIRST_EXCEPTION)
        for fut in futures:
            if fut.done() and not fut.cancelled() and fut.exception() is not None:
                raise fut.exception()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    if failure:
        raise failure[0]


def connect(scheduler, timeout: float = CONNECT_TIMEOUT):
    """``(client, own)`` for a scheduler address (or a ``distributed.Client``, ``own`` False).

    SweepError in one line when the address is malformed, nothing answers there within
    ``timeout`` seconds, or a worker runs other package sources than this process
    (:func:`.sources.foreign_workers`).
    """
    from dask.distributed import Client

    if isinstance(scheduler, Client):
        _check_sources(scheduler)
        return scheduler, False
    address = scheduler.strip() if isinstance(scheduler, str) else scheduler
    if not isinstance(address, str) or not _ADDRESS.match(address):
        raise SweepError(f"scheduler: {scheduler!r} is not a dask scheduler address; expected "
                         "e.g. tcp://host:8786")
    client = Client.__new__(Client)
    try:
        client.__init__(address, timeout=timeout, set_as_default=False)
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
    try:
        _check_sources(client)
    except BaseException:
        client.close()
        raise
    return client, True


def _check_sources(client) -> None:
    """SweepError (one line) if a worker of the cluster runs other sources than this process."""
    foreign = sources.foreign_workers(client)
    if foreign:
        raise SweepError(f"scheduler: {sources.refusal(foreign)}")


def _discard(client) -> None:
    """Stop a client whose constructor failed. Left alone, its ``__del__`` waits for a
    connection that never came (10 s at exit) and prints a traceback."""
    try:
        client.status = "closed"  # close() and __del__ then have nothing to do
        client._loop_runner.stop()
    except Exception:  # noqa: BLE001 (failed before these existed: nothing to stop)
        pass


def _solve_remote(inp: BlockInputs | PackedInputs, args, client_sources=None, k=None,
                  triples=None, identity=None) -> dict:
    """Block ``k`` solved on a worker: its arrays, the worker's address and sources, the thread's
    CPU seconds and, given the store's ``identity``, the block's digest (:func:`.store.block_digest`
    of the arrays the store keeps, ``triples`` included), computed here rather than in the process
    that writes."""
    from dask.distributed import get_worker

    from .block import solve_block

    out = {"worker": get_worker().address}
    # A worker of other sources says so at once, without solving (its kernels may not even be
    # compiled); the client checks the digest of every block (sources.foreign_block).
    if client_sources is None or client_sources == sources.digest():
        c0 = time.thread_time()
        block = solve_block(inp.unpack(), *args)
        out["cpu"] = time.thread_time() - c0  # the worker thread's, returned with the block
        if identity is not None:
            block["triples"] = triples
            out[DIGEST] = block_digest(identity, k, block)
        out.update(block)
    return sources.stamp(out)


def cluster_threads(client) -> int:
    """Threads of all the cluster's workers (at least 1): the workers of its CPU accounting."""
    workers = client.scheduler_info().get("workers", {})
    return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))


def _run_distributed(plan, todo, store, args, client, progress: BlockCount, writer=None, cpu=None,
                     no_workers_timeout=NO_WORKERS_TIMEOUT) -> int:
    """Run the blocks on the cluster of ``client``; returns its threads (:func:`cluster_threads`),
    and appends each block's CPU seconds on its worker to ``cpu``."""
    from dask.distributed import CancelledError, KilledWorker

    address = client.scheduler.address
    try:
        with client.as_current():  # as_completed finds it
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


def _submit_and_store(plan, todo, store, args, client, progress: BlockCount, writer=None, cpu=None,
                      watch: _WorkerWatch | None = None) -> None:
    from dask.distributed import as_completed

    # By reference: the workers import it (and the solver); this process never loads numba.
    from .block import warm_up

    tag = plan.digest()[:12]  # keys unique per plan: a shared cluster may hold older runs
    # Each worker loads (or compiles, a minute of CPU on a new source tree) the kernels in a task
    # of its own before its first block: in its thread pool, not in its event loop as
    # client.run would, where a long compile stops the worker's heartbeats until the scheduler
    # restarts it. Not waited for; a worker that joins later loads them with its first block.
    warm = [client.submit(warm_up, key=f"cc-warm-up-{tag}-{i}", workers=[address],
                          allow_other_workers=False, priority=20, pure=False)
            for i, address in enumerate(client.scheduler_info().get("workers", {}))]
    identity = store.identity()
    futures = []
    for k in todo:
        # The block's own inputs, packed (its eps K entries are made on the worker), and what
        # its digest binds it to: the worker digests the block, this process only writes it.
        futures.append(client.submit(_solve_remote, plan.packed_inputs(k), args, sources.digest(),
                                     k, plan.blocks[k] if identity else None, identity,
                                     key=f"cc-block-{tag}-{k}"))
    key_to_block = {f.key: k for f, k in zip(futures, todo)}
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
            foreign = sources.foreign_block(out, out.get("worker", "?"))
            if foreign is not None:
                raise ForeignWorker(f"{foreign}; its block was not used")
            del out["sources"], out["worker"]
            seconds = out.pop("cpu")
            if cpu is not None:
                cpu.append(seconds)
            out["triples"] = plan.blocks[k]
            store.put(k, out)  # with the digest the worker computed
            progress()
            if writer is not None:
                writer.add(k, out)
            fut.release()
    for fut in warm:
        fut.release()


def _result(fut, watch: _WorkerWatch | None):
    """``fut.result()``, watching the cluster meanwhile: a finished task whose worker is lost
    before its result is fetched runs again, and waits for a worker like any other.

    The result is asked for only once the task has finished (or failed): waiting is a look at the
    future's state, which this process keeps, not a call through the client's event loop. Such
    calls with a timeout, made twice a second for every future waited on, cost the client CPU
    and, timing out on a loaded machine, can end in an error of the library's own (a cancelled
    wait it does not catch); a cancelled future is the scheduler's loss (CancelledError).
    """
    from dask.distributed import CancelledError

    patience = FETCH_FIRST
    while True:
        status = fut.status
        if status == "cancelled":
            raise CancelledError(fut.key)
        if status not in ("finished", "error"):
            if watch is not None:
                watch.check()
            time.sleep(POLL)
            continue
        try:
            return fut.result(timeout=patience)
        except TimeoutError:  # dask.distributed's is the built-in one
            # A slow transfer or a lost worker: the cluster is looked at (a lost worker's task
            # runs again, a cluster without workers ends the run), and the fetch begins again
            # with twice the patience, so a large result on a slow link still comes home.
            patience = min(2 * patience, FETCH_TIMEOUT)
            if watch is not None:
                watch.check()
            continue
        except (OSError, KeyboardInterrupt):
            raise
        except Exception:
            # A task that fails on a worker of other sources (an older _solve_remote, a module
            # it lacks) is that worker's doing: say so rather than show its traceback.
            foreign = sources.foreign_workers(fut.client)
            if foreign:
                raise ForeignWorker(f"{sources.refusal(foreign)}; a block failed on it") from None
            raise


class LocalEncoder:
    """Tiles derived and encoded (:func:`.encode.encode_tile`) in a pool of ``workers`` threads
    beside the solving ones: numpy's loops, the checksum and deflate leave the GIL, and the solving
    kernels never take it, so the cores share both."""

    def __init__(self, workers: int):
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(max(1, int(workers)), thread_name_prefix="cc-encode")
        # A tile waiting per thread: each in flight holds one tile's derived values at most.
        self.slots = max(1, int(workers)) + 1

    def submit(self, function, job):
        return self._pool.submit(function, job)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class ClusterEncoder:
    """Tiles derived and encoded on the cluster's workers: each task carries its tile's inputs
    (nothing scattered), so one whose worker is lost runs again on another, and it is placed in
    the file when its encoded chunks come back."""

    def __init__(self, client, no_workers_timeout: float = NO_WORKERS_TIMEOUT):
        import warnings

        self.client = client
        self.watch = _WorkerWatch(client, no_workers_timeout)
        self.slots = 2 * cluster_threads(client)
        # A tile's task carries its inputs (megabytes, on purpose: nothing scattered, so a lost
        # worker's task runs again elsewhere); dask's advice against large graphs is not for it.
        warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)

    def submit(self, function, job):
        # Before the blocks still queued: a tile in flight holds memory here and there.
        return _Watched(self.client.submit(function, job, pure=False, priority=10), self.watch,
                        self.client)

    def close(self) -> None:
        pass


class _Watched:
    """A cluster future whose ``result`` watches the cluster (:class:`_WorkerWatch`)."""

    def __init__(self, fut, watch, client):
        self.fut, self.watch, self.client = fut, watch, client

    def result(self):
        from dask.distributed import CancelledError

        try:
            out = _result(self.fut, self.watch)
        except CancelledError:
            raise SchedulerLost(f"lost the dask scheduler at {self.client.scheduler.address} "
                                "(CancelledError)") from None
        self.fut.release()
        return out

    def cancel(self) -> None:
        try:
            self.fut.cancel()
        except Exception:  # noqa: BLE001 (a lost scheduler has nothing to cancel)
            pass
