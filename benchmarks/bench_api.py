"""What the Python API costs on top of its kernels: ``solve_point`` per call, ``solve`` per array.

``solve_point`` at the README's point (eps = 1/30, L = 10, K = 0.5, A = 1/3, N = 1) with warm
kernels against the kernels it runs (``solve_eta`` and the plug-edge root) on the same point,
best of ``--repeat`` (CPU time of the thread). ``solve`` on ``--points`` distinct random points (eps in [0.02, 0.1],
L in [5, 20], K in [0.1, 2], A in [0, 1], N in [0.5, 2]) on one thread against one
``solve_batch`` call on the same points, CPU seconds of one run each.
``solve_point(..., sensitivities=True)`` at the same point, side by side with the plain call, and
with a profile of 21 points (reported); ``solve(..., sensitivities=True)`` on the first
``--sens-points`` of the random points against the plain ``solve`` on them (reported).
Targets: ``solve_point`` <= 25 us per call; ``solve`` <= 1.3x the kernel's own time; with
sensitivities <= 2.5x the plain call.

Run: ``.venv/bin/python benchmarks/bench_api.py [--points 100000] [--repeat 7] [--json PATH]``.
"""

from __future__ import annotations

import time

import numpy as np

from cosserat_channel.integrate import stepping
from cosserat_channel.measure import harness
from cosserat_channel.solver import batch, layout, plug_edge, stage1, stage2
from cosserat_channel.sweep.arrays import solve
from cosserat_channel.solver.point import Workspace, solve_point

README_POINT = (1 / 30, 10, 0.5, 1 / 3, 1)
TARGET_POINT_US = 25.0
TARGET_SOLVE_RATIO = 1.3
TARGET_SENSITIVITY_RATIO = 2.5


def point_costs(repeat: int):
    """Seconds per call of solve_point and of its kernels alone, best of ``repeat``."""
    eps, L, K, A, N = README_POINT
    ws = Workspace()

    def kernels():
        ws.run(eps * L, A, float(N), 1e-8, 1e-12, layout.METHOD_AUTO, True)
        plug_edge.one_minus_xi_p(eps * K, ws.res, ws.ax, ws.T2, ws.Q2)

    # CPU time of this thread: blind to waiting for a core on a shared machine
    api = harness.best_of(lambda: solve_point(*README_POINT), repeat, min_seconds=0.2,
                          clock=time.thread_time)
    kern = harness.best_of(kernels, repeat, min_seconds=0.2, clock=time.thread_time)
    solve_point(*README_POINT, sensitivities=True)  # compile its kernels first
    sens = harness.best_of(lambda: solve_point(*README_POINT, sensitivities=True), repeat,
                           min_seconds=0.2, clock=time.thread_time)
    return api.seconds, kern.seconds, sens.seconds


def array_costs(n: int):
    """CPU seconds of solve on ``n`` distinct points (one thread) and of solve_batch alone."""
    rng = np.random.default_rng(0)
    eps, L, K = rng.uniform(0.02, 0.1, n), rng.uniform(5, 20, n), rng.uniform(0.1, 2, n)
    A, N = rng.uniform(0, 1, n), rng.uniform(0.5, 2, n)
    solve(eps[:10], L[:10], K[:10], A[:10], N[:10], workers=1)  # load the kernels first
    res = np.empty((n, layout.N_R))
    stats = np.zeros((n, 2, stepping.N_STATS), dtype=np.int64)
    t0 = time.process_time()
    batch.solve_batch(eps * L, A, N, eps * K, np.arange(n + 1, dtype=np.int64), 1e-8, 1e-12,
                      stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, res, stats, np.empty(n),
                      np.empty(0), np.empty((n, layout.N_PROF, 0)), True, True)
    kernel = time.process_time() - t0
    t0 = time.process_time()
    ds = solve(eps, L, K, A, N, workers=1)
    api = time.process_time() - t0
    return api, kernel, int(ds.attrs["n_solves"])


def sensitivity_costs(n: int, repeat: int):
    """Seconds per call of solve_point with a 21-point profile, plain and with sensitivities,
    best of ``repeat``; CPU seconds of solve on ``n`` random points, plain and with them."""
    xi = np.linspace(0.0, 1.0, 21)
    solve_point(*README_POINT, profile=xi, sensitivities=True)  # compile first
    prof = harness.best_of(lambda: solve_point(*README_POINT, profile=xi), repeat,
                           min_seconds=0.2, clock=time.thread_time)
    prof_s = harness.best_of(lambda: solve_point(*README_POINT, profile=xi, sensitivities=True),
                             repeat, min_seconds=0.2, clock=time.thread_time)
    rng = np.random.default_rng(0)
    eps, L, K = rng.uniform(0.02, 0.1, n), rng.uniform(5, 20, n), rng.uniform(0.1, 2, n)
    A, N = rng.uniform(0, 1, n), rng.uniform(0.5, 2, n)
    solve(eps[:10], L[:10], K[:10], A[:10], N[:10], workers=1, sensitivities=True)
    t0 = time.process_time()
    solve(eps, L, K, A, N, workers=1)
    plain = time.process_time() - t0
    t0 = time.process_time()
    solve(eps, L, K, A, N, workers=1, sensitivities=True)
    with_s = time.process_time() - t0
    return prof.seconds, prof_s.seconds, plain, with_s


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--points", type=int, default=100_000, help="distinct points for solve")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--sens-points", type=int, default=2_000,
                    help="random points for solve with sensitivities")
    args = ap.parse_args()
    if args.points < 10:
        ap.error("--points must be at least 10")
    rec = harness.Record("bench_api", args.json)
    api, kern, sens = point_costs(args.repeat)
    rec.row("solve_point", us_per_call=1e6 * api, kernel_us=1e6 * kern,
            sensitivities_us=1e6 * sens)
    print(f"solve_point: {1e6 * api:.1f} us per call; its kernels alone {1e6 * kern:.1f} us; "
          f"with sensitivities {1e6 * sens:.1f} us ({sens / api:.2f}x)")
    s_api, s_kern, n_solves = array_costs(args.points)
    rec.row("solve", points=args.points, n_solves=n_solves, seconds=s_api, kernel_seconds=s_kern)
    print(f"solve on {args.points:,} points ({n_solves:,} integrations): {s_api:.3f} s CPU; "
          f"solve_batch alone {s_kern:.3f} s ({s_api / s_kern:.3f}x)")
    prof, prof_s, plain, with_s = sensitivity_costs(max(10, args.sens_points), args.repeat)
    n_s = max(10, args.sens_points)
    rec.row("sensitivities", profile_us=1e6 * prof, profile_sensitivities_us=1e6 * prof_s,
            points=n_s, solve_seconds=plain, solve_sensitivities_seconds=with_s)
    print(f"solve_point with a 21-point profile: {1e6 * prof:.1f} us; with sensitivities "
          f"{1e6 * prof_s:.1f} us ({prof_s / prof:.2f}x)")
    print(f"solve on {n_s:,} points: {1e6 * plain / n_s:.1f} us a point; with sensitivities "
          f"{1e6 * with_s / n_s:.1f} us a point ({with_s / plain:.1f}x)")
    verdicts = [
        rec.check(f"solve_point <= {TARGET_POINT_US:g} us per call", 1e6 * api <= TARGET_POINT_US,
                  f"{1e6 * api:.1f} us"),
        rec.check(f"solve <= {TARGET_SOLVE_RATIO:g}x the kernel", s_api <= TARGET_SOLVE_RATIO * s_kern,
                  f"{s_api / s_kern:.3f}x"),
        rec.check(f"sensitivities <= {TARGET_SENSITIVITY_RATIO:g}x solve_point",
                  sens <= TARGET_SENSITIVITY_RATIO * api, f"{sens / api:.2f}x"),
    ]
    for v in verdicts:
        print(v.line())
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
