"""The solvability atlas against its targets (issue 14): accuracy, classification, cost, speed.

On one box of ``(A, N)`` (default A in [-0.5, 0.5], N in [1, 1.5]: one edge eta_max, steep
towards A = -1):

1. builds the atlas (``--tol``, default 1e-8) and counts its traces and status solves;
2. compares its ``eta_max`` with direct bisection (``regimes.trace_edge``) at ``--points``
   random ``(A, N)``;
3. the uniform-grid baseline: traces an ``n x n`` equispaced grid (``--uniform``, default 33),
   interpolates it bicubically (``scipy.interpolate.RectBivariateSpline``) on the nested 9, 17
   and 33 grids, measures the error at the same random points, and extrapolates with the measured
   order to the ``n`` that reaches the atlas's maximum error;
4. python-adaptive's ``Learner2D`` (when importable) on the same function, ``log eta_max(A, N)``,
   measured the same way at a third, two thirds and all of ``--learner`` points;
5. ``classify`` against direct solves (``Workspace.status`` at ``regimes.EDGE_RTOL``, one at a
   time) on ``--classify`` random points (eps L log-uniform in [1e-3, 100]) plus a tenth as many
   placed 1e-9 to 1e-2 (relative) from the edge;
6. times ``cosserat-channel plot --regime --atlas`` on a 41 x 26 sweep of the box (a fresh
   process, start-up included).

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/bench_atlas.py --atlas-out atlas.nc``.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def log(msg):
    print(msg, flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--A", default="-0.5:0.5")
    ap.add_argument("--N", default="1:1.5")
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--max-depth", type=int, default=3)
    ap.add_argument("--points", type=int, default=200)
    ap.add_argument("--uniform", type=int, default=33, help="finest uniform grid (2^k + 1)")
    ap.add_argument("--learner", type=int, default=300)
    ap.add_argument("--classify", type=int, default=100_000)
    ap.add_argument("--atlas-out", help="also keep the atlas in this file")
    ap.add_argument("--seed", type=int, default=14)
    args = ap.parse_args()

    from scipy.interpolate import RectBivariateSpline

    from cosserat_channel import atlas as at
    from cosserat_channel import model, regimes
    from cosserat_channel import status as st
    from cosserat_channel.measure import machine
    from cosserat_channel.solve import Workspace

    A_rng = tuple(float(v) for v in args.A.split(":"))
    N_rng = tuple(float(v) for v in args.N.split(":"))
    rng = np.random.default_rng(args.seed)
    trace_range = (1e-3 / at.TRACE_WIDEN, 100.0 * at.TRACE_WIDEN)
    log(f"machine: {machine.machine()}; {machine.git_revision()}")
    log(f"box A {A_rng}, N {N_rng}, tol {args.tol:g}, degree {at.DEGREE}, max depth {args.max_depth}")

    # 1. the atlas ---------------------------------------------------------------------------
    regimes.trace_edge(0.0, 1.0)  # load the compiled kernels before timing
    t0 = time.perf_counter()
    atlas = at.build_atlas(A_rng, N_rng, tol=args.tol, max_depth=args.max_depth)
    t_build = time.perf_counter() - t0
    n_tr, n_sol = atlas.attrs["n_traces"], atlas.attrs["n_solves"]
    per_trace = n_sol / n_tr
    log(f"atlas: {t_build:.1f} s, {atlas.leaf_n.size} cells (levels {np.bincount(atlas.leaf_level)}), "
        f"{int((atlas.leaf_n < 0).sum())} unresolved, {n_tr} traces, {n_sol} solves "
        f"({per_trace:.1f} per trace), largest cell estimate {np.max(atlas.leaf_error):.2e}")
    if args.atlas_out:
        at.save_atlas(atlas, args.atlas_out)

    # 2. eta_max against direct bisection ----------------------------------------------------
    A = rng.uniform(*A_rng, args.points)
    N = rng.uniform(*N_rng, args.points)
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    t0 = time.perf_counter()
    direct = [regimes.trace_edge(a, n, eta_range=trace_range, workspace=ws) for a, n in zip(A, N)]
    t_direct = time.perf_counter() - t0
    _, low, eta, err = atlas.transitions(A, N)
    ref = np.array([e.eta_max if e.kind == 0 else np.nan for e in direct])
    n_ref = np.array([e.transitions.size for e in direct])
    ours = np.array([row[np.isfinite(row)][-1] if np.isfinite(row).any() else np.nan for row in eta])
    same = n_ref == np.sum(np.isfinite(eta), axis=1)
    rel = np.abs(np.log(ours / ref))
    ok = same & np.isfinite(rel)
    within = rel[ok] <= np.fmax(args.tol, err[ok])
    atlas_err = float(np.max(rel[ok]))
    log(f"eta_max at {args.points} random (A, N): {ok.sum()} compared ({(~same).sum()} with "
        f"another number of transitions), max relative error {atlas_err:.2e} (tol {args.tol:g}), "
        f"{within.sum()} within max(tol, cell estimate), {np.sum(rel[ok] <= args.tol)} within tol; "
        f"direct bisection {t_direct / args.points * 1e3:.0f} ms per (A, N)")

    def errors_of(interp):
        got = np.array([interp(a, n) for a, n in zip(A[ok], N[ok])])
        return float(np.max(np.abs(got - np.log(ref[ok]))))

    # 3. uniform grids, bicubic ----------------------------------------------------------------
    n = args.uniform
    ga, gn = np.linspace(*A_rng, n), np.linspace(*N_rng, n)
    t0 = time.perf_counter()
    grid = np.array([[regimes.trace_edge(a, b, eta_range=trace_range, workspace=ws).eta_max
                      for b in gn] for a in ga])
    t_grid = time.perf_counter() - t0
    uni = []
    m = n
    while m >= 5:
        step = (n - 1) // (m - 1)
        spline = RectBivariateSpline(ga[::step], gn[::step], np.log(grid[::step, ::step]), kx=3,
                                     ky=3)
        uni.append((m, errors_of(lambda a, b, s=spline: float(s(a, b)[0, 0]))))
        m = (m - 1) // 2 + 1
    uni.sort()
    (m1, e1), (m2, e2) = uni[-2], uni[-1]
    order = math.log(e1 / e2) / math.log((m2 - 1) / (m1 - 1))
    need = (m2 - 1) * (e2 / atlas_err) ** (1.0 / order) + 1
    log("uniform bicubic grid: " + ", ".join(f"{m}x{m}: {e:.2e}" for m, e in uni)
        + f" (tracing {n}x{n}: {t_grid:.0f} s); measured order {order:.2f}; for the atlas's "
        f"{atlas_err:.2e}: about {need:.0f}x{need:.0f} = {need * need:.3g} traces, "
        f"{need * need * per_trace:.3g} solves; atlas/uniform = {n_tr / need**2:.4f}")
    d = int(np.max(atlas.leaf_level))
    cheb = (atlas.roots[0] * 2**d * atlas.degree + 1) * (atlas.roots[1] * 2**d * atlas.degree + 1)
    log(f"uniform Chebyshev cells at the atlas's finest level {d}: {cheb} traces "
        f"(atlas/uniform = {n_tr / cheb:.3f})")

    # 4. python-adaptive Learner2D ---------------------------------------------------------------
    try:
        import adaptive
    except ImportError:
        log("python-adaptive: not importable, skipped")
    else:
        def f(xy):
            return math.log(regimes.trace_edge(xy[0], xy[1], eta_range=trace_range,
                                               workspace=ws).eta_max)

        learner = adaptive.Learner2D(f, bounds=[A_rng, N_rng])
        res = []
        t0 = time.perf_counter()
        for target in (args.learner // 3, 2 * args.learner // 3, args.learner):
            adaptive.runner.simple(learner, npoints_goal=target)
            ip = learner.interpolator(scaled=False)
            res.append((learner.npoints, errors_of(lambda a, b, ip=ip: float(np.ravel(ip(a, b))[0]))))
        t_learn = time.perf_counter() - t0
        (p1, q1), (p2, q2) = res[-2], res[-1]
        order_l = math.log(q1 / q2) / math.log(p2 / p1)
        need_l = p2 * (q2 / atlas_err) ** (1.0 / order_l)
        log(f"Learner2D (adaptive {adaptive.__version__}): " + ", ".join(
            f"{p} points: {q:.2e}" for p, q in res) + f" ({t_learn:.0f} s); measured order "
            f"{order_l:.2f} in points; for {atlas_err:.2e}: about {need_l:.3g} points")

    # 5. classify against direct solves -----------------------------------------------------------
    k = args.classify
    kn = k // 10
    cA = np.r_[rng.uniform(*A_rng, k), rng.uniform(*A_rng, kn)]
    cN = np.r_[rng.uniform(*N_rng, k), rng.uniform(*N_rng, kn)]
    ceta = 10 ** rng.uniform(-3, 2, k)
    _, _, t, _ = atlas.transitions(cA[k:], cN[k:])
    last = np.array([row[np.isfinite(row)][-1] if np.isfinite(row).any() else 1.0 for row in t])
    delta = rng.choice([-1, 1], kn) * 10 ** rng.uniform(-9, -2, kn)
    ceta = np.r_[ceta, np.clip(last * (1 + delta), 1e-3, 100)]
    L = 100.0
    t0 = time.perf_counter()
    codes = at.classify(ceta / L, L, 0.5, cA, cN, atlas=atlas)
    t_cls = time.perf_counter() - t0
    t0 = time.perf_counter()
    truth = np.empty(ceta.size, dtype=np.int8)
    for i in range(ceta.size):
        c = model.classify(ceta[i], cA[i], cN[i])
        if c == st.OK and cA[i] != -1.0:
            c = ws.status(ceta[i], cA[i], cN[i], regimes.EDGE_RTOL, regimes.EDGE_ATOL)
        truth[i] = c
    t_solve = time.perf_counter() - t0
    dec = codes != at.UNDECIDED
    wrong = int(np.sum(codes[dec] != truth[dec]))
    for label, sl in (("random", slice(0, k)), ("near the edge", slice(k, None))):
        d_ = dec[sl]
        log(f"classify, {label}: {d_.size} points, {int(np.sum(codes[sl][d_] != truth[sl][d_]))} "
            f"decided wrongly, {100 * (1 - d_.mean()):.3f} % undecided")
    log(f"classify: {ceta.size} points in {t_cls:.2f} s; direct solves {t_solve:.0f} s "
        f"(Workspace.status in a loop); wrong decided points {wrong}; statuses "
        f"{dict(zip(*np.unique(truth, return_counts=True)))}")

    # 6. a regime map from the atlas -------------------------------------------------------------
    from cosserat_channel.sweep import run_sweep

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "atlas.nc")
        at.save_atlas(atlas, path)
        res = os.path.join(tmp, "map.nc")
        run_sweep({"grid": {"eps": 0.01, "L": 10, "K": 0.5, "A": {"linspace": [*A_rng, 41]},
                            "N": {"linspace": [*N_rng, 26]}}}, workers=1).to_netcdf(res)
        cmd = [sys.executable, "-m", "cosserat_channel.cli", "plot", res, "--regime", "--x", "A",
               "--y", "N", "--atlas", path, "-o", os.path.join(tmp, "map.png")]
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            best = min(best, time.perf_counter() - t0)
        log(f"plot --regime --atlas (fresh process): best of 3 {best:.2f} s")


if __name__ == "__main__":
    main()
