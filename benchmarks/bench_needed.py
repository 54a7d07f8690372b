"""Compute only what the question needs: stage-1-only sweeps and edge tracing, timed side by side.

Measures, in one run on this machine:

1. the same unreduced sweep (one core) asked for every output and for ``m_wall`` alone (stage-1
   output: no velocity stage away from the path edge, no plug-edge root);
2. ``regimes.trace_edge`` deciding feasibility by the full two-stage solve (as before) and by
   ``Workspace.status`` (stage 2 only next to the edge), with the two eta_max compared;
3. with ``--baseline REF``, the same edges traced by the package as it was at git commit REF
   (default 5fd2cfb, the last commit before the status path: feasibility by both stages, the
   kernels of that day), in a subprocess of this run on a ``git archive`` of REF: the time
   before, measured side by side rather than quoted.

Run: ``.venv/bin/python benchmarks/bench_needed.py [--quick] [--baseline [REF]] [--json PATH]``.
Targets: sweep ratio <= 0.55, trace_edge ratio <= 0.5 with identical eta_max to 1e-10 (relative).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from cosserat_channel import regimes, run_sweep
from cosserat_channel.measure import harness
from cosserat_channel.solver.point import Workspace

EDGE_CASES = ((1 / 3, 1.0), (0.0, 2.0), (-0.5, 1.0), (3.0, 0.5), (1.0, 1.0), (2.0, 3.0))


class FullSolveWorkspace(Workspace):
    """Feasibility by both stages everywhere: what edge tracing did before the status path."""

    def status(self, eta, A, N, rtol, atol):
        return self.run(eta, A, N, rtol, atol)


def sweep_mapping(n_eps, n_L, variables=None):
    m = {"grid": {"eps": {"logspace": [-3, -0.5, n_eps]}, "L": {"linspace": [2, 20, n_L]},
                  "K": [0.1, 0.5, 1.0, 5.0, 50.0], "A": [1 / 3, 1.0], "N": 1.0}}
    if variables:
        m["output"] = {"variables": variables}
    return m


def time_sweep(mapping, repeat):
    """Seconds of the unreduced sweep on one core (best of ``repeat``) and its Dataset."""
    t = harness.best_of(lambda: run_sweep(mapping, reduce=False, workers=1, progress=False), repeat)
    return t.seconds, t.result


BASELINE_SCRIPT = """
import json, sys, time
from cosserat_channel import regimes
cases = json.loads(sys.argv[1])
regimes.trace_edge(1 / 3, 1.0)  # compile / load outside the timing
out = []
for A, N in cases:
    t0 = time.perf_counter()
    e = regimes.trace_edge(A, N)
    out.append([time.perf_counter() - t0, e.eta_max])
print(json.dumps(out))
"""


def trace_baseline(ref: str, cases) -> list | None:
    """``[(seconds, eta_max), ...]`` of ``trace_edge`` on ``cases`` with the package at git ``ref``."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory(prefix="cc-baseline-") as tmp:
        archive = subprocess.run(["git", "-C", root, "archive", ref, "src"], capture_output=True)
        if archive.returncode != 0:
            print(f"baseline: cannot read commit {ref!r}: {archive.stderr.decode().strip()}")
            return None
        subprocess.run(["tar", "-x", "-C", tmp], input=archive.stdout, check=True)
        env = dict(os.environ, PYTHONPATH=os.path.join(tmp, "src"))
        run = subprocess.run([sys.executable, "-c", BASELINE_SCRIPT, json.dumps(cases)], env=env,
                             capture_output=True, text=True)
        if run.returncode != 0:
            print(f"baseline at {ref} failed: {run.stderr.strip().splitlines()[-1:]}")
            return None
        return json.loads(run.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--quick", action="store_true", help="a small grid (CI smoke run)")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--baseline", nargs="?", const="5fd2cfb", default=None, metavar="REF",
                    help="also trace the edges with the package at git commit REF (default "
                         "5fd2cfb, the last commit before the status path)")
    args = ap.parse_args()
    rec = harness.Record("bench_needed", args.json)
    n = 20 if args.quick else 100
    print(f"one core; unreduced sweep of {n} x {n} x 5 x 2 points")
    time_sweep(sweep_mapping(3, 2), 1)  # compile / load the kernels outside the timing

    t_all, ds_all = time_sweep(sweep_mapping(n, n), args.repeat)
    t_m, ds_m = time_sweep(sweep_mapping(n, n, ["m_wall"]), args.repeat)
    same_status = bool((ds_all.status.values == ds_m.status.values).all())
    same_m = bool(np.array_equal(ds_all.m_wall.values, ds_m.m_wall.values, equal_nan=True))
    ratio = t_m / t_all
    rec.add("sweep", {"points": n * n * 10, "every_output_s": t_all, "m_wall_only_s": t_m,
                      "ratio": ratio, "statuses_identical": same_status,
                      "m_wall_identical": same_m})
    v = rec.check("sweep of m_wall alone / every output <= 0.55", ratio <= 0.55, f"{ratio:.2f}")
    print(f"sweep, every output : {t_all:8.2f} s")
    print(f"sweep, m_wall only  : {t_m:8.2f} s   ratio {ratio:.2f}  (target <= 0.55: "
          f"{v.word})  statuses identical: {same_status}, m_wall identical: {same_m}")

    ws_full, ws_new = FullSolveWorkspace(max_steps_stage1=regimes.EDGE_MAX_STEPS), \
        Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    regimes.trace_edge(1 / 3, 1.0, workspace=ws_new)  # warm up
    t_old = t_new = 0.0
    worst = 0.0
    etas = []
    for A, N in EDGE_CASES:
        t0 = time.perf_counter()
        old = regimes.trace_edge(A, N, workspace=ws_full)
        t1 = time.perf_counter()
        new = regimes.trace_edge(A, N, workspace=ws_new)
        t2 = time.perf_counter()
        t_old += t1 - t0
        t_new += t2 - t1
        etas.append(new.eta_max)
        if np.isfinite(old.eta_max) or np.isfinite(new.eta_max):
            worst = max(worst, abs(new.eta_max - old.eta_max) / abs(old.eta_max))
        rec.row("edges", A=A, N=N, eta_max_full=old.eta_max, eta_max_status=new.eta_max,
                full_s=t1 - t0, status_s=t2 - t1)
        print(f"  A = {A:6.3f}, N = {N:4.2f}: eta_max {old.eta_max:.12g} (full) "
              f"{new.eta_max:.12g} (status path); {t1 - t0:6.2f} s -> {t2 - t1:6.2f} s")
    r = t_new / t_old
    v1 = rec.check("trace_edge by status / by the full solve <= 0.5", r <= 0.5, f"{r:.2f}")
    v2 = rec.check("eta_max of the two the same to 1e-10 (relative)", worst <= 1e-10,
                   f"{worst:.1e}")
    print(f"trace_edge, {len(EDGE_CASES)} edges: {t_old:.2f} s -> {t_new:.2f} s, ratio {r:.2f} "
          f"(target <= 0.5: {v1.word}); max relative eta_max difference "
          f"{worst:.1e} (target <= 1e-10: {v2.word})")
    if args.baseline:
        base = trace_baseline(args.baseline, [list(c) for c in EDGE_CASES])
        if base is not None:
            t_base = sum(b[0] for b in base)
            worst_b = max((abs(new_e - b[1]) / abs(b[1]) for b, new_e in zip(base, etas)
                           if np.isfinite(b[1])), default=0.0)
            rb = t_new / t_base
            for (A, N), b, new_e in zip(EDGE_CASES, base, etas):
                rec.row("baseline", A=A, N=N, eta_max_then=b[1], eta_max_now=new_e, then_s=b[0])
                print(f"  A = {A:6.3f}, N = {N:4.2f}: eta_max {b[1]:.12g} (at {args.baseline}) "
                      f"{new_e:.12g} (now); {b[0]:6.2f} s")
            v1 = rec.check(f"trace_edge now / at {args.baseline} <= 0.5", rb <= 0.5, f"{rb:.2f}")
            v2 = rec.check(f"eta_max now and at {args.baseline} the same to 1e-10 (relative)",
                           worst_b <= 1e-10, f"{worst_b:.1e}")
            print(f"trace_edge at {args.baseline}, same edges: {t_base:.2f} s; this commit "
                  f"{t_new:.2f} s, ratio {rb:.2f} (target <= 0.5: {v1.word}); max relative "
                  f"eta_max difference {worst_b:.1e} (target <= 1e-10: {v2.word})")
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
