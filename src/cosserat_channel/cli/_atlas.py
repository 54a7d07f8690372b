"""The ``atlas`` command: sample every edge of solvability over a box of (A, N), adaptively."""

from __future__ import annotations

import argparse
import math
import os

from . import (
    EXIT_FAILURE,
    EXIT_OK,
    ETA_RANGE,
    CliError,
    ParameterError,
    Progress,
    _FIRST_RUN,
    _figure_output,
    _note,
    check_not_input,
    check_output_path,
    interruptible,
    interrupted,
    register,
)


def parse_range(text: str, option: str) -> tuple:
    """``"a:b"`` -> ``(a, b)`` with ``a < b`` finite; CliError naming ``option`` otherwise."""
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise CliError(f"{option}: expected LO:HI; got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise CliError(f"{option}: need finite LO < HI; got {text!r}")
    return lo, hi


def _atlas_arguments(p: argparse.ArgumentParser) -> None:
    from ..atlas import (
        DEFAULT_A,
        DEFAULT_N,
        DEFAULT_TOL,
        DEGREE,
        MAX_DEGREE,
        MAX_DEPTH,
        MAX_DEPTH_LIMIT,
        TOL_MAX,
        TOL_MIN,
    )

    out = p.add_mutually_exclusive_group(required=True)
    out.add_argument("-o", "--output", metavar="ATLAS.nc", help="NetCDF file to write")
    out.add_argument("--cache", action="store_true",
                     help="write the cached atlas that 'plot --regime' uses when no --atlas is "
                     "given ($XDG_CACHE_HOME/cosserat-channel/atlas.nc)")
    p.add_argument("--A", default=f"{DEFAULT_A[0]:g}:{DEFAULT_A[1]:g}", metavar="LO:HI",
                   help=f"range of A (default {DEFAULT_A[0]:g}:{DEFAULT_A[1]:g}; write --A=-1:5 when "
                   "it starts below 0; A <= -1 and the wall line are analytic)")
    p.add_argument("--N", default=f"{DEFAULT_N[0]:g}:{DEFAULT_N[1]:g}", metavar="LO:HI",
                   help=f"range of N > 0 (default {DEFAULT_N[0]:g}:{DEFAULT_N[1]:g})")
    p.add_argument("--tol", type=float, default=DEFAULT_TOL,
                   help=f"relative error of the edges in eps L, in [{TOL_MIN:g}, {TOL_MAX:g}] "
                   f"(default {DEFAULT_TOL:g}: the edge itself is known to ~{TOL_MIN:g})")
    p.add_argument("--eta-range", default=ETA_RANGE, metavar="LO:HI",
                   help=f"range of eta = eps L the atlas answers for (default {ETA_RANGE})")
    p.add_argument("--degree", type=int, default=DEGREE,
                   help=f"Chebyshev degree a cell starts with, even (default {DEGREE})")
    p.add_argument("--max-degree", type=int, default=MAX_DEGREE,
                   help="largest degree a cell may grow to (doubling) before it is split "
                   f"(default {MAX_DEGREE}; --degree for splitting only)")
    p.add_argument("--max-depth", type=int, default=MAX_DEPTH,
                   help=f"splits of a root cell, in [0, {MAX_DEPTH_LIMIT}] (default {MAX_DEPTH})")
    p.add_argument("--plot", metavar="FILE.png",
                   help="also draw the solvable region in (A, N), shaded by eta_max and eta_min")
    p.add_argument("--workers", type=int, metavar="N",
                   help="threads tracing a cell's nodes at once (default: all cores; the atlas "
                   "is the same whatever their number)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the output (and FILE.png) if it exists")


@register("atlas", "sample every edge of solvability in eps L over a box of (A, N), adaptively",
          _atlas_arguments)
def _atlas(args: argparse.Namespace) -> int:
    from .. import atlas as atlas_mod

    A = parse_range(args.A, "--A")
    N = parse_range(args.N, "--N")
    eta_range = parse_range(args.eta_range, "--eta-range")
    workers = (os.cpu_count() or 1) if args.workers is None else args.workers
    if workers < 1:
        raise CliError(f"--workers must be a positive integer; got {workers}")
    try:
        atlas_mod.check_build_arguments(A, N, args.tol, args.degree, args.max_depth, eta_range,
                                        args.max_degree)
    except ParameterError as exc:  # the message names the argument and its allowed range
        raise CliError(str(exc)) from None
    output = atlas_mod.cache_path() if args.cache else args.output
    if args.cache:
        os.makedirs(os.path.dirname(output), exist_ok=True)
    check_output_path(output, "-o", overwrite=args.overwrite)
    if args.plot is not None:
        check_not_input(args.plot, [output], "--plot")
        _figure_output(args.plot, "--plot", overwrite=args.overwrite)
    try:
        with interruptible(), Progress("atlas", "tracing " + _FIRST_RUN, delay=1.0) as bar:
            def progress(leaves, queued, traces):
                bar.update(f"{leaves} cells done, {queued} queued, {traces} edges traced")

            atlas = atlas_mod.build_atlas(A, N, tol=args.tol, degree=args.degree,
                                          max_depth=args.max_depth, max_degree=args.max_degree,
                                          eta_range=eta_range, progress=progress,
                                          workers=workers)
    except KeyboardInterrupt as exc:
        # The traces live in memory until the atlas is whole: nothing is written, nothing lost.
        return interrupted(exc, f"nothing written to {output} (the traces are kept in memory "
                           "until the atlas is whole: a rerun traces them again)")
    n_unres = int((atlas.leaf_n < 0).sum())
    over = int((atlas.leaf_error > atlas.tol).sum()) - n_unres
    a = atlas.attrs
    print(f"{atlas.leaf_n.size} cells ({n_unres} unresolved, {over} above the tolerance), "
          f"{a['n_traces']} edges traced, {a['n_solves']} solves "
          f"({a['solves_per_edge_point']:.2f} per edge point; {a['n_fallback']} of "
          f"{a['n_predicted']} predicted traces made afresh)")
    try:
        atlas_mod.save_atlas(atlas, output)
        if args.plot is not None:
            import numpy as np

            from ..plot import regimes as plot_regimes

            bds = atlas.boundary(np.linspace(*A, 301), np.linspace(*N, 201))
            plot_regimes.solvable_region_figure(bds, path=args.plot)
    except OSError as exc:
        raise CliError(str(exc), EXIT_FAILURE) from None
    if args.cache:
        _note(f"cached as {output}: 'plot --regime' draws its edges from it")
    return EXIT_OK
