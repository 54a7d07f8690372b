"""The ``run``, ``query`` and ``info`` commands: sweeps and their result files."""

from __future__ import annotations

import argparse
import math
import os
import logging
import sys

from . import (  # noqa: F401 (the shared pieces of the command line)
    open_results,
    CliError,
    EXIT_FAILURE,
    EXIT_OK,
    PROG,
    ParameterError,
    Progress,
    _FIRST_RUN,
    _error,
    _note,
    _read_or_write_failure,
    check_not_input,
    check_output_path,
    register,
)
# ---------------------------------------------------------------------------------------------
# run (the engine lives in sweep/engine.py)
# ---------------------------------------------------------------------------------------------
def _run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("sweep", metavar="SWEEP.toml", help="the sweep file")
    p.add_argument("-o", "--output", metavar="OUT.nc",
                   help="result file (default: the sweep's [output] path, else SWEEP.nc in the "
                   "current directory); unfinished work is kept in OUT.nc.partial/ and resumed")
    p.add_argument("--workers", type=int, metavar="N", help="threads (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the blocks on this dask.distributed scheduler, e.g. tcp://host:8786 "
                   "(checked before anything is written; see README, 'sweeps on a cluster')")
    p.add_argument("--no-reduce", dest="reduce", action="store_false",
                   help="one integration per grid point instead of per distinct (eps L, A, N); "
                   "same values, for checks and benchmarks")
    p.add_argument("--block-size", type=int, metavar="B", help="integrations per block")
    p.add_argument("--overwrite", action="store_true",
                   help="compute again and replace OUT.nc if it is already a finished result "
                   "(without it a finished OUT.nc is kept)")
    p.add_argument("--compress", choices=("zlib", "zstd", "none"),
                   help="codec of the file: zlib (level 1 with shuffle; every netCDF-4 reader "
                   "opens it), zstd (Zstandard: less CPU to write, needs netCDF-C >= 4.9 with "
                   "its filter to read) or none (default: the sweep's [output] compress, else "
                   "zlib)")


@register("run", "solve every point of a sweep file and write a NetCDF result", _run_arguments)
def _run(args: argparse.Namespace) -> int:
    for flag, value in (("--workers", args.workers), ("--block-size", args.block_size)):
        if value is not None and value < 1:
            raise CliError(f"{flag} must be a positive integer; got {value}")

    from ..sweep import run_sweep
    from ..sweep.spec import SweepError, load_sweep

    try:
        spec = load_sweep(args.sweep)
    except SweepError as exc:
        raise CliError(str(exc)) from None
    if args.output is not None and not args.output.strip():
        raise CliError("-o: the output file name is empty")
    output = args.output if args.output is not None else spec.output_path
    if output is None:
        output = os.path.splitext(os.path.basename(args.sweep))[0] + ".nc"
    check_not_input(output, [args.sweep], "-o")
    if not args.overwrite and _finished_result_kept(output, spec):
        return EXIT_OK
    if args.scheduler is None:
        from ..sweep.engine import warm_up

        # Here, not inside the run: on a terminal the minute a new version spends compiling
        # shows as such, before the run's own progress bar starts.
        with Progress("run", "loading the solver " + _FIRST_RUN, delay=2.0):
            warm_up()
    logger = logging.getLogger("cosserat_channel.sweep")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"{PROG}: run: %(message)s"))
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    from ..sweep.engine import SchedulerLost

    try:
        run_sweep(spec, output, workers=args.workers, scheduler=args.scheduler,
                  reduce=args.reduce, block_size=args.block_size, compress=args.compress).close()
    except SweepError as exc:
        raise CliError(str(exc)) from None
    except SchedulerLost as exc:
        from ..sweep.store import partial_dir

        raise CliError(f"{exc}; finished blocks are kept in {partial_dir(output)}/, rerun the same "
                       "command to resume", EXIT_FAILURE) from None
    except OSError as exc:
        from ..files import WriteError
        from ..sweep.store import partial_dir

        message = str(exc) if isinstance(exc, WriteError) else \
            f"cannot write {output!r}: {exc.strerror or exc}"
        if os.path.isdir(partial_dir(output)):
            message += (f"; finished blocks are kept in {partial_dir(output)}/, run the same "
                        "command again to resume")
        raise CliError(message, EXIT_FAILURE) from None
    except KeyboardInterrupt:
        _error(f"interrupted; finished blocks are kept in {output}.partial/, run the same "
               "command again to resume")
        return 130
    finally:
        logger.removeHandler(handler)
    return EXIT_OK


def _finished_result_kept(output: str, spec) -> bool:
    """True (and a note) if ``output`` is already this sweep's result; CliError if it is another
    file. An unfinished run (``OUT.nc.partial/`` beside it) is resumed, not refused."""
    from ..sweep.store import partial_dir

    if not os.path.exists(output) or os.path.isdir(partial_dir(output)):
        return False
    sha = None
    try:
        import netCDF4

        with netCDF4.Dataset(output) as nc:
            sha = getattr(nc, "sweep_sha256", None)
    except (OSError, ValueError, RuntimeError):
        pass
    if sha == spec.sha256:
        _note(f"{output} is already the finished result of this sweep; kept (add --overwrite "
              "to compute it again)")
        return True
    what = "the result of another sweep" if sha else "not a result of 'run'"
    raise CliError(f"{output} exists ({what}); kept: add --overwrite to replace it, or choose "
                   "another -o")



# ---------------------------------------------------------------------------------------------
# example (the sweep files that come with the package)
# ---------------------------------------------------------------------------------------------
def _example_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", metavar="NAME",
                   help="an example's name (without NAME: list them)")
    p.add_argument("-o", "--output", metavar="SWEEP.toml",
                   help="copy it to this file (default: print it)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing SWEEP.toml")


@register("example", "list the example sweep files that come with the package, print or copy one",
          _example_arguments)
def _example(args: argparse.Namespace) -> int:
    from ..sweep.spec import examples

    shipped = examples()
    if args.name is None:
        if args.output is not None:
            raise CliError("-o needs an example's NAME")
        width = max(map(len, shipped))
        for name, text in shipped.items():
            first = next((line.lstrip("# ").strip() for line in text.splitlines()
                          if line.startswith("#")), "")
            print(f"{name:<{width}}  {first}")
        return EXIT_OK
    name = args.name[:-5] if args.name.endswith(".toml") else args.name
    if name not in shipped:
        raise CliError(f"no example {args.name!r}; the examples are {', '.join(shipped)}")
    if args.output is None:
        sys.stdout.write(shipped[name])
        return EXIT_OK
    check_output_path(args.output, "-o")
    if os.path.lexists(args.output) and not args.overwrite:
        raise CliError(f"-o: {args.output} exists; kept (add --overwrite to replace it)")
    from ..files import atomic_output

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(shipped[name])

    try:
        atomic_output(args.output, write)
    except OSError as exc:
        raise CliError(f"-o: cannot write {args.output!r}: {exc.strerror or exc}",
                       EXIT_FAILURE) from None
    _note(f"wrote {args.output}; run it with: {PROG} run {args.output}")
    return EXIT_OK


# ---------------------------------------------------------------------------------------------
# query, info (result files; the parsing, rendering and describing live in results/)
# ---------------------------------------------------------------------------------------------
_QUERY_FORMATS = ("table", "csv", "json", "netcdf")


def _query_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", metavar="OUT.nc", help="a result file written by 'run'")
    s = p.add_argument_group("selection (all clauses are ANDed)")
    s.add_argument("--sel", action="append", default=[], metavar="NAME=VALUE",
                   help="one value of a coordinate, e.g. L=10 (repeatable); it must be a grid "
                   "value (10 significant digits suffice; an off-grid value names the nearest)")
    s.add_argument("--nearest", action="store_true",
                   help="let --sel take the nearest grid value (and say so on stderr)")
    s.add_argument("--range", action="append", default=[], metavar="NAME=LO:HI",
                   help="inclusive range of a coordinate, LO or HI may be empty, e.g. eps=:0.01")
    s.add_argument("--where", action="append", default=[], metavar="'NAME OP VALUE'",
                   help="OP one of == != < <= > >= on a variable or coordinate; status by name, "
                   "e.g. 'Delta > 2', 'status == ok' (repeatable)")
    o = p.add_argument_group("output")
    o.add_argument("--vars", metavar="a,b", help="variables to report (default: all scalar ones)")
    o.add_argument("--format", choices=_QUERY_FORMATS, default="table",
                   help="rows as table (default), csv or json, or a NetCDF subset (needs -o)")
    o.add_argument("-o", "--output", metavar="FILE",
                   help="write to FILE (atomically) instead of stdout")


@register("query", "select and filter the points of a result file", _query_arguments)
def _query(args: argparse.Namespace) -> int:
    if args.format == "netcdf" and args.output is None:
        raise CliError("--format netcdf writes a file: give -o FILE")
    if args.output is not None:
        check_output_path(args.output, "-o")
        check_not_input(args.output, [args.results], "-o")
    from ..results import light, render, selection

    def select(ds):
        try:
            sel = [selection.parse_sel(t, ds) for t in args.sel]
            ranges = [selection.parse_range(t, ds) for t in args.range]
            where = [selection.parse_where(t, ds) for t in args.where]
            variables = selection.parse_vars(args.vars, ds)
            clauses = [f"--sel {t}" for t in args.sel] + [f"--range {t}" for t in args.range]
            clauses += [f"--where '{c.text}'" for c in where]
            return selection.select(ds, sel, ranges, where, variables, " ".join(clauses),
                                nearest=args.nearest)
        except ParameterError as exc:
            ds.close()
            raise CliError(str(exc)) from None

    # A slice or a curve of a result file is read with netCDF4 alone (importing xarray and dask
    # takes longer than such a query); a larger box, a NetCDF subset or a file that needs
    # xarray's decoding is read through xarray and dask, in chunks.
    ds = light.open_light(args.results) if args.format != "netcdf" else None
    picked = None if ds is None else select(ds)
    if picked is None or math.prod(picked.ds.sizes.values()) > selection.ROW_BLOCK:
        if ds is not None:
            ds.close()
        ds = open_results(args.results)
        picked = select(ds)
    try:
        for name, asked, taken in picked.snapped:
            _note(f"--nearest: --sel {name}={asked:.10g} is not a grid value; took the nearest, "
                  f"{name}={taken:.10g}")
        try:
            if picked.count() == 0:  # reads the file: inside the read-failure handling
                _note("the selection is empty: no point matches")
            if args.format == "netcdf":
                render.write_netcdf(picked, args.output)
            elif args.output is not None:
                writer = {"table": lambda f: f.write(render.format_table(picked)),
                          "csv": lambda f: render.write_csv(picked, f),
                          "json": lambda f: render.write_json(picked, f)}[args.format]
                render.write_text(args.output, writer)
            else:
                sys.stdout.write(render.render(picked, args.format))
        except (OSError, RuntimeError) as exc:
            raise _read_or_write_failure(exc, args.results, ds, args.output) from None
    finally:
        ds.close()
    return EXIT_OK


def _info_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", metavar="OUT.nc", help="a result file written by 'run'")


@register("info", "describe a result file: dimensions, variables, status counts, provenance",
          _info_arguments)
def _info(args: argparse.Namespace) -> int:
    from ..results import describe
    ds = open_results(args.results)
    try:
        try:
            text = describe.describe(ds, args.results)
        except (OSError, RuntimeError) as exc:
            raise _read_or_write_failure(exc, args.results, ds, None) from None
        sys.stdout.write(text)
    finally:
        ds.close()
    return EXIT_OK
