"""The ``stability`` and ``bench`` commands: the reports of :mod:`cosserat_channel.measure`."""

from __future__ import annotations

import argparse
import os

from ..parameters import TOLERANCES, ParameterError
from .common import (
    EXIT_FAILURE,
    EXIT_OK,
    PROG,
    CliError,
    Progress,
    error,
    interrupted,
    interruptible,
    number,
    register,
)

# ---------------------------------------------------------------------------------------------
# stability: the stability report
# ---------------------------------------------------------------------------------------------
def _stability_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output", dest="output_dir", default="stability_report",
                   metavar="DIR", help="where stability.md and stability.png go "
                   "(default: stability_report/, created if missing)")
    # The older spelling still works, unlisted: -o/--output is every other command's.
    p.add_argument("--output-dir", dest="output_dir", default=argparse.SUPPRESS,
                   help=argparse.SUPPRESS)
    p.add_argument("--quick", action="store_true",
                   help="a small version (one (A, N) series, few points, one timing repeat)")
    p.add_argument("--repeats", type=int, default=5, metavar="R",
                   help="timing repeats per point, the best is reported (default 5)")
    p.add_argument("--rtol", type=number, default=None, metavar="RTOL",
                   help="the relative tolerance every row is solved at, in "
                   f"{TOLERANCES['rtol'].interval} (default {TOLERANCES['rtol'].default:g})")


@register("stability", "report steps, cost and error of one point from eps L = 1e-8 to the "
          "edge of solvability, and which stage-1 path each point took", _stability_arguments)
def _stability(args: argparse.Namespace) -> int:
    if args.repeats < 1:
        raise CliError(f"--repeats must be a positive integer; got {args.repeats}")
    rtol = TOLERANCES["rtol"].default if args.rtol is None else args.rtol
    try:
        rtol = TOLERANCES["rtol"].check(rtol)
    except ParameterError as exc:
        raise CliError(f"--rtol: {exc}") from None
    from ..measure.stability import directory_problem, write_report

    problem = directory_problem(args.output_dir)
    if problem:
        raise CliError(f"-o/--output: {problem}")

    repeats = 1 if args.quick else args.repeats
    try:
        with interruptible(), Progress("stability", "finding the edges of the series") as bar:
            rep = write_report(args.output_dir, quick=args.quick, repeats=repeats,
                               progress=bar.report, rtol=rtol)
    except KeyboardInterrupt as exc:
        from ..measure.stability import PARTIAL_NAME, kept

        n = kept(args.output_dir, args.quick, repeats, rtol)
        return interrupted(exc, f"the {n} rows measured so far are kept in "
                           f"{os.path.join(args.output_dir, PARTIAL_NAME)}: run the same command "
                           "again to continue from them" if n else "no row was finished")
    except OSError as exc:
        raise CliError(f"cannot write the report into {args.output_dir!r}: {exc}",
                       EXIT_FAILURE) from None
    v = rep.verdict
    print(f"wrote {os.path.join(args.output_dir, 'stability.md')} and "
          f"{os.path.join(args.output_dir, 'stability.png')}; max error/rtol "
          f"{v['max_err_over_rtol']:.2f}, max steps {v['max_steps']}")
    return EXIT_OK



# ---------------------------------------------------------------------------------------------
# bench (the report lives in measure/workprecision.py)
# ---------------------------------------------------------------------------------------------
# = measure.workprecision.DEFAULT_OUTPUT, not imported: --help stays light.
_BENCH_OUTPUT = "bench-report"


def _bench_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true",
                   help="a tiny set (12 points, 3 rtols, scipy RK45 and LSODA on 3 points), "
                   "well under two minutes; for checks, not for numbers: its PASS/FAIL lines are "
                   "no verdict and the exit code is 0 (a full run exits 1 if a required target "
                   "is missed)")
    p.add_argument("-o", "--output", metavar="DIR",
                   help=f"report directory, created if missing (default: {_BENCH_OUTPUT}); its "
                   "reference_cache.npz is reused by later runs with the same set")
    p.add_argument("--scipy-points", type=int, metavar="N",
                   help="points in the subsample the scipy loops run on (default 60, quick 3)")


@register("bench", "work-precision report: error against run time per point, ours side by side "
          "with scipy solve_ivp and numbalsoda", _bench_arguments)
def _bench(args: argparse.Namespace) -> int:
    if args.scipy_points is not None and args.scipy_points < 2:
        raise CliError(f"--scipy-points must be an integer >= 2; got {args.scipy_points}")
    output = args.output or _BENCH_OUTPUT
    if os.path.exists(output) and not os.path.isdir(output):
        raise CliError(f"-o: {output!r} exists and is not a directory")
    command = " ".join(
        [PROG, "bench"] + (["--quick"] if args.quick else []) + ["-o", output]
        + ([f"--scipy-points {args.scipy_points}"] if args.scipy_points is not None else [])
    )
    from ..measure import workprecision

    try:
        with interruptible(), Progress("bench", "starting") as bar:
            def progress(done, total, text):
                bar.line(f"{PROG}: bench: {text}")
                bar.report(done, total, f"stages done; last: {text}")

            rep = workprecision.run(output, quick=args.quick, scipy_points=args.scipy_points,
                                    command=command, progress=progress)
    except KeyboardInterrupt as exc:
        return interrupted(exc, workprecision.kept(output, quick=args.quick))
    except OSError as exc:
        raise CliError(f"cannot write the report into {output!r}: {exc}", EXIT_FAILURE) from None
    missed = [t for t in rep.targets if t.missed]
    for target in rep.targets:
        print(("quick set, not a verdict: " if args.quick else "") + target.line())
    print("wrote " + ", ".join(str(p) for p in rep.paths.values()))
    if missed and not args.quick:
        error(f"{len(missed)} required target(s) of the report missed (the FAIL lines above); "
              "the report is written")
        return EXIT_FAILURE
    return EXIT_OK

