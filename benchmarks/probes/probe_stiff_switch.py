"""Where does the stiff path pay on stage 1? RODAS4P2 against the explicit path, on the same points.

Calibrates: ``cosserat_channel.solver.stage1.STIFF_LAMBDA``, ``STIFF_LAMBDA_DOP853`` and
``STIFF_N_MARGIN``, the thresholds of ``stage1.use_stiff_path``.

Each point is solved at each rtol with stage 1
forced onto either path (``METHOD_EXPLICIT``: DOP853 at rtol <= ``stage1.DOP853_RTOL``,
Dormand-Prince above; ``METHOD_STIFF``: RODAS4P2), as the solver runs it (the march from the axis
series, the split at xi = N, the event and conditioning re-marches): both stages
(``batch.solve_eta``) and stage 1 alone (``stage1.solve_stage1``, what ``stage1_batch`` and
stage-1-only sweeps run). The path matters for both: stage 2 integrates on stage 1's dense output,
and takes more panels on RODAS4P2's (3rd order) than on DOP853's (7th order).

Points: the grid of ``bench_point.py`` (eta = eps L in [1/300, 4], A = 1/3, N = 1), ``--points``
random points (eta log-uniform in [1e-4, 20], A in [-0.99, 5], N in [0.3, 3], seed 1), and lines
in eta in [1e-4, 1] at A = 1/3, 2 and N = 0.9, 1, 1.1, 1.3 (the crossover depends on N near 1);
only those where stage 1 integrates. Per point, rtol and path it records the CPU time of the
thread per solve (``time.thread_time``, best of 3 runs of enough solves to last ``MIN_SECONDS``,
so it holds on a shared machine), stage 1's evaluations and steps (RODAS4P2's Jacobians not
counted), the status, ``m(1)/(nu L)`` and ``J(0)``; the references are the explicit path at rtol
1e-13, atol 1e-16 (``m(1)`` checked against scipy's DOP853 at rtol 1e-12 on 40 points).

It prints, per rtol: the crossover in the stiffness measure ``x = (1 - xi1) max(2/eta,
beta/xi1)`` of ``use_stiff_path`` for classes of N; the cost of both paths at a few points; the
total time of the rule in the code and of the earlier rule (``STIFF_LAMBDA sqrt(1e-6/rtol)``)
against the better path for every point; and each path's errors.

Run (about 5 minutes on one core):
    PYTHONPATH=src .venv/bin/python benchmarks/probes/probe_stiff_switch.py [--points 1000] [--save F.npz]
    PYTHONPATH=src .venv/bin/python benchmarks/probes/probe_stiff_switch.py --load F.npz
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numba import njit

from cosserat_channel.integrate import dense, panels, stepping
from cosserat_channel.measure import harness
from cosserat_channel.physics import model
from cosserat_channel.solver import batch, layout, stage1, stage2
from cosserat_channel import status as st

RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
ATOL = 1e-12
REF_RTOL, REF_ATOL = 1e-13, 1e-16
MIN_SECONDS = 2e-3
METHODS = (layout.METHOD_EXPLICIT, layout.METHOD_STIFF)
SETS = ("grid", "random", "lines")


@njit
def _repeat(eta, A, N, rtol, atol, method, both, reps, ax, T1, Q1, T2, Q2, stats1, stats2, res):
    """``reps`` solves of one point (the timed loop, no Python between them): stage 1 alone
    (``stage1.solve_stage1``, what ``stage1_batch`` runs) or both stages (``batch.solve_eta``)."""
    code = 0
    for _ in range(reps):
        if both:
            code = batch.solve_eta(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                                    method)
        else:
            code = stage1.solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method)[0]
    return code


class Solver:
    """Work arrays for one forced solve at a time."""

    def __init__(self):
        self.ax = np.empty(model.N_AX)
        self.T1 = np.empty(stage1.MAX_STEPS_STAGE1 + 1)
        self.Q1 = np.empty((stage1.MAX_STEPS_STAGE1, dense.N_DENSE, 1))
        self.T2 = np.empty(stage2.MAX_STEPS_STAGE2 + 1)
        self.Q2 = np.empty((stage2.MAX_STEPS_STAGE2, panels.N_ROWS, 2))
        self.stats1 = np.zeros(stepping.N_STATS, np.int64)
        self.stats2 = np.zeros(stepping.N_STATS, np.int64)
        self.res = np.empty(layout.N_R)

    def run(self, point, rtol, atol, method, both, reps=1):
        return _repeat(*point, rtol, atol, method, both, reps, self.ax, self.T1, self.Q1, self.T2,
                       self.Q2, self.stats1, self.stats2, self.res)

    def seconds(self, point, rtol, method, both):
        """CPU seconds of the thread per solve: best of 3 runs of enough solves, looped inside
        the kernel (no Python between them)."""
        t0 = time.thread_time()
        self.run(point, rtol, ATOL, method, both)
        reps = max(1, int(MIN_SECONDS / max(time.thread_time() - t0, 1e-6)))
        t = harness.best_of(lambda: self.run(point, rtol, ATOL, method, both, reps), 3,
                            clock=time.thread_time)
        return t.seconds / reps


def points(n, seed=1):
    """``eta, A, N`` and each point's set (``SETS``): bench_point's grid, ``n`` random points,
    and lines in eta at N around 1, where the slow manifold ``w ~ sqrt(N^2 - xi^2)`` ends near the
    wall (the grid has N = 1; random points rarely come close)."""
    eps = np.logspace(np.log10(1 / 600), np.log10(0.2), 50)
    L = np.linspace(2, 20, 20)
    eta_g = (eps[:, None] * L[None, :]).ravel()
    rng = np.random.default_rng(seed)
    eta_r = 10.0 ** rng.uniform(-4, np.log10(20.0), n)
    A_r = rng.uniform(-0.99, 5.0, n)
    N_r = rng.uniform(0.3, 3.0, n)
    eta_l = np.logspace(-4, 0, 25)
    line_AN = [(A, N) for A in (1 / 3, 2.0) for N in (0.9, 1.0, 1.1, 1.3)]
    eta = np.concatenate([eta_g, eta_r] + [eta_l] * len(line_AN))
    A = np.concatenate([np.full(eta_g.size, 1 / 3), A_r] + [np.full(eta_l.size, a) for a, _ in line_AN])
    N = np.concatenate([np.ones(eta_g.size), N_r] + [np.full(eta_l.size, m) for _, m in line_AN])
    which = np.repeat([0, 1, 2], [eta_g.size, n, eta_l.size * len(line_AN)])
    return eta, A, N, which


def measure(eta, A, N):
    """Per point, rtol and path (last axis: explicit, RODAS4P2): CPU seconds of stage 1 alone
    (``sec1``) and of both stages (``sec``), stage 1's evaluations and steps, the status,
    ``m(1)/(nu L)`` and ``J(0)`` (``mu``, ``J``); per point and rtol the rule's inputs and choice;
    per point the references (``ref_mu``, ``ref_J``)."""
    solver = Solver()
    n, r = eta.size, len(RTOLS)
    out = {k: np.full((n, r, 2), np.nan)
           for k in ("sec1", "sec", "fev", "steps", "status", "mu", "J", "xi_stop")}
    for k in ("x", "rtol1", "xi1", "auto"):
        out[k] = np.full((n, r), np.nan)
    for k in ("beta", "ref_mu", "ref_J"):
        out[k] = np.full(n, np.nan)
    res = solver.res
    for i in range(n):
        point = (eta[i], A[i], N[i])
        code = solver.run(point, REF_RTOL, REF_ATOL, layout.METHOD_EXPLICIT, True)
        if res[layout.R_PATH] == layout.PATH_NONE:
            continue
        if code == st.OK:
            out["ref_mu"][i], out["ref_J"][i] = res[layout.R_MU_WALL], res[layout.R_J_AXIS]
        out["beta"][i] = solver.ax[model.AX_BETA]
        for j, rtol in enumerate(RTOLS):
            solver.run(point, rtol, ATOL, layout.METHOD_AUTO, False)
            out["auto"][i, j] = res[layout.R_PATH]
            rtol1 = stage1.stage1_rtol(rtol, A[i], N[i], solver.ax)
            xi1 = stage1.stage1_start(solver.ax, rtol1)[0]
            out["xi1"][i, j], out["rtol1"][i, j] = xi1, rtol1
            out["x"][i, j] = (1 - xi1) * max(2 / eta[i], out["beta"][i] / xi1)
            for k, method in enumerate(METHODS):
                code = solver.run(point, rtol, ATOL, method, True)
                out["status"][i, j, k] = code
                out["fev"][i, j, k] = solver.stats1[stepping.STAT_FEV]
                out["steps"][i, j, k] = (solver.stats1[stepping.STAT_ACCEPTED]
                                         + solver.stats1[stepping.STAT_REJECTED])
                out["mu"][i, j, k] = res[layout.R_MU_WALL]
                out["J"][i, j, k] = res[layout.R_J_AXIS]
                out["xi_stop"][i, j, k] = res[layout.R_XI_STOP]
                out["sec"][i, j, k] = solver.seconds(point, rtol, method, True)
                out["sec1"][i, j, k] = solver.seconds(point, rtol, method, False)
    return out


def check_reference(eta, A, N, ref, picks=40):
    """Largest relative difference of the reference m(1)/(nu L) from scipy's DOP853 at 1e-12."""
    from cosserat_channel.measure import runners

    ok = np.flatnonzero(np.isfinite(ref))
    sub = ok[np.linspace(0, ok.size - 1, min(picks, ok.size)).round().astype(int)]
    worst = 0.0
    for i in sub:
        m = runners.scipy_stage1(eta[i], 1.0, A[i], N[i], "DOP853", 1e-12, 1e-16, 2_000_000)
        if np.isfinite(m):
            worst = max(worst, abs(m - ref[i]) / N[i])
    return worst, sub.size


N_CLASSES = ((0.0, 0.9), (0.9, 1.0), (1.0, 1.05), (1.05, 1.1), (1.1, 1.2), (1.2, 1.5), (1.5, 2.0),
             (2.0, 3.0))
REPRESENTATIVE = ((1e-3, 0.9), (1e-3, 1.0), (1e-2, 1.0), (1e-3, 1.1), (1e-3, 1.3))  # (eta, N), A = 1/3


def _crossover(x, e, r):
    """The threshold on ``x`` that minimises the total time (explicit below, RODAS4P2 above) and
    the range of thresholds within 2 % of that total."""
    cands = np.concatenate([[0.0], np.sort(x), [np.inf]])
    totals = np.array([np.where(x > c, r, e).sum() for c in cands])
    good = cands[totals <= 1.02 * totals.min()]
    return cands[np.argmin(totals)], good.min(), good.max()


def report(d, which):
    """Crossovers, a few points, what the rule in the code costs, and the accuracy of each path."""
    sec, sec1, status, x = d["sec"], d["sec1"], d["status"], d["x"]
    both = np.isfinite(sec).all(axis=2) & np.isfinite(sec1).all(axis=2)
    # Near the axis edge (beta > 4N/eta) the N dependence does not apply (see use_stiff_path).
    manifold = d["beta"] * d["eta"] <= 4 * d["N"]
    print("\nCrossover in x = (1 - xi1) max(2/eta, beta/xi1), both stages: the threshold that "
          "minimises the total time of the class (range within 2 %), points")
    print("| rtol | " + " | ".join(f"N in ({lo:g}, {hi:g}]" for lo, hi in N_CLASSES) + " |")
    print("|---" * (len(N_CLASSES) + 1) + "|")
    for j, rtol in enumerate(RTOLS):
        cells = []
        for lo, hi in N_CLASSES:
            sel = both[:, j] & manifold & (d["N"] > lo) & (d["N"] <= hi)
            _, a, b = _crossover(x[sel, j], sec[sel, j, 0], sec[sel, j, 1])
            cells.append(f"{a:.0f}-{b:.0f} ({sel.sum()})")
        print(f"| {rtol:g} | " + " | ".join(cells) + " |")

    print("\nPer solve, explicit / RODAS4P2 (A = 1/3): microseconds for both stages, for stage 1 "
          "alone, stage 1's evaluations; * = the rule's pick")
    print("| rtol | " + " | ".join(f"eta {e:g}, N {n:g}" for e, n in REPRESENTATIVE) + " |")
    print("|---" * (len(REPRESENTATIVE) + 1) + "|")
    rows = [np.flatnonzero((which == 2) & np.isclose(d["eta"], e) & (d["A"] == 1 / 3)
                           & (d["N"] == n))[0] for e, n in REPRESENTATIVE]
    for j, rtol in enumerate(RTOLS):
        cells = []
        for i in rows:
            star = ("", "*") if d["auto"][i, j] == layout.PATH_STIFF else ("*", "")
            cells.append(" / ".join(f"{sec[i, j, k] * 1e6:.0f}, {sec1[i, j, k] * 1e6:.0f}, "
                                    f"{d['fev'][i, j, k]:.0f}{star[k]}" for k in range(2)))
        print(f"| {rtol:g} | " + " | ".join(cells) + " |")

    old = x > stage1.STIFF_LAMBDA * np.sqrt(1e-6 / d["rtol1"])
    rules = (("the rule in the code", d["auto"] == layout.PATH_STIFF),
             ("STIFF_LAMBDA sqrt(1e-6/rtol) at every rtol", old))
    for name, stiff in rules:
        print(f"\nTotal time of {name} / the better path's per point, both stages (stage 1 alone); "
              "worst single point")
        print("| rtol | " + " | ".join(SETS) + " |")
        print("|---" * (len(SETS) + 1) + "|")
        for j, rtol in enumerate(RTOLS):
            cells = []
            for k in range(len(SETS)):
                sel = both[:, j] & (which == k)
                tot = []
                for t in (sec, sec1):
                    picked = np.where(stiff[sel, j], t[sel, j, 1], t[sel, j, 0])
                    best = t[sel, j].min(axis=1)
                    tot.append((picked.sum() / best.sum(), np.max(picked / best)))
                cells.append(f"{tot[0][0]:.3f} ({tot[1][0]:.3f}); {tot[0][1]:.1f}x")
            print(f"| {rtol:g} | " + " | ".join(cells) + " |")

    err_m = np.abs(d["mu"] - d["ref_mu"][:, None, None]) / d["N"][:, None, None]
    err_J = np.abs(d["J"] / d["ref_J"][:, None, None] - 1.0)
    print("\nErrors / rtol against the reference, each path forced (points solved on both): "
          "m(1)/(nu N L) and J(0), median and 99th percentile")
    print("| rtol | points | m_wall explicit | m_wall RODAS4P2 | J(0) explicit | J(0) RODAS4P2 |")
    print("|---|---|---|---|---|---|")
    for j, rtol in enumerate(RTOLS):
        sel = np.isfinite(err_m[:, j]).all(axis=1) & np.isfinite(err_J[:, j]).all(axis=1)
        cells = [f"{np.median(e[sel, j, k]) / rtol:.3f}, {np.percentile(e[sel, j, k], 99) / rtol:.2f}"
                 for e in (err_m, err_J) for k in range(2)]
        print(f"| {rtol:g} | {sel.sum()} | " + " | ".join(cells) + " |")
    differ = both & (status[:, :, 0] != status[:, :, 1])
    print(f"\n{differ.sum()} (point, rtol) pairs where the two paths give different statuses")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1000)
    ap.add_argument("--save", help="write the raw measurements to this .npz")
    ap.add_argument("--load", help="report on measurements saved with --save")
    args = ap.parse_args()
    print("\n".join(harness.header_lines(harness.header())))
    print(f"stage1.STIFF_LAMBDA = {stage1.STIFF_LAMBDA:g}, STIFF_LAMBDA_DOP853 = "
          f"{stage1.STIFF_LAMBDA_DOP853:g}, STIFF_N_MARGIN = {stage1.STIFF_N_MARGIN:g}")
    if args.load:
        d = dict(np.load(args.load))
        report(d, d["which"])
        return 0
    eta, A, N, which = points(args.points)
    d = measure(eta, A, N)
    d.update(eta=eta, A=A, N=N, which=which)
    if args.save:
        np.savez(args.save, **d)
    worst, k = check_reference(eta, A, N, d["ref_mu"])
    print(f"# reference: explicit path at rtol {REF_RTOL:g}; max |difference| / N from scipy "
          f"DOP853 at 1e-12 on {k} points: {worst:.1e}")
    report(d, which)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
