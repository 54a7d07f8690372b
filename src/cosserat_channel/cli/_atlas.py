"""The ``atlas`` command: sample every edge of solvability over a box of (A, N), adaptively."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import stat

from ..parameters import ParameterError
from .common import (
    ETA_RANGE,
    EXIT_FAILURE,
    EXIT_OK,
    FIRST_RUN,
    CliError,
    Progress,
    check_not_input,
    check_output_path,
    figure_output,
    interrupted,
    interruptible,
    note,
    publish_figure,
    register,
)

from ..files import STREAM, output_kind, remove_stale_temporaries


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
    out.add_argument("-o", "--output", metavar="ATLAS.nc",
                     help="NetCDF file to write; the edges traced before Ctrl-C are kept in "
                     "ATLAS.nc.partial, and the same command resumes from them")
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
        built = atlas_mod.check_build_arguments(A, N, args.tol, args.degree, args.max_depth,
                                                eta_range, args.max_degree)
    except ParameterError as exc:  # the message names the argument and its allowed range
        raise CliError(str(exc)) from None
    output = atlas_mod.cache_path() if args.cache else args.output
    if args.cache:
        try:
            os.makedirs(os.path.dirname(output), exist_ok=True)
        except OSError as exc:  # a read-only home, a file where the directory should be
            raise CliError(f"--cache: cannot make the cache directory "
                           f"{os.path.dirname(output)!r} ({exc.strerror or exc}); set "
                           "XDG_CACHE_HOME to a writable directory, or give -o FILE",
                           EXIT_FAILURE) from None
    check_output_path(output, "-o", overwrite=args.overwrite)
    if args.plot is not None:
        check_not_input(args.plot, [output], "--plot")
        figure_output(args.plot, "--plot", overwrite=args.overwrite)
    # The traces are kept beside a file output when the build is stopped, and resumed from there:
    # not beside a stream (a FIFO, /dev/stdout), whose directory is not the user's to write in.
    partial = None if output_kind(output) == STREAM else atlas_mod.partial_path(output)
    key = atlas_mod.traces_key(*built, args.max_degree)
    try:
        traces = None if partial is None else atlas_mod.load_traces(partial, key)
    except ParameterError as exc:  # another build's, damaged, or not a file: left alone
        raise CliError(str(exc)) from None
    kept = traces is not None
    if kept:
        note(f"resuming from the {len(traces)} edges traced before, kept in {partial}")
    else:
        traces = {}
    resumed = len(traces)
    saver = _Saver(partial, traces, key, kept)
    try:
        with interruptible(), Progress("atlas", "tracing " + FIRST_RUN, delay=1.0) as bar:
            def progress(done, total, text=""):
                bar.report(done, total, text)
                saver.maybe()

            atlas = atlas_mod.build_atlas(A, N, tol=args.tol, degree=args.degree,
                                          max_depth=args.max_depth, max_degree=args.max_degree,
                                          eta_range=eta_range, progress=progress,
                                          workers=workers, traces=traces)
    except KeyboardInterrupt as exc:
        return interrupted(exc, _keep_traces(partial, traces, key, resumed, output,
                                             ours=saver.owns()))
    n_unres = int((atlas.leaf_n < 0).sum())
    over = int((atlas.leaf_error > atlas.tol).sum()) - n_unres
    a = atlas.attrs
    print(f"{atlas.leaf_n.size} cells ({n_unres} unresolved, {over} above the tolerance), "
          f"{a['n_traces']} edges traced, {a['n_solves']} solves "
          f"({a['solves_per_edge_point']:.2f} per edge point; {a['n_fallback']} of "
          f"{a['n_predicted']} predicted traces made afresh)")
    try:
        try:
            with interruptible():
                atlas_mod.save_atlas(atlas, output, replace=args.overwrite)
        except KeyboardInterrupt as exc:  # the file is written whole or not at all
            return interrupted(exc, _keep_traces(partial, traces, key, resumed, output,
                                                 ours=saver.owns()))
        if saver.owns():  # the atlas is whole: its traces are in it
            with contextlib.suppress(FileNotFoundError):
                os.unlink(partial)
        if partial is not None:  # and what a build killed while saving them left beside it
            remove_stale_temporaries(os.path.dirname(os.path.abspath(partial)), partial)
        if args.plot is not None:
            import numpy as np

            from ..plot import regimes as plot_regimes

            bds = atlas.boundary(np.linspace(*A, 301), np.linspace(*N, 201))
            try:
                with interruptible():
                    publish_figure(plot_regimes.solvable_region_figure(bds), args.plot,
                                   "--plot", overwrite=args.overwrite)
            except KeyboardInterrupt as exc:
                return interrupted(exc, f"the atlas is written to {output}; {args.plot} is not")
    except OSError as exc:
        raise CliError(str(exc), EXIT_FAILURE) from None
    if args.cache:
        note(f"cached as {output}: 'plot --regime' draws its edges from it")
    return EXIT_OK


# Seconds between two savings of the traces while a build runs: a build killed outright (an
# out-of-memory kill, a batch system's hard limit) loses at most this much tracing.
SAVE_SECONDS = 60.0


class _Saver:
    """Writes the traces of a running build to ``partial`` every :data:`SAVE_SECONDS`, whole
    or not at all (:func:`atlas.save_traces`), so that a build killed by SIGKILL resumes.

    Never over a file it did not write or resume from: what is at ``partial`` must be the very
    file (device and inode) it last saw there; anything else appeared meanwhile and is left
    alone. A failure to write is said once, and the build goes on (a stopped build still keeps
    its traces).
    """

    def __init__(self, partial, traces, key, resumed: bool):
        import time

        self.partial, self.traces, self.key = partial, traces, key
        self.wrote = False
        self._saved = len(traces)
        self._clock = time.monotonic
        self._last = self._clock()
        self._failed = False
        self._ours = self._identity() if resumed else None

    def _identity(self):
        try:
            st_ = os.lstat(self.partial)
        except OSError:
            return None
        return (st_.st_dev, st_.st_ino) if stat.S_ISREG(st_.st_mode) else ("other", st_.st_mode)

    def owns(self) -> bool:
        """Whether the file at ``partial`` is the one this build saved or resumed from."""
        return self._ours is not None and self._identity() == self._ours

    def maybe(self) -> None:
        """Save the traces if :data:`SAVE_SECONDS` have passed and there are new ones."""
        from .. import atlas as atlas_mod
        from ..files import describe

        if self.partial is None or self._failed or len(self.traces) == self._saved or \
                self._clock() - self._last < SAVE_SECONDS:
            return
        found = self._identity()
        if found is not None and found != self._ours:
            self._failed = True
            mode = os.lstat(self.partial).st_mode if found[0] == "other" else stat.S_IFREG
            note(f"{self.partial} appeared meanwhile ({describe(mode)}) and is left alone: the "
                 "traces are no longer kept as the build goes")
            return
        snapshot = dict(self.traces)
        try:
            atlas_mod.save_traces(self.partial, snapshot, self.key)
        except OSError as exc:
            self._failed = True
            note(f"cannot keep the traces in {self.partial} as the build goes "
                 f"({exc.strerror or exc}); they are kept if it is stopped")
            return
        self.wrote = True
        self._ours = self._identity()
        self._saved = len(snapshot)
        self._last = self._clock()


def _keep_traces(partial, traces, key, resumed, output, ours=False) -> str:
    """Write the traces of a stopped build to ``partial`` (unless there is nothing new to keep);
    what was kept, for :func:`interrupted`. ``ours``: the file at ``partial`` is the one this
    build resumed from or saved (:meth:`_Saver.owns`); anything else there is left alone."""
    from .. import atlas as atlas_mod
    from ..files import WriteError, describe, write_failure

    if len(traces) == resumed:
        if not resumed:
            return f"nothing written to {output} (no edge was traced yet)"
        return (f"nothing written to {output}; the {resumed} edges traced before are still kept "
                f"in {partial}: run the same command again to resume")
    if partial is None:
        return (f"nothing written to {output} (an atlas written to a stream keeps no traces: "
                "a rerun traces them again)")
    try:
        mode = os.lstat(partial).st_mode
    except OSError:  # nothing there (or a name too long for one: saving says so)
        mode = None
    if mode is not None and not (ours and stat.S_ISREG(mode)):
        # Made by someone else while the build ran: never written over.
        return (f"nothing written to {output}; the traces are lost: {partial} appeared meanwhile "
                f"({describe(mode)}) and is left alone")
    try:
        with interruptible():  # stopped again: the file is written whole or not at all
            atlas_mod.save_traces(partial, traces, key)
    except OSError as exc:
        if not isinstance(exc, WriteError):
            exc = write_failure(partial, exc)
        return f"nothing written to {output}; the traces could not be kept ({exc})"
    except KeyboardInterrupt:
        return (f"nothing written to {output}; stopped again while the traces were written to "
                f"{partial}: they are lost" + (", the earlier ones kept" if ours else ""))
    return (f"the {len(traces)} edges traced so far are kept in {partial}: run the same command "
            "again to resume")
