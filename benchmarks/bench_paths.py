"""Stage-1 path choice: the explicit pair vs RODAS4P2 against eta = eps L, side by side in one run.

For A = 1/3, N = 1, rtol = 1e-8 (the explicit pair is then DOP853): accepted stage-1 steps,
microseconds for both stages (best of 5 x 20 runs) and the relative error of Delta against scipy
Radau at rtol 1e-12, along one line in eta. ``stage1.use_stiff_path``'s rule was calibrated on
many more points and several N and rtol with ``benchmarks/probes/probe_stiff_switch.py``; this is
the quick look at one line.

Run:  .venv/bin/python benchmarks/bench_paths.py [--json PATH]
"""

from cosserat_channel.measure import harness
from cosserat_channel.physics.reference import reference
from cosserat_channel.solver import layout, plug_edge
from cosserat_channel.solver.point import Workspace

ETAS = (3.0, 1.0, 0.3, 0.1, 0.03, 0.01, 1e-3, 1e-4)
NAMES = {layout.METHOD_EXPLICIT: "explicit", layout.METHOD_STIFF: "RODAS4P2"}


def timed(ws, eta, method, reps=20):
    """Microseconds per solve of both stages: best of 5 timings of ``reps`` solves."""
    return 1e6 * harness.best_of(lambda: ws.run(eta, 1 / 3, 1.0, 1e-8, 1e-12, method), 5,
                                 inner=reps, warm_up=True).seconds


def main():
    args = harness.parser(__doc__).parse_args()
    rec = harness.Record("bench_paths", args.json)
    ws = Workspace()
    print("| eta | explicit steps | explicit us | explicit err(Delta) | RODAS4P2 steps | RODAS4P2 us "
          "| RODAS4P2 err(Delta) | auto picks |")
    print("|---|---|---|---|---|---|---|---|")
    for eta in ETAS:
        eps, L = eta / 10, 10.0
        ref = reference(eps, L, 0.5, 1 / 3, 1.0, method="Radau")
        cells = [f"{eta:g}"]
        row = {"eta": eta}
        for method in (layout.METHOD_EXPLICIT, layout.METHOD_STIFF):
            us = timed(ws, eta, method, reps=2 if (method == layout.METHOD_EXPLICIT and eta < 1e-3) else 20)
            om = plug_edge.one_minus_xi_p(eps * 0.5, ws.res, ws.ax, ws.T2, ws.Q2)
            err = abs(om / eps / ref["Delta"] - 1)
            cells += [str(ws.stats1[0]), f"{us:.0f}", f"{err:.1e}"]
            name = NAMES[method]
            row.update({f"{name}_steps": int(ws.stats1[0]), f"{name}_us": us, f"{name}_err_Delta": err})
        ws.run(eta, 1 / 3, 1.0, 1e-8, 1e-12, layout.METHOD_AUTO)
        row["auto"] = "RODAS4P2" if ws.res[layout.R_PATH] else "explicit"
        cells.append(row["auto"])
        rec.row("line", **row)
        print("| " + " | ".join(cells) + " |")
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
