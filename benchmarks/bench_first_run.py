"""Seconds to a user's first ``point``: a fresh process on an empty Numba cache, then from the cache.

Each round makes an empty temporary ``NUMBA_CACHE_DIR``, runs ``cosserat-channel point ...`` in a
new Python process (the first run compiles every kernel the point needs), then the same command
again in another new process (the kernels load from that cache). It prints the CPU model, the load
average before each run, and each run's wall-clock and CPU time (user + system of the command and
of the process it compiles part of the kernels in, ``solver.ahead``): on a loaded machine the wall
time grows with the load, the CPU time much less, and on two idle cores the cold run's wall time
is below its CPU time. ``--profile`` adds, per
compiled function, the compile time spent in it outside the functions it compiled in turn (Numba's
compile events) and how many specialisations were compiled, in the command's own process (what
the other process compiled, it loads).

Run:  .venv/bin/python benchmarks/bench_first_run.py [--rounds 1] [--profile] [--json PATH]
      [-- POINT OPTIONS]

The default is the README's first point (``--eps 1/30 --L 10 --K 0.5 --A 1/3 --N 1 --d-p 0.002
--rho-p 2940 --phi 25 --plot FIG.png``, the figure written into the temporary directory). Target: the
cold run within 30 s wall on an idle machine (judged only where the load is below 1; the
fastest round counts).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cosserat_channel.measure import harness

# The README's first point (its figure goes into the round's temporary directory).
POINT = ["--eps", "1/30", "--L", "10", "--K", "0.5", "--A", "1/3", "--N", "1", "--d-p", "0.002",
         "--rho-p", "2940", "--phi", "25"]
TARGET_S = 30.0
# The target holds on an idle machine: judged only where the 1-minute load is below this.
IDLE_LOAD = 1.0

# Run in the child with --profile: the CLI under Numba's compile-event listener, which writes
# {function: [self seconds, compiles]} as JSON to the file named by argv[1].
_PROFILED = """
import json, sys, time
from collections import defaultdict
from numba.core import event

stack, spent, count = [], defaultdict(float), defaultdict(int)

class Listener(event.Listener):
    def on_start(self, e):
        f = e.data["dispatcher"].py_func
        stack.append([f.__module__ + "." + f.__qualname__, time.perf_counter(), 0.0])

    def on_end(self, e):
        name, t, inner = stack.pop()
        dt = time.perf_counter() - t
        spent[name] += dt - inner
        count[name] += 1
        if stack:
            stack[-1][2] += dt

event.register("numba:compile", Listener())
from cosserat_channel.cli import main
rc = main(sys.argv[2:])
with open(sys.argv[1], "w") as fh:
    json.dump({k: [spent[k], count[k]] for k in spent}, fh)
sys.exit(rc)
"""


def _run(args, cache, profile_to=None):
    """One fresh process: (wall s, CPU s, exit code)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    if profile_to is None:
        cmd = [sys.executable, "-m", "cosserat_channel.cli", "point", *args]
    else:
        cmd = [sys.executable, "-c", _PROFILED, profile_to, "point", *args]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        sys.stderr.write(done.stderr)
    return wall, cpu, done.returncode


def _load() -> float:
    return os.getloadavg()[0]


def main(argv=None) -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--rounds", type=int, default=1, help="cold + warm pairs (default 1)")
    ap.add_argument("--profile", action="store_true",
                    help="compile time per function in the first round's cold run")
    ap.add_argument("--top", type=int, default=15, help="functions listed with --profile")
    ap.add_argument("point", nargs="*", help="the point's options (after --)")
    opts = ap.parse_args(argv)
    args = opts.point or POINT
    plot = not opts.point
    rec = harness.Record("bench_first_run", opts.json)
    print(f"command timed: cosserat-channel point {' '.join(args)}"
          + (" --plot FIG.png" if plot else ""))
    print(f"{'round':>5} {'run':>5} {'load (1 min)':>12} {'wall s':>8} {'CPU s':>7}")
    profile = None
    cold = []
    for i in range(opts.rounds):
        with tempfile.TemporaryDirectory(prefix="numba-first-run-") as cache:
            out = Path(cache) / "profile.json" if opts.profile and i == 0 else None
            for run in ("cold", "warm"):
                load = _load()
                figure = ["--plot", str(Path(cache) / f"{run}.png")] if plot else []
                wall, cpu, rc = _run(args + figure, cache,
                                     str(out) if out and run == "cold" else None)
                if rc != 0:
                    print(f"the {run} run failed (exit {rc})", file=sys.stderr)
                    return 1
                print(f"{i + 1:>5} {run:>5} {load:>12.2f} {wall:8.1f} {cpu:7.1f}", flush=True)
                rec.row("runs", round=i + 1, run=run, load=load, wall_s=wall, cpu_s=cpu)
                if run == "cold":
                    cold.append((wall, cpu, load))
            if out is not None:
                profile = json.loads(out.read_text())
    print(f"load after: {_load():.2f}")
    wall, cpu, load = min(cold)
    text = f"first point on an empty cache <= {TARGET_S:g} s wall on an idle machine"
    if load < IDLE_LOAD:
        v = rec.check(text, wall <= TARGET_S, f"{wall:.1f} s wall, {cpu:.1f} s CPU")
    else:
        v = rec.check(text, None, f"machine loaded (load {load:.1f}): {wall:.1f} s wall, "
                      f"{cpu:.1f} s CPU")
    print("target: " + v.line())
    if profile:
        total = sum(s for s, _ in profile.values())
        n = sum(c for _, c in profile.values())
        print(f"\ncompile time by function (round 1, cold): {total:.1f} s in {n} compilations")
        for name, (s, c) in sorted(profile.items(), key=lambda kv: -kv[1][0])[:opts.top]:
            print(f"{s:7.2f} s  x{c:<3} {name}")
        rec.add("compile_s_by_function", {k: v[0] for k, v in profile.items()})
    return rec.finish()


if __name__ == "__main__":
    sys.exit(main())
