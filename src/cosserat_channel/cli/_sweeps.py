"""The ``run``, ``query`` and ``info`` commands: sweeps and their result files."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import logging
import shlex
import sys

from ..parameters import ParameterError
from .common import (
    EXIT_FAILURE,
    EXIT_OK,
    FIRST_RUN,
    PROG,
    CliError,
    Progress,
    Terminated,
    add_overwrite_argument,
    check_not_input,
    check_output_path,
    error,
    interruptible,
    note,
    open_results,
    read_or_write_failure,
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
    p.add_argument("--no-workers-timeout", type=float, metavar="SECONDS",
                   help="with --scheduler: end the run (blocks kept) when the cluster has had no "
                   "worker for this long (default 120)")
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
    # SIGTERM (what batch schedulers and ``kill`` send) stops the run as SIGINT does: the blocks
    # in flight are stored and one line says what is kept.
    with interruptible():
        return _run_command(args)


def _run_command(args: argparse.Namespace) -> int:
    for flag, value in (("--workers", args.workers), ("--block-size", args.block_size)):
        if value is not None and value < 1:
            raise CliError(f"{flag} must be a positive integer; got {value}")
    if args.no_workers_timeout is not None and not 0 < args.no_workers_timeout < math.inf:
        raise CliError(f"--no-workers-timeout must be a positive number of seconds; got "
                       f"{args.no_workers_timeout:g}")

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
    from ..sweep.store import check_writable

    try:
        check_writable(output)  # before the kernels load; run_sweep checks again
    except SweepError as exc:
        raise CliError(f"-o: {exc}") from None
    if not args.overwrite and _finished_result_kept(output, spec):
        return EXIT_OK
    logger = logging.getLogger("cosserat_channel.sweep")
    handler = _LineHandler()
    handler.setFormatter(logging.Formatter(f"{PROG}: run: %(message)s"))
    from ..sweep.schedulers import SchedulerLost

    try:
        if args.scheduler is None:
            from ..sweep.block import warm_up

            # Here, not inside the run: on a terminal the minute a new version spends compiling
            # shows as such, before the run's own progress line starts.
            with Progress("run", "loading the solver " + FIRST_RUN, delay=2.0):
                warm_up()
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
        with _quiet_distributed(args.scheduler is not None), \
                Progress("run", "planning the blocks") as bar:
            handler.bar = bar  # the run's log lines print above the progress line
            run_sweep(spec, output, workers=args.workers, scheduler=args.scheduler,
                      reduce=args.reduce, block_size=args.block_size,
                      overwrite=args.overwrite, compress=args.compress,
                      no_workers_timeout=args.no_workers_timeout, progress=bar.report,
                      open_result=False)
    except SweepError as exc:
        raise CliError(str(exc)) from None
    except SchedulerLost as exc:
        from ..sweep.store import partial_dir

        raise CliError(f"{exc}; finished blocks are kept in {partial_dir(output)}/, rerun the same "
                       "command to resume", EXIT_FAILURE) from None
    except OSError as exc:
        from ..files import OutputAppeared, WriteError
        from ..sweep.store import partial_dir

        message = str(exc) if isinstance(exc, WriteError) else \
            f"cannot write {output!r}: {exc.strerror or exc}"
        if os.path.isdir(partial_dir(output)) and not isinstance(exc, OutputAppeared):
            message += (f"; finished blocks are kept in {partial_dir(output)}/, run the same "
                        "command again to resume")
        raise CliError(message, EXIT_FAILURE) from None
    except KeyboardInterrupt as exc:
        what, code = ("terminated (SIGTERM)", 143) if isinstance(exc, Terminated) else \
            ("interrupted", 130)
        error(f"{what}; finished blocks are kept in {output}.partial/, run the same "
              "command again to resume")
        return code
    finally:
        logger.removeHandler(handler)
    return EXIT_OK


class _LineHandler(logging.Handler):
    """Log records as lines on stderr, above the progress line while ``bar`` is set."""

    bar = None

    def emit(self, record: logging.LogRecord) -> None:
        text = self.format(record)
        if self.bar is not None:
            self.bar.line(text)
        else:
            print(text, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _quiet_distributed(active: bool):
    """Within: dask.distributed's client-side log lines off (a lost scheduler printed some thirty
    lines of tracebacks before the run's own line, which says what happened and what is kept)."""
    if not active:
        yield
        return
    import distributed  # noqa: F401 (its logging set-up runs on import: override it after)

    names = {"distributed", "tornado", "asyncio"} | {
        n for n in logging.Logger.manager.loggerDict if n.split(".")[0] in ("distributed", "tornado")}
    saved = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for n, level in saved.items():
            logging.getLogger(n).setLevel(level)


def _finished_result_kept(output: str, spec) -> bool:
    """True (and a note) if ``output`` is already this sweep's result; CliError if it is another
    file. An unfinished run (``OUT.nc.partial/`` beside it) is resumed, not refused.

    The solver's kernels are loaded only after this answer: a kept result costs nothing. It is
    a first look; :func:`..sweep.run_sweep` decides again once it holds the store's lock."""
    from ..sweep.engine import KEPT, finished_result
    from ..sweep.spec import SweepError
    from ..sweep.store import partial_dir

    if os.path.isdir(partial_dir(output)):
        return False
    try:
        kept = finished_result(output, spec)
    except SweepError as exc:
        raise CliError(str(exc)) from None
    if kept:
        note(KEPT.format(output=output))
    return kept


# ---------------------------------------------------------------------------------------------
# example (the sweep files that come with the package)
# ---------------------------------------------------------------------------------------------
def _example_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", metavar="NAME",
                   help="an example's name (without NAME: list them)")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="copy it to this file (default: print it); a sweep's copy writes "
                   "FILE's stem .nc where it is run")
    p.add_argument("--overwrite", action="store_true", help="replace an existing FILE")


@register("example", "list the example sweep files and fit measurements that come with the "
          "package, print or copy one", _example_arguments)
def _example(args: argparse.Namespace) -> int:
    from ..sweep.spec import example_copy, example_measurements, examples

    sweeps, measurements = examples(), example_measurements()
    if args.name is None:
        if args.output is not None:
            raise CliError("-o needs an example's NAME")
        shipped = {**sweeps, **measurements}
        width = max(map(len, shipped))
        for name, text in shipped.items():
            first = next((line.lstrip("# ").strip() for line in text.splitlines()
                          if line.startswith("#")), "")
            print(f"{name:<{width}}  {first}")
        return EXIT_OK
    name = args.name[:-5] if args.name.endswith(".toml") else args.name
    if name not in sweeps and name + ".csv" in measurements:
        name += ".csv"
    if name not in sweeps and name not in measurements:
        raise CliError(f"no example {args.name!r}; the examples are "
                       f"{', '.join([*sweeps, *measurements])}")
    text = sweeps.get(name) or measurements[name]
    if args.output is None:
        sys.stdout.write(text)
        return EXIT_OK
    check_output_path(args.output, "-o", overwrite=args.overwrite)
    if name in sweeps:
        text = example_copy(name, text, args.output)
        then = f"run it with: {PROG} run {shlex.quote(args.output)}"
    else:
        fit = next((line.split(":", 1)[1].strip() for line in text.splitlines()
                    if line.startswith("# Fit:")), f"{PROG} fit {name}")
        then = "fit it with: " + fit.replace(f" {name} ", f" {shlex.quote(args.output)} ", 1)
    from ..files import WriteError, atomic_output

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)

    try:
        atomic_output(args.output, write, replace=args.overwrite)
    except WriteError as exc:  # a file that appeared meanwhile is kept (OutputAppeared)
        raise CliError(f"-o: {exc}", EXIT_FAILURE) from None
    except OSError as exc:
        raise CliError(f"-o: cannot write {args.output!r}: {exc.strerror or exc}",
                       EXIT_FAILURE) from None
    note(f"wrote {args.output}; {then}")
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
    add_overwrite_argument(o, "FILE")


@register("query", "select and filter the points of a result file", _query_arguments)
def _query(args: argparse.Namespace) -> int:
    if args.format == "netcdf" and args.output is None:
        raise CliError("--format netcdf writes a file: give -o FILE")
    if args.output is not None:
        check_not_input(args.output, [args.results], "-o")
        check_output_path(args.output, "-o", overwrite=args.overwrite)
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
            note(f"--nearest: --sel {name}={asked:.10g} is not a grid value; took the nearest, "
                 f"{name}={taken:.10g}")
        try:
            if picked.count() == 0:  # reads the file: inside the read-failure handling
                note("the selection is empty: no point matches")
            if args.format == "netcdf":
                render.write_netcdf(picked, args.output, replace=args.overwrite)
            elif args.output is not None:
                writer = {"table": lambda f: f.write(render.format_table(picked)),
                          "csv": lambda f: render.write_csv(picked, f),
                          "json": lambda f: render.write_json(picked, f)}[args.format]
                from ..files import write_text

                write_text(args.output, writer, replace=args.overwrite)
            else:
                sys.stdout.write(render.render(picked, args.format))
        except BrokenPipeError:
            raise  # the reader left (| head): nothing to tell from the file (see main)
        except (OSError, RuntimeError) as exc:
            raise read_or_write_failure(exc, args.results, ds, args.output) from None
    finally:
        ds.close()
    return EXIT_OK


def _info_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", metavar="FILE.nc",
                   help="a file written by 'run' (or 'query --format netcdf'), 'boundary' or 'atlas'")
    p.add_argument("--check-all", action="store_true",
                   help="read every variable through to verify it (default: up to 1 GB of "
                   "values; the report names what was not read)")


def _atlas_problem(path) -> str | None:
    """What reading the atlas at ``path`` as the commands do finds wrong (one line), or None:
    its layout, its numbers, and for the shipped atlas the digest the package records
    (:func:`cosserat_channel.atlas.load_atlas`)."""
    from ..atlas import load_atlas

    try:
        load_atlas(path)
    except ParameterError as exc:
        return str(exc)
    return None


@register("info", "describe a file of the tool (result, boundary or atlas) and verify it: "
          "dimensions, variables, status counts, provenance", _info_arguments)
def _info(args: argparse.Namespace) -> int:
    from ..results import describe

    try:
        ds = describe.open_described(args.results)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    try:
        # What is described is read first: a damaged file is reported as such, not described.
        problem, skipped = describe.verify(ds, None if args.check_all else describe.CHECK_BYTES)
        if problem is None and describe.file_kind(ds) == "atlas":
            problem = _atlas_problem(args.results)
        if problem:
            raise CliError(f"{args.results}: {problem}", EXIT_FAILURE)
        try:
            text = describe.describe(ds, args.results, skipped)
        except (OSError, RuntimeError) as exc:
            raise read_or_write_failure(exc, args.results, ds, None) from None
        sys.stdout.write(text)
    finally:
        ds.close()
    return EXIT_OK
