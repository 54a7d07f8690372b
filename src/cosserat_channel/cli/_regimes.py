"""The ``boundary`` and ``plot`` commands: solvability edges and figures of results."""

from __future__ import annotations

import argparse
import math

from ..parameters import ParameterError
from .common import (
    ETA_RANGE,
    EXIT_FAILURE,
    EXIT_OK,
    FIRST_RUN,
    CliError,
    Progress,
    add_overwrite_argument,
    check_not_input,
    check_output_path,
    figure_output,
    publish_figure,
    interrupted,
    interruptible,
    note,
    open_results,
    read_or_write_failure,
    register,
)

from ..regime_codes import ETA_COARSE

# ---------------------------------------------------------------------------------------------
# phase-plane, boundary, plot (data in regimes/, figures in plot/regimes.py and plot/lines.py)
# ---------------------------------------------------------------------------------------------
# boundary: values per list and (A, N) pairs. One pair costs ~80 solves (tens of ms), so the
# largest accepted run takes about an hour; without a bound 'start:stop:1000000000' built a list
# of 23 GB before anything was checked.
MAX_BOUNDARY_VALUES = 100_000
MAX_BOUNDARY_PAIRS = 100_000
MAX_COARSE = 10_000


def parse_values(text: str, option: str, max_values: int = MAX_BOUNDARY_VALUES) -> list:
    """``"a,b,c"`` (a list) or ``"start:stop:num"`` (linspace) -> list of floats; CliError if bad."""
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3:
                raise ValueError
            start, stop, num = float(parts[0]), float(parts[1]), int(parts[2])
            if num < 1:
                raise ValueError
            if num > max_values:
                raise CliError(f"{option}: {num:,} values is more than {max_values:,}; "
                               "split the run")
            import numpy as np

            values = [float(v) for v in np.linspace(start, stop, num)]
        else:
            if text.count(",") >= max_values:
                raise CliError(f"{option}: more than {max_values:,} values; split the run")
            values = [float(v) for v in text.split(",")]
    except ValueError:
        raise CliError(f"{option}: expected a list 'a,b,c' or 'start:stop:num'; got {text!r}") \
            from None
    if not all(math.isfinite(v) for v in values):
        raise CliError(f"{option}: values must be finite; got {text!r}")
    return values


def _boundary_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--A", required=True, metavar="LIST|START:STOP:NUM",
                   help="values of A, e.g. -0.9:0.9:19 or 0,0.3333333333333333")
    p.add_argument("--N", required=True, metavar="LIST|START:STOP:NUM",
                   help="values of N (> 0), e.g. 0.5,1,2")
    p.add_argument("--eta-range", default=ETA_RANGE, metavar="LO:HI",
                   help=f"searched range of eta = eps L (default {ETA_RANGE}: eps <= 1, L <= 100)")
    p.add_argument("--coarse", type=int, default=ETA_COARSE, metavar="M",
                   help=f"log-spaced samples before bisection (default {ETA_COARSE})")
    p.add_argument("-o", "--output", metavar="OUT.nc",
                   help="NetCDF file to write (without it the table is printed alone)")
    p.add_argument("--plot", metavar="FILE.png", help="also plot eta_max against A, one line per N")
    p.add_argument("--atlas", metavar="ATLAS.nc",
                   help="draw the edges from this atlas (written by 'atlas') instead of tracing "
                   "(default: the cached atlas, else the shipped whole-plane one, where it covers "
                   "the grid, holds its tolerance there and --eta-range is its own)")
    p.add_argument("--trace", action="store_true",
                   help="trace the edges (by continuation along the grid) even where an atlas "
                   "covers the grid; --coarse applies to tracing only")
    p.add_argument("--overwrite", action="store_true",
                   help="trace again and replace OUT.nc (and FILE.png) if it exists (without it "
                   "an OUT.nc traced with the same arguments is reused, any other file is kept)")


@register("boundary", "trace eta_max(A, N), the largest eps L with a solution, by bisection",
          _boundary_arguments)
def _boundary(args: argparse.Namespace) -> int:
    from ..parameters import check_eta_range, check_values

    A = parse_values(args.A, "--A")
    N = parse_values(args.N, "--N")
    if len(A) * len(N) > MAX_BOUNDARY_PAIRS:
        raise CliError(f"--A, --N: {len(A) * len(N):,} (A, N) pairs is more than "
                       f"{MAX_BOUNDARY_PAIRS:,}; split the run")
    try:
        lo, hi = (float(v) for v in args.eta_range.split(":"))
    except ValueError:
        raise CliError(f"--eta-range: expected LO:HI; got {args.eta_range!r}") from None
    try:
        # The ranges of parameters.py, as for 'point': outside them the kernels overflow.
        check_values("A", A, "--A")
        check_values("N", N, "--N")
        check_eta_range((lo, hi), "--eta-range")
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    if not 2 <= args.coarse <= MAX_COARSE:
        raise CliError(f"--coarse must be in [2, {MAX_COARSE}]; got {args.coarse}")
    # An existing OUT.nc may be reused (below); FILE.png is kept unless --overwrite.
    if args.output is not None:
        check_output_path(args.output, "-o", overwrite=True)
    if args.plot is not None:
        check_not_input(args.plot, [p for p in [args.output] if p is not None], "--plot")
        figure_output(args.plot, "--plot", overwrite=args.overwrite)
    from .. import regimes
    from ..status import Status

    if args.atlas is not None and args.output is not None:
        check_not_input(args.output, [args.atlas], "-o")
    source = _edge_source(A, N, atlas=args.atlas, trace=args.trace, eta_range=(lo, hi))
    if not source.traced:
        if args.output is not None:
            check_output_path(args.output, "-o", overwrite=args.overwrite)
        if args.atlas is None:
            note(f"edges drawn from the {source.describe()} (--trace to trace them)")
        ds = source.boundary
    else:
        ds = None if args.overwrite or args.output is None else \
            _same_boundary(args.output, A, N, lo, hi, args.coarse)
    write = ds is None or not source.traced  # a file reused as it is is not written again
    if ds is None:
        try:
            with interruptible(), Progress("boundary", "tracing " + FIRST_RUN, delay=1.0) as bar:
                ds = regimes.trace_boundary(A, N, eta_range=(lo, hi), n_coarse=args.coarse,
                                            progress=bar.report)
        except KeyboardInterrupt as exc:
            return interrupted(exc, "no file written" + (f" ({args.output} untouched)" if
                               args.output else "") + ": a trace keeps nothing before its end")
    from ..files import write_dataset

    try:
        if write and args.output is not None:
            write_dataset(args.output, ds, replace=args.overwrite)
        if args.plot is not None:
            from ..plot import regimes as plot_regimes

            publish_figure(plot_regimes.boundary_figure(ds), args.plot, "--plot",
                           overwrite=args.overwrite)
    except OSError as exc:
        from ..files import WriteError

        raise CliError(str(exc) if isinstance(exc, WriteError) else f"cannot write: {exc}",
                       EXIT_FAILURE) from None
    # Printed after the files are written: a reader that leaves early (| head) loses no file.
    print(f"{'A':>12} {'N':>10} {'eta_max':>18} {'kind':<20} {'status above'}")
    for i, a in enumerate(ds["A"].values):
        for j, n in enumerate(ds["N"].values):
            k = int(ds["edge_kind"].values[i, j])
            above = int(ds["status_above"].values[i, j])
            name = "-" if above < 0 else Status(above).name
            print(f"{a:12.6g} {n:10.6g} {ds['eta_max'].values[i, j]:18.12g} "
                  f"{regimes.EDGE_KINDS[k]:<20} {name}")
    return EXIT_OK


_OPTIONS = {"atlas": "--atlas", "eta_range": "--eta-range", "trace": "--trace"}


def _edge_source(A, N, **kw):
    """:func:`cosserat_channel.atlas.source.edge_source` with its notes on stderr and its
    errors as one line naming the option at fault."""
    from ..atlas.source import SourceError, edge_source

    try:
        return edge_source(A, N, note=note, **kw)
    except SourceError as exc:
        if exc.parameter == "trace":
            raise CliError("--atlas and --trace are two sources of the same edge: give one") \
                from None
        raise CliError(f"{_OPTIONS[exc.parameter]}: {exc}") from None


def _same_boundary(path, A, N, lo, hi, coarse):
    """The Dataset in ``path`` if it was traced with these arguments (note: reused), None if there
    is no file; CliError if it is another file (kept unless --overwrite)."""
    from ..files import FILE, output_kind

    if output_kind(path) != FILE:  # nothing there, or a stream to write into
        return None
    import numpy as np
    import xarray as xr

    from ..results.selection import OPEN_ERRORS

    try:
        ds = xr.load_dataset(path)
    except OPEN_ERRORS:
        ds = None
    if ds is not None and "eta_max" in ds:
        a = ds.attrs
        if (ds["A"].size == len(A) and ds["N"].size == len(N)
                and np.array_equal(ds["A"].values, A) and np.array_equal(ds["N"].values, N)
                and (a.get("eta_search_min"), a.get("eta_search_max"), a.get("n_coarse"))
                == (lo, hi, coarse)):
            note(f"{path} was traced with these arguments; reused (add --overwrite to trace "
                 "again)")
            return ds
    what = "traced with other arguments" if ds is not None and "eta_max" in ds else \
        "not a 'boundary' result"
    raise CliError(f"{path} exists ({what}); kept: add --overwrite to replace it, or choose "
                   "another -o")


def _plot_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", metavar="OUT.nc", help="a result file written by 'run'")
    p.add_argument("--regime", action="store_true",
                   help="map the status over the (--x, --y) slice with the analytic boundaries")
    p.add_argument("--x", required=True, help="abscissa: eps, W_over_d_p, L, K, A, N or xi")
    p.add_argument("--y", required=True,
                   help="a variable (e.g. Delta; u_over_u0 with --x xi) or, with --regime, a "
                   "dimension")
    p.add_argument("--hue", help="one line per value of this dimension")
    p.add_argument("--at", metavar="NAME=VALUE[,NAME=VALUE]",
                   help="grid values of the other dimensions that vary, e.g. K=0.5,N=1 "
                   "(an off-grid value names the nearest)")
    p.add_argument("--nearest", action="store_true",
                   help="let --at take the nearest grid values (and say so on stderr)")
    p.add_argument("--boundary", metavar="BOUNDARY.nc",
                   help="with --regime: traced edge from 'boundary' (default: traced here on a "
                   "coarse grid)")
    p.add_argument("--atlas", metavar="ATLAS.nc",
                   help="with --regime: draw the edges from this atlas (written by 'atlas'; "
                   "default: the cached atlas if it covers the map, else traced here)")
    p.add_argument("--no-asymptote", dest="asymptote", action="store_false",
                   help="do not overlay the Appendix C asymptotics (N = 1)")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="figure to write")
    add_overwrite_argument(p, "FILE.png")


def parse_at(text: str | None) -> dict:
    """``"eps=0.03,L=10"`` -> ``{"eps": 0.03, "L": 10.0}``; CliError if malformed."""
    out = {}
    for item in (text or "").split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            x = float(value)
        except ValueError:
            raise CliError(f"--at: expected NAME=VALUE[,NAME=VALUE]; got {text!r}") from None
        name = name.strip()
        if name in out:
            raise CliError(f"--at {name}: given twice ({name}={out[name]:.10g} and "
                           f"{name}={x:.10g}); give each dimension once")
        out[name] = x
    return out


def _resolve_at(ds, args, at: dict) -> dict:
    """``--at`` values replaced by the grid values they match (exactly, or with --nearest the
    nearest, noted on stderr); CliError naming the dimensions still to fix, with an example."""
    from ..parameters import DIMS as dims
    from ..results.selection import QueryError, match_coordinate

    out = {}
    for name, value in at.items():
        if name not in ds.dims or name not in ds.coords:
            raise CliError(f"--at {name}: not a dimension of the result (have "
                           f"{', '.join(d for d in ds.dims if d in ds.coords)})")
        c = ds[name].values
        try:
            i, exact = match_coordinate(c, value, name, "--at", nearest=args.nearest)
        except QueryError as exc:
            raise CliError(str(exc)) from None
        if not exact:
            note(f"--nearest: --at {name}={value:.10g} is not a grid value; took the nearest, "
                 f"{name}={float(c[i]):.10g}")
        out[name] = float(c[i])
    keep = {args.x, args.y} if args.regime else {args.x, args.hue, "eps" if args.x ==
                                                  "W_over_d_p" else args.x}
    loose = [d for d in dims if d in ds.dims and ds.sizes[d] > 1 and d not in keep
             and d not in out]
    if loose:
        example = ",".join(f"{d}={float(ds[d].values[0])!r}" for d in loose)
        values = "; ".join(f"{d}: " + ", ".join(f"{v:.10g}" for v in ds[d].values[:6])
                           + (", …" if ds.sizes[d] > 6 else "") for d in loose)
        raise CliError(f"{', '.join(loose)} vary in {args.results}: fix them with --at, e.g. "
                       f"--at {example} (values {values})")
    return out


def _open_whole(path):
    """The result file at ``path`` for a figure, which reads all of it: opened without dask.

    :func:`open_results` (query's checks and one-line errors) opens it dask-backed, which costs a
    fresh process about a second of imports and scheduling for nothing here. A file that fails
    the same checks goes through :func:`open_results`, which says what is wrong with it.
    """
    import xarray as xr

    from ..results.flags import QueryError, check_flags
    from ..results.selection import OPEN_ERRORS, check_storage

    try:
        check_storage(path)  # it is read whole: its declared sizes first
    except QueryError as exc:
        raise CliError(str(exc)) from None
    try:
        ds = xr.open_dataset(path)
    except OPEN_ERRORS:
        return open_results(path)
    status = ds.data_vars.get("status")
    try:
        if status is None or not {"flag_values", "flag_meanings"} <= set(status.attrs):
            raise QueryError("not a result file")
        check_flags(ds)
    except QueryError:
        ds.close()
        return open_results(path)
    return ds


@register("plot", "plot a result file: regime map, Delta against a parameter, or profiles",
          _plot_arguments)
def _plot(args: argparse.Namespace) -> int:
    at = parse_at(args.at)
    if args.boundary is not None and not args.regime:
        raise CliError("--boundary goes with --regime")
    if args.atlas is not None and not args.regime:
        raise CliError("--atlas goes with --regime")
    if args.atlas is not None and args.boundary is not None:
        raise CliError("--atlas and --boundary are two sources of the same edge: give one")
    if args.regime and args.hue is not None:
        raise CliError("--hue does not go with --regime")
    check_not_input(args.output, [args.results, args.boundary, args.atlas], "-o")
    figure_output(args.output, overwrite=args.overwrite)
    from ..plot import regimes as plot_regimes
    ds = _open_whole(args.results)
    try:
        # Read (and so checksum) first: a damaged file is reported as such, whatever else is wrong.
        try:
            ds = ds.load()
        except (OSError, RuntimeError) as exc:
            raise read_or_write_failure(exc, args.results, ds, None) from None
        at = _resolve_at(ds, args, at)
        boundary = None
        if args.boundary is not None:
            import xarray as xr

            from ..results.selection import OPEN_ERRORS

            try:
                boundary = xr.load_dataset(args.boundary)
            except OPEN_ERRORS as exc:
                raise CliError(f"--boundary: cannot read {args.boundary!r}: {exc}") from None
            if "eta_max" not in boundary:
                raise CliError(f"--boundary: {args.boundary!r} is not a 'boundary' result")
        try:
            with Progress("plot", "drawing " + FIRST_RUN * args.regime, delay=1.0) as bar:
                if args.regime:
                    if boundary is None:
                        boundary = _atlas_boundary(ds, args, at)
                    if boundary is None:
                        # The figure only draws data: the traced edge is computed here, on the
                        # coarse (A, N) grid the map asks for.
                        grid = plot_regimes.regime_trace_grid(ds, args.x, args.y, at)
                        if grid is not None:
                            from .. import regimes

                            boundary = regimes.trace_boundary(*grid, progress=bar.report)
                    fig = plot_regimes.regime_map(ds, args.x, args.y, at, boundary=boundary)
                else:
                    # Imported here: line plots overlay the asymptotics (scipy.optimize, ~0.4 s
                    # of a fresh process), which a regime map never needs.
                    from ..plot import lines as plot_lines

                    fig = plot_lines.line_plot(ds, args.x, args.y, args.hue, at,
                                               asymptote=args.asymptote)
            publish_figure(fig, args.output, overwrite=args.overwrite)
        except (ValueError, KeyError) as exc:
            # A KeyError's str() is the repr of its message; its argument is the message.
            message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
            raise CliError(str(message)) from None
        except OSError as exc:
            raise CliError(f"-o: cannot write {args.output!r}: {exc}", EXIT_FAILURE) from None
    finally:
        ds.close()
    return EXIT_OK


def _atlas_boundary(ds, args, at):
    """The edge of a regime map from ``--atlas`` or the default atlas (:func:`_edge_source`,
    any stated error: the figure marks where it is above the atlas's tolerance), as a boundary
    Dataset; None when the map has no (A, N) direction or no atlas answers (the caller then
    traces). Which atlas drew the edge is said on stderr."""
    import math

    from ..plot import regimes as plot_regimes

    # On the map's own contouring grid: the figure then takes the edge as it is, uninterpolated.
    grid = plot_regimes.regime_trace_grid(ds, args.x, args.y, at, n=plot_regimes.MAP_GRID)
    if grid is None:
        return None
    source = _edge_source(*grid, atlas=args.atlas, tol=math.inf)
    if source.traced:
        return None
    if args.atlas is None:
        note(f"edges drawn from the {source.describe()}")
    return source.boundary
