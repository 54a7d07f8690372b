"""Where the wall ends the slow manifold: the stiff path's turn, with and without its re-march.

Calibrates: ``cosserat_channel.solver.stage1.TURN_KAPPA``, ``TURN_SPAN`` and ``TURN_COND``.

For small eta and N close to 1 the stage-1 path follows ``delta = N - sqrt(N^2 - xi^2)`` up to
the wall and turns off it within a layer next to the wall, where ``N - delta`` falls to
``|delta(1) - N| = delta(1) / kappa``. The outputs read ``N - delta`` there. For each point and
rtol this probe solves stage 1 as ``solve_eta`` does but stops before the turn's re-march (the
plain march, ``_stage1_pass``), then marches the turn again with the given settings, and runs
stage 2 and the plug edge on both. It prints the worst relative error of ``mu_wall``, ``J(0)``
and ``1 - xi_p`` over rtol against the package at rtol 1e-13, before and after, with the steps
of both stages.

Run:  PYTHONPATH=src .venv/bin/python benchmarks/probes/probe_turn.py [TURN_SPAN TURN_COND]
"""

from __future__ import annotations

import sys

import numpy as np

from cosserat_channel.integrate import stepping
from cosserat_channel.physics import model
from cosserat_channel.solver import layout, plug_edge, stage1, stage2
from cosserat_channel.solver.point import Workspace

ATOL = 1e-12
POINTS = [(A, N, eta) for A, N in ((1 / 3, 1.0), (1 / 3, 1.003), (1.0, 1.0), (1 / 3, 0.999),
                                   (-0.5, 1.0))
          for eta in (1e-8, 1e-7, 1e-6, 6e-6, 3e-5, 1e-4, 1e-3)]
RTOLS = (1e-5, 1e-6, 1e-7, 1e-8)


def solve(ws, eta, A, N, rtol, eps_K, turn):
    """``(mu_wall, J(0), 1 - xi_p, stage-1 steps, stage-2 panels)``, or None without a solution.

    ``turn=None``: the package's stage 1 (the reference, at rtol 1e-13). Else stage 1's plain
    march (``_stage1_pass``, as ``solve_stage1_with`` runs it before any re-march) and, with
    ``turn = (span, cond)``, the turn marched again as ``_turn_remarch`` does; then stage 2 and
    the plug edge."""
    stats1 = np.zeros(stepping.N_STATS, dtype=np.int64)
    stats2 = stats1.copy()
    res = ws.res
    res[:] = np.nan
    buf = np.empty(1)
    if model.classify(eta, A, N) != 0:
        return None
    if turn is None:
        if stage1.solve_stage1_with(None, None, eta, A, N, rtol, ATOL, ws.ax, ws.T1, ws.Q1, stats1,
                                    res, layout.METHOD_AUTO)[0] != 0:
            return None
        n1 = int(res[layout.R_N1])
    else:
        model.axis_constants(eta, A, N, ws.ax)
        rtol1 = stage1.stage1_rtol(rtol, A, N, ws.ax)
        xi1, w1 = stage1.stage1_start(ws.ax, rtol1)
        stiff = stage1.use_stiff_path(eta, A, N, ws.ax, xi1, rtol1)
        atol1 = np.array([ATOL * min(1.0, rtol1 / rtol)])
        args1 = (eta, A, N, ws.ax)
        s, n1, _ = stage1._stage1_pass(None, None, stiff, xi1, w1, args1, rtol1, atol1, ws.T1,
                                       ws.Q1, stats1, 0.0)
        if s != stepping.SUCCESS:
            return None
        res[layout.R_XI1] = xi1
        res[layout.R_RTOL1] = rtol1
        delta_wall = stage1._delta_wall(ws.T1, ws.Q1, n1, buf)
        mu = abs(delta_wall - N)
        kappa = abs(delta_wall) / mu
        if turn != "plain" and stiff and kappa > stage1.TURN_KAPPA:
            span, cond = turn
            k0 = n1 - 1
            while k0 > 0 and abs(N - ws.T1[k0] ** 2 * ws.Q1[k0, 0, 0]) < span * mu:
                k0 -= 1
            rtol_leg = rtol1 * cond / kappa
            atol_leg = np.array([ATOL * min(1.0, rtol_leg / rtol)])
            s, nb, _ = stage1._march_rodas(ws.T1[k0], np.array([ws.Q1[k0, 0, 0]]), 1.0, 0.0, 0.0,
                                           args1, rtol_leg, atol_leg, ws.T1[k0:], ws.Q1[k0:],
                                           stats1)
            n1 = k0 + nb
        res[layout.R_N1] = n1
        res[layout.R_MU_WALL] = stage1._delta_wall(ws.T1, ws.Q1, n1, buf) - N
    mu_wall = res[layout.R_MU_WALL]
    stage2._march_stage2(eta, A, N, rtol, ATOL, ws.ax, res[layout.R_XI1], ws.T1, ws.Q1, n1, ws.T2,
                         ws.Q2, stats2, res)
    om = plug_edge.one_minus_xi_p(eps_K, res, ws.ax, ws.T2, ws.Q2)
    return (mu_wall, res[layout.R_J_AXIS], om, int(stats1[stepping.STAT_ACCEPTED]),
            int(stats2[stepping.STAT_ACCEPTED]))


def main():
    turn = (float(sys.argv[1]), float(sys.argv[2])) if len(sys.argv) > 2 else (
        stage1.TURN_SPAN, stage1.TURN_COND)
    ws, wr = Workspace(), Workspace()
    L, K = 10.0, 0.5
    print(f"turn re-march: span {turn[0]:g}, cond {turn[1]:g}, kappa > {stage1.TURN_KAPPA:g}")
    print("| A | N | eta | rtol | error/rtol plain | error/rtol re-marched | stage-1 steps | "
          "stage-2 panels |")
    print("|---|---|---|---|---|---|---|---|")
    worst = [0.0, 0.0]
    for A, N, eta in POINTS:
        eps = eta / L
        ref = solve(wr, eta, A, N, 1e-13, eps * K, None)
        if ref is None:
            continue
        for rtol in RTOLS:
            out = [solve(ws, eta, A, N, rtol, eps * K, t) for t in ("plain", turn)]
            err = [max(abs(o[i] / ref[i] - 1) for i in range(3)) / rtol for o in out]
            worst = [max(w, e) for w, e in zip(worst, err)]
            print(f"| {A:.4g} | {N:g} | {eta:g} | {rtol:g} | {err[0]:.1f} | {err[1]:.1f} | "
                  f"{out[0][3]} -> {out[1][3]} | {out[0][4]} -> {out[1][4]} |")
    print(f"worst error/rtol: plain {worst[0]:.1f}, re-marched {worst[1]:.1f}")


if __name__ == "__main__":
    main()
