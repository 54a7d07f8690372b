"""A first run's kernels compiled in two processes: a child compiles and caches part of them
while this process compiles the rest, then loads the child's from Numba's cache.

On an empty kernel cache a first point spends nearly all its time compiling, on one core. Its
kernels split into parts that do not call each other: stage 1 (typed first, by the entry kernel)
and stage 2's march, the plug-edge root and the profile kernel (:data:`JOBS`). :func:`start`
hands the parts that are not cached yet to a child process (``python -c``, this package's
sources, the same ``NUMBA_CACHE_DIR``), which compiles them in the order the caller meets them
and reports each on its standard output. In this process the dispatchers of those parts wait,
at their first compilation, until the child has reported them (or is gone), and then load them
from the cache instead of compiling them; the last one to be compiled by the child is needed
last. Nothing changes where the child fails or is slow: a kernel it did not cache is compiled
here, as without it.

Nothing is started where the kernels are cached already (one read of each part's cache index),
where Numba's cache is off or JIT compilation is disabled, on fewer than two usable cores, on a
platform without ``fork``-style pipes (Windows), or inside the child itself. The child never
outlives this process: it ends when its standard input closes (this process ended, however) or
at this process's exit, on Ctrl-C with it, and it never prints (its standard error goes to
``/dev/null``). Two processes writing the same function's cache entries at once are serialised
by :mod:`cosserat_channel._jit` (a lock per cache directory).
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import threading
import time

from .._jit import PACKAGE

# Set in the child's environment: the child compiles what it was given and starts no child.
CHILD_ENV = "COSSERAT_CHANNEL_COMPILE_CHILD"
# The longest this process waits for the child to report a part before compiling it itself.
WAIT_S = 600.0


def _signatures(name: str) -> list:
    """``[(dispatcher, argument types)]`` of part ``name``: the types its caller passes (the
    point's work arrays are C-contiguous float64 arrays, the counters int64)."""
    from numba import types

    f8, i8 = types.float64, types.int64
    a1, a2, a3, c1 = f8[::1], f8[:, ::1], f8[:, :, ::1], i8[::1]
    if name == "stage2":
        from .stage2 import _march_stage2

        # eta, A, N, rtol, atol, ax, xi1, T1, Q1, n1, T2, Q2, stats2, res
        return [(_march_stage2, (f8, f8, f8, f8, f8, a1, f8, a1, a3, i8, a1, a3, c1, a1))]
    if name == "plug_edge":
        from .plug_edge import one_minus_xi_p

        return [(one_minus_xi_p, (f8, a1, a1, a1, a3))]  # eps_K, res, ax, T2, Q2
    if name == "profile":
        from .batch import profile_kernel

        # xis, eta, A, N, ax, res, T1, Q1, T2, Q2, out
        return [(profile_kernel, (a1, f8, f8, f8, a1, a1, a1, a3, a1, a3, a2))]
    raise KeyError(name)


# The parts a child may compile, in the order a point's solve meets them.
JOBS = ("stage2", "plug_edge", "profile")


def _cached(dispatcher, sig) -> bool:
    """Whether Numba's cache holds ``dispatcher`` for ``sig`` (its index, read without loading)."""
    cache = dispatcher._cache
    key = cache._index_key(sig, dispatcher.targetctx.codegen())
    return key in cache._cache_file._load_index()


def _usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def _eligible() -> bool:
    from numba.core import config

    from .._jit import JIT

    return (JIT["cache"] and not config.DISABLE_JIT and os.name == "posix"
            and bool(sys.executable) and CHILD_ENV not in os.environ and _usable_cores() >= 2)


class _Child:
    """The child process compiling ``names``, and what it has reported so far."""

    def __init__(self, names, code: str = f"from {__name__} import child; child()"):
        env = dict(os.environ, **{CHILD_ENV: "1"})
        # The child imports these very sources, wherever this process found them.
        env["PYTHONPATH"] = os.pathsep.join(
            [str(PACKAGE.parent)] + [p for p in [env.get("PYTHONPATH")] if p])
        self.names = list(names)
        self.done: set[str] = set()
        self.lock = threading.Lock()
        # Unbuffered: a buffered reader would take several reports at once into its buffer,
        # where select() cannot see them, and wait for the child's next report or its exit.
        self.proc = subprocess.Popen(
            [sys.executable, "-P", "-c", code, *self.names], bufsize=0,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            env=env, close_fds=True)
        self.ended = False
        atexit.register(self.close)

    def wait(self, name: str) -> bool:
        """Until the child reports ``name`` or ends: whether it compiled (and cached) it."""
        import select

        deadline = time.monotonic() + WAIT_S
        with self.lock:
            while name not in self.done and not self.ended:
                left = deadline - time.monotonic()
                if left <= 0 or not select.select([self.proc.stdout], [], [], left)[0]:
                    self.close()
                    break
                line = self.proc.stdout.readline()
                if not line:
                    self.ended = True
                    break
                self.done.add(line.decode().strip())
            return name in self.done

    def close(self) -> None:
        """End the child (if it still runs) and reap it."""
        self.ended = True
        proc = self.proc
        if proc.poll() is None:
            proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        for pipe in (proc.stdin, proc.stdout):
            try:
                pipe.close()
            except OSError:
                pass


_state = {"started": False, "child": None}
_start_lock = threading.Lock()


def start(names=JOBS) -> None:
    """Hand the parts ``names`` (of :data:`JOBS`) that the cache lacks to a child process.

    Called before the first solve; only the first call of a process does anything. Never
    raises: where anything is amiss the kernels are compiled here, as without a child.
    """
    with _start_lock:
        if _state["started"]:
            return
        _state["started"] = True
        try:
            if not _eligible():
                return
            parts = {name: _signatures(name) for name in names}
            cold = [name for name in names
                    if not all(_cached(d, sig) for d, sig in parts[name])]
            if not cold:
                return
            child = _state["child"] = _Child(cold)
        except Exception:
            return
        for name in cold:
            for dispatcher, _ in parts[name]:
                _wait_at_first_compile(dispatcher, name, child)


def _wait_at_first_compile(dispatcher, name: str, child: _Child) -> None:
    """Make ``dispatcher``'s first compilation wait for the child's report of part ``name``; it
    then finds the child's entry in the cache (or compiles, where there is none)."""

    def compile(sig):
        dispatcher.__dict__.pop("compile", None)
        child.wait(name)
        return dispatcher.compile(sig)

    dispatcher.compile = compile


def child() -> None:
    """The child's main: compile the parts named in ``sys.argv``, reporting each on stdout."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends it at once, without a word

    def orphaned():
        sys.stdin.buffer.read()  # returns when the parent's end of the pipe closes
        os._exit(0)

    threading.Thread(target=orphaned, daemon=True).start()
    code = 1
    try:
        for name in sys.argv[1:]:
            for dispatcher, sig in _signatures(name):
                dispatcher.compile(sig)
            sys.stdout.write(name + "\n")
            sys.stdout.flush()
        code = 0
    finally:
        # Not through the interpreter's shutdown: it would wait for stdin's lock, which the
        # watching thread holds, and abort.
        os._exit(code)
