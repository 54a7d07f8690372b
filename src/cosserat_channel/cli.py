"""The ``cosserat-channel`` command line.

Each subcommand is one entry in :data:`COMMANDS`: a function that adds its arguments to its
parser and a function that runs it and returns the exit code. Add a subcommand with
:func:`register`; :func:`main` needs no change.

Exit codes: 0 for an answer (a point without solution is an answer: its status says why), 1 for
a failure after the input was accepted (e.g. the plot file could not be written), 2 for input
the program rejects (argparse errors, parameters outside the model's domain). Every error is one
line on stderr, ``cosserat-channel: error: <message>``, never a traceback.

Heavy modules (numba through :mod:`.solve`, matplotlib through :mod:`.plot`) are imported inside
the commands, so ``--help`` and argument errors answer at once. Nothing imports this module.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import dataclass
from typing import Callable

from .parameters import DIMS, MATERIAL, MATERIAL_REQUIRED, PARAMETERS, TOLERANCES, ParameterError

PROG = "cosserat-channel"
DESCRIPTION = ("Solve the frictional Cosserat model of dense granular flow in a vertical channel "
               "(Mohan, Nott & Rao)\nfor one point or a sweep over (eps, L, K, A, N), and query "
               "and plot the results.")
EPILOG = f"""examples:
  {PROG} point --eps 0.0333333333 --L 10 --K 0.5 --A 0.333333333 --N 1
  {PROG} run sweeps/quickstart.toml -o demo/quickstart.nc
  {PROG} info demo/quickstart.nc
  {PROG} query demo/quickstart.nc --sel L=10 --where "status == ok" --vars Delta,slip
  {PROG} plot demo/quickstart.nc --x eps --y Delta --hue L --at K=0.5,A=0.3333333333,N=1 -o demo/delta.png

'{PROG} COMMAND --help' describes a command; README.md has the rest."""
EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2


class CliError(Exception):
    """An error reported as one line on stderr with the given exit code (no traceback)."""

    def __init__(self, message: str, code: int = EXIT_USAGE):
        super().__init__(message)
        self.code = code


class _ParserExit(Exception):
    """argparse finished on its own (``--help``, ``--version``) with this exit code."""

    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser that raises instead of printing usage and calling ``sys.exit``.

    argparse's own ``error`` prints the usage block too; the contract here is one line on stderr
    and ``main`` returning the code, which the tests (and callers embedding ``main``) rely on.
    """

    def error(self, message):
        raise CliError(message, EXIT_USAGE)

    def exit(self, status=0, message=None):
        if message:
            sys.stderr.write(message)
        raise _ParserExit(status)


# ---------------------------------------------------------------------------------------------
# Subcommand registry
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Command:
    """One subcommand: ``configure(parser)`` adds its arguments, ``run(args)`` returns the code."""

    name: str
    help: str
    configure: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


COMMANDS: dict[str, Command] = {}


def register(name: str, help: str, configure: Callable[[argparse.ArgumentParser], None]):
    """Decorator registering ``run(args) -> int`` as subcommand ``name``."""

    def decorate(run):
        if name in COMMANDS:
            raise RuntimeError(f"subcommand {name!r} registered twice")
        COMMANDS[name] = Command(name, help, configure, run)
        return run

    return decorate


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with one subparser per registered command."""
    from . import __version__

    # allow_abbrev=False: an abbreviation that works today breaks when a later option shares it.
    parser = _Parser(prog=PROG, description=DESCRIPTION, epilog=EPILOG, allow_abbrev=False,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for cmd in COMMANDS.values():
        p = sub.add_parser(cmd.name, help=cmd.help, description=cmd.help, allow_abbrev=False)
        cmd.configure(p)
        p.set_defaults(_run=cmd.run)
    return parser


def main(argv=None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    try:
        args = build_parser().parse_args(argv)
        return args._run(args)
    except _ParserExit as exc:
        return exc.code
    except CliError as exc:
        _error(str(exc))
        return exc.code


def _error(message: str) -> None:
    print(f"{PROG}: error: {' '.join(message.split())}", file=sys.stderr)


def _note(message: str) -> None:
    print(f"{PROG}: note: {' '.join(message.split())}", file=sys.stderr)


class Progress:
    """A live status line on stderr while a command works, only when stderr is a terminal.

    ``with Progress("boundary") as p: ... p.update("3/8 edges")`` redraws
    ``cosserat-channel: boundary: 3/8 edges (0:12)`` in place, with the elapsed time ticking
    every half second; the line is cleared at the end. Nothing is drawn before ``delay``
    seconds, so a command that finishes quickly shows nothing; with stderr redirected (a file,
    a pipe, a test) nothing is drawn at all. :meth:`line` prints a permanent line above it.
    """

    def __init__(self, what: str, text: str = "", delay: float = 0.0, stream=None):
        import threading

        self.stream = stream or sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.what, self.text, self.delay = what, text, delay
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._tick, daemon=True)
        self._drawn = False

    def __enter__(self):
        import time

        self._t0 = time.monotonic()
        if self.enabled:
            self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self._clear()
        return False

    def update(self, text: str) -> None:
        self.text = text
        self._draw()

    def line(self, message: str) -> None:
        """Print ``message`` as a line of its own (always, terminal or not)."""
        with self._lock:
            self._clear_locked()
            print(message, file=self.stream, flush=True)
        self._draw()

    def _tick(self) -> None:
        while not self._stop.wait(0.5):
            self._draw()

    def _draw(self) -> None:
        import shutil
        import time

        if not self.enabled or self._stop.is_set():
            return
        elapsed = time.monotonic() - self._t0
        if elapsed < self.delay:
            return
        minutes, seconds = divmod(int(elapsed), 60)
        text = f"{PROG}: {self.what}: {self.text} ({minutes}:{seconds:02d})"
        width = max(20, shutil.get_terminal_size().columns - 1)
        with self._lock:
            self.stream.write("\r\033[K" + text[:width])
            self.stream.flush()
            self._drawn = True

    def _clear(self) -> None:
        with self._lock:
            self._clear_locked()

    def _clear_locked(self) -> None:
        if self._drawn:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self._drawn = False


# The first use of the solver compiles it (about a minute; later runs load it from the cache).
_FIRST_RUN = "(the first run of a new version compiles the solver: about a minute)"
_SOLVING = "solving " + _FIRST_RUN


# ---------------------------------------------------------------------------------------------
# Shared argument groups and checks
# ---------------------------------------------------------------------------------------------
# Numbers are parsed with float() only: nan and inf must reach parameters.check_point, whose message
# names the parameter and its range (one message for the API and the command line).
_POINT_ARGS = tuple((f"--{d}", d, f"{PARAMETERS[d].long_name}, in {PARAMETERS[d].interval}")
                    for d in DIMS)
_MATERIAL_ARGS = tuple(("--" + k.replace("_", "-"), k, MATERIAL[k].long_name) for k in MATERIAL_REQUIRED)


def add_point_arguments(p: argparse.ArgumentParser) -> None:
    """``--eps --L --K --A --N`` (required) and ``--rtol --atol``."""
    g = p.add_argument_group("point (eps, L, K, A, N)")
    for flag, dest, text in _POINT_ARGS:
        g.add_argument(flag, dest=dest, type=float, required=True, metavar=dest.upper(), help=text)
    t = p.add_argument_group("tolerances")
    for name, param in TOLERANCES.items():
        t.add_argument(f"--{name}", type=float,
                       help=f"{param.long_name} of both integrations, in {param.interval} "
                       f"(default {param.default:g})")


def add_material_arguments(p: argparse.ArgumentParser) -> None:
    """``--d-p --rho-p --phi``: all three or none."""
    g = p.add_argument_group("material (all three or none; adds nu and wall stresses in Pa)")
    for flag, dest, text in _MATERIAL_ARGS:
        g.add_argument(flag, dest=dest, type=float, help=text)


def material_from_args(args: argparse.Namespace) -> dict | None:
    """The ``material`` mapping for :func:`solve.solve_point`, or None; CliError if partial."""
    given = {dest: getattr(args, dest) for _, dest, _ in _MATERIAL_ARGS}
    if all(v is None for v in given.values()):
        return None
    missing = [flag for flag, dest, _ in _MATERIAL_ARGS if given[dest] is None]
    if missing:
        raise CliError(
            "--d-p, --rho-p and --phi go together; missing " + ", ".join(missing)
        )
    return given


def tolerances_from_args(args: argparse.Namespace) -> dict:
    """``rtol``/``atol`` keyword arguments actually given (the solver keeps its own defaults)."""
    return {k: getattr(args, k) for k in ("rtol", "atol") if getattr(args, k) is not None}


def check_output_path(path: str, option: str) -> None:
    """Raise CliError unless a file can be created at ``path`` (checked before any work)."""
    from .files import output_problem

    problem = output_problem(path)
    if problem:
        raise CliError(f"{option}: {problem}")


def check_not_input(path: str, inputs, option: str) -> None:
    """Raise CliError if ``path`` is one of the command's input files (same file, any spelling).

    A command never writes over what it reads: ``query X.nc --format csv -o X.nc`` would replace
    the result by its own CSV.
    """
    for src in inputs:
        if src is None:
            continue
        same = os.path.realpath(path) == os.path.realpath(src)
        if not same and os.path.exists(path) and os.path.exists(src):
            same = os.path.samefile(path, src)
        if same:
            raise CliError(f"{option}: {path!r} is this command's input {src!r}; writing it would "
                           "destroy the input: give another file name")


# ---------------------------------------------------------------------------------------------
# point
# ---------------------------------------------------------------------------------------------
def _point_arguments(p: argparse.ArgumentParser) -> None:
    add_point_arguments(p)
    add_material_arguments(p)
    out = p.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    out.add_argument("--plot", metavar="FILE.png",
                     help="also plot the profiles against xi to FILE (PNG; written only if solved)")


@register("point", "solve one point (eps, L, K, A, N) and print its outputs", _point_arguments)
def _point(args: argparse.Namespace) -> int:
    material = material_from_args(args)
    tolerances = tolerances_from_args(args)
    if args.plot is not None:
        check_output_path(args.plot, "--plot")
        from . import plot

        try:
            plot.figure_format(args.plot)
        except ValueError as exc:
            raise CliError(f"--plot: {exc}") from None

    import numpy as np

    from . import solve

    profile = np.linspace(0.0, 1.0, 401) if args.plot is not None else None
    try:
        with Progress("point", _SOLVING, delay=2.0):
            result = solve.solve_point(
                args.eps, args.L, args.K, args.A, args.N,
                material=material, profile=profile, **tolerances,
            )
    except ParameterError as exc:
        raise CliError(str(exc)) from None

    if args.json:
        # allow_nan=False: to_dict maps NaN to null, and the output must stay strict JSON.
        print(json.dumps(result.to_dict(), allow_nan=False))
    else:
        tol = {k: tolerances.get(k, p.default) for k, p in TOLERANCES.items()}
        print(format_point_table(result, tol, material))

    if args.plot is not None:
        if not result.ok:
            _note(f"no profile to plot (status {result.status.name}); {args.plot} not written")
        else:
            try:
                plot.point_profiles(result, args.plot)
            except OSError as exc:
                raise CliError(f"--plot: cannot write {args.plot!r}: {exc}", EXIT_FAILURE) from None
    return EXIT_OK


def _row(name: str, value, unit: str = "", text: str = "") -> str:
    v = f"{value:.10g}" if isinstance(value, float) else str(value)
    return f"  {name:<17} {v:>18}  {unit:<19} {text}".rstrip()


def format_point_table(result, tolerances: dict, material: dict | None) -> str:
    """The human-readable report of one point: parameters, status, outputs, counters."""
    from .outputs import OUTPUTS

    lines = ["parameters"]
    for _, dest, text in _POINT_ARGS:
        lines.append(_row(dest, getattr(result, dest), "-", text.split(",")[0]))
    for k, v in tolerances.items():
        text = "relative tolerance" if k == "rtol" else "absolute tolerance"
        lines.append(_row(k, float(v), "-", text))
    if material is not None:
        for _, dest, text in _MATERIAL_ARGS:
            lines.append(_row(dest, float(material[dest]), MATERIAL[dest].units,
                              text.rsplit(" in ", 1)[0]))
    lines.append(f"status  {result.status.name}: {result.status.message}")
    outputs = [
        _row(name, float(getattr(result, name)), o.units, o.long_name)
        for name, o in OUTPUTS.items()
        if math.isfinite(getattr(result, name))
    ]
    if outputs:
        lines.append("outputs")
        lines.extend(outputs)
    lines.append("counters  " + " ".join(f"{k}={v}" for k, v in result.counters.items()))
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# query, info (result files; the parsing and formatting live in query.py)
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
    from . import query
    try:
        ds = query.open_results(args.results)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    try:
        try:
            sel = [query.parse_sel(t, ds) for t in args.sel]
            ranges = [query.parse_range(t, ds) for t in args.range]
            where = [query.parse_where(t, ds) for t in args.where]
            variables = query.parse_vars(args.vars, ds)
            clauses = [f"--sel {t}" for t in args.sel] + [f"--range {t}" for t in args.range]
            clauses += [f"--where '{c.text}'" for c in where]
            selection = query.select(ds, sel, ranges, where, variables, " ".join(clauses),
                                     nearest=args.nearest)
        except ParameterError as exc:
            raise CliError(str(exc)) from None
        for name, asked, taken in selection.snapped:
            _note(f"--nearest: --sel {name}={asked:.10g} is not a grid value; took the nearest, "
                  f"{name}={taken:.10g}")
        try:
            if selection.count() == 0:  # reads the file: inside the read-failure handling
                _note("the selection is empty: no point matches")
            if args.format == "netcdf":
                query.write_netcdf(selection, args.output)
            elif args.output is not None:
                writer = {"table": lambda f: f.write(query.format_table(selection)),
                          "csv": lambda f: query.write_csv(selection, f),
                          "json": lambda f: query.write_json(selection, f)}[args.format]
                query.write_text(args.output, writer)
            else:
                sys.stdout.write(query.render(selection, args.format))
        except (OSError, RuntimeError) as exc:
            raise _read_or_write_failure(exc, args.results, ds, args.output) from None
    finally:
        ds.close()
    return EXIT_OK


def _read_or_write_failure(exc: BaseException, results: str, ds, output: str | None) -> CliError:
    """One line for an error met while reading ``results`` or writing ``output``.

    Both raise the same types (netCDF4 reports a damaged chunk and a full disk alike as
    ``RuntimeError: NetCDF: HDF error``), so the file is read through once more to tell them
    apart: a damaged result file says so, whatever the output.
    """
    from . import query
    from .files import WriteError

    problem = query.read_problem(ds)
    if problem:
        return CliError(f"{results}: {problem}", EXIT_FAILURE)
    if isinstance(exc, WriteError):
        return CliError(f"-o: {exc}", EXIT_FAILURE)
    if isinstance(exc, OSError):
        where = repr(output) if output is not None else "standard output"
        return CliError(f"cannot write {where}: {exc.strerror or exc}", EXIT_FAILURE)
    return CliError(f"{results}: cannot read: {' '.join(str(exc).split())}", EXIT_FAILURE)


def _info_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", metavar="OUT.nc", help="a result file written by 'run'")


@register("info", "describe a result file: dimensions, variables, status counts, provenance",
          _info_arguments)
def _info(args: argparse.Namespace) -> int:
    from . import query
    try:
        ds = query.open_results(args.results)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    try:
        try:
            text = query.describe(ds, args.results)
        except (OSError, RuntimeError) as exc:
            raise _read_or_write_failure(exc, args.results, ds, None) from None
        sys.stdout.write(text)
    finally:
        ds.close()
    return EXIT_OK


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
                   help="run the blocks on this dask.distributed scheduler, e.g. tcp://host:8786")
    p.add_argument("--no-reduce", dest="reduce", action="store_false",
                   help="one integration per grid point instead of per distinct (eps L, A, N); "
                   "same values, for checks and benchmarks")
    p.add_argument("--block-size", type=int, metavar="B", help="integrations per block")
    p.add_argument("--overwrite", action="store_true",
                   help="compute again and replace OUT.nc if it is already a finished result "
                   "(without it a finished OUT.nc is kept)")


@register("run", "solve every point of a sweep file and write a NetCDF result", _run_arguments)
def _run(args: argparse.Namespace) -> int:
    for flag, value in (("--workers", args.workers), ("--block-size", args.block_size)):
        if value is not None and value < 1:
            raise CliError(f"{flag} must be a positive integer; got {value}")
    import logging

    from .sweep import run_sweep
    from .sweep.spec import SweepError, load_sweep

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
        from .sweep.engine import warm_up

        # Here, not inside the run: on a terminal the minute a new version spends compiling
        # shows as such, before the run's own progress bar starts.
        with Progress("run", "loading the solver " + _FIRST_RUN, delay=2.0):
            warm_up()
    logger = logging.getLogger("cosserat_channel.sweep")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"{PROG}: run: %(message)s"))
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        run_sweep(spec, output, workers=args.workers, scheduler=args.scheduler,
                  reduce=args.reduce, block_size=args.block_size)
    except SweepError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        from .files import WriteError
        from .sweep.store import partial_dir

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
    from .sweep.store import partial_dir

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
# stability (issue 4)
# ---------------------------------------------------------------------------------------------
def _stability_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output-dir", dest="output_dir", default="stability_report",
                   metavar="DIR", help="where stability.md and stability.png go "
                   "(default: stability_report/, created if missing)")
    p.add_argument("--quick", action="store_true",
                   help="a small version (one (A, N) series, few points, one timing repeat)")
    p.add_argument("--repeats", type=int, default=5, metavar="R",
                   help="timing repeats per point, the best is reported (default 5)")


@register("stability", "report steps, cost and error of one point from eps L = 1e-8 to the "
          "edge of solvability, and which stage-1 path each point took", _stability_arguments)
def _stability(args: argparse.Namespace) -> int:
    if args.repeats < 1:
        raise CliError(f"--repeats must be a positive integer; got {args.repeats}")
    from .measure.stability import directory_problem, write_report

    problem = directory_problem(args.output_dir)
    if problem:
        raise CliError(f"-o/--output-dir: {problem}")

    repeats = 1 if args.quick else args.repeats
    try:
        with Progress("stability", "finding the edges of the series") as bar:
            def progress(i, n, row):
                bar.update(f"{i}/{n} points; last: {row['case']} eta = {row['eta']:.3g}: "
                           f"{row['status']}, {row['path']} path")

            rep = write_report(args.output_dir, quick=args.quick, repeats=repeats,
                               progress=progress)
    except OSError as exc:
        raise CliError(f"cannot write the report into {args.output_dir!r}: {exc}",
                       EXIT_FAILURE) from None
    v = rep.verdict
    print(f"wrote {os.path.join(args.output_dir, 'stability.md')} and "
          f"{os.path.join(args.output_dir, 'stability.png')}; max error/rtol "
          f"{v['max_err_over_rtol']:.2f}, max steps {v['max_steps']}")
    return EXIT_OK


# ---------------------------------------------------------------------------------------------
# phase-plane, boundary, plot (data in regimes.py, figures in plot/regimes.py and plot/lines.py)
# ---------------------------------------------------------------------------------------------
def _figure_output(path: str, option: str = "-o") -> None:
    """Check a figure path before any work (writable directory, a format Agg can write)."""
    check_output_path(path, option)
    from . import plot

    try:
        plot.figure_format(path)
    except ValueError as exc:
        raise CliError(f"{option}: {exc}") from None


def _phase_plane_arguments(p: argparse.ArgumentParser) -> None:
    for flag, dest, text in _POINT_ARGS:
        if dest != "K":
            p.add_argument(flag, dest=dest, type=float, required=True, metavar=dest.upper(),
                           help=text)
    p.add_argument("--nu", type=float, help="solids fraction: plot m_bar = nu m as the paper "
                   "(figure 12: 0.603) instead of m_bar/nu")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="figure to write")


@register("phase-plane", "plot the phase plane of eq:a1/eq:a2 (paper figure 12) for any "
          "(eps, L, A, N)", _phase_plane_arguments)
def _phase_plane(args: argparse.Namespace) -> int:
    if args.nu is not None and not (0.0 < args.nu < 1.0):
        raise CliError(f"--nu must be in (0, 1); got {args.nu:g}")
    _figure_output(args.output)
    from . import regimes
    from .plot import regimes as plot_regimes
    try:
        with Progress("phase-plane", _SOLVING, delay=2.0):
            pp = regimes.phase_plane(args.eps, args.L, args.A, args.N)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    for tr in pp.trajectories:
        print(f"E{tr.root} from m(0) = {tr.start:+.6g}: {tr.end}"
              + (f" at xi = {tr.xi[-1]:.6g}" if tr.end == "D=0" else "")
              + (f", m(1)/nu = {tr.m[-1]:.10g}" if tr.end == "wall" else ""))
    try:
        plot_regimes.phase_plane_figure(pp, nu=args.nu, path=args.output)
    except OSError as exc:
        raise CliError(f"-o: cannot write {args.output!r}: {exc}", EXIT_FAILURE) from None
    return EXIT_OK


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
    p.add_argument("--eta-range", default="0.001:100", metavar="LO:HI",
                   help="searched range of eta = eps L (default 0.001:100: eps <= 1, L <= 100)")
    p.add_argument("--coarse", type=int, default=48, metavar="M",
                   help="log-spaced samples before bisection (default 48)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.nc", help="NetCDF file to write")
    p.add_argument("--plot", metavar="FILE.png", help="also plot eta_max against A, one line per N")
    p.add_argument("--overwrite", action="store_true",
                   help="trace again and replace OUT.nc if it exists (without it an OUT.nc "
                   "traced with the same arguments is reused, any other is kept)")


@register("boundary", "trace eta_max(A, N), the largest eps L with a solution, by bisection",
          _boundary_arguments)
def _boundary(args: argparse.Namespace) -> int:
    from .parameters import ETA_MAX, ETA_MIN

    A = parse_values(args.A, "--A")
    N = parse_values(args.N, "--N")
    if any(n <= 0.0 for n in N):
        raise CliError(f"--N: values must be > 0; got {args.N!r}")
    if len(A) * len(N) > MAX_BOUNDARY_PAIRS:
        raise CliError(f"--A, --N: {len(A) * len(N):,} (A, N) pairs is more than "
                       f"{MAX_BOUNDARY_PAIRS:,}; split the run")
    try:
        lo, hi = (float(v) for v in args.eta_range.split(":"))
    except ValueError:
        raise CliError(f"--eta-range: expected LO:HI; got {args.eta_range!r}") from None
    if not (0.0 < lo < hi < math.inf):
        raise CliError(f"--eta-range: need 0 < LO < HI < inf; got {args.eta_range!r}")
    if lo < ETA_MIN or hi > ETA_MAX:
        raise CliError(f"--eta-range: {args.eta_range!r} is not inside [{ETA_MIN:g}, "
                       f"{ETA_MAX:g}], the eps L the solver resolves")
    if not 2 <= args.coarse <= MAX_COARSE:
        raise CliError(f"--coarse must be in [2, {MAX_COARSE}]; got {args.coarse}")
    check_output_path(args.output, "-o")
    if args.plot is not None:
        _figure_output(args.plot, "--plot")
        check_not_input(args.plot, [args.output], "--plot")
    from . import regimes
    from .status import Status

    ds = None if args.overwrite else _same_boundary(args.output, A, N, lo, hi, args.coarse)
    traced = ds is None
    if traced:
        with Progress("boundary", "tracing " + _FIRST_RUN, delay=1.0) as bar:
            ds = regimes.trace_boundary(A, N, eta_range=(lo, hi), n_coarse=args.coarse,
                                        progress=lambda k, n: bar.update(f"{k}/{n} edges traced"))
    print(f"{'A':>12} {'N':>10} {'eta_max':>18} {'kind':<20} {'status above'}")
    for i, a in enumerate(ds["A"].values):
        for j, n in enumerate(ds["N"].values):
            k = int(ds["edge_kind"].values[i, j])
            above = int(ds["status_above"].values[i, j])
            name = "-" if above < 0 else Status(above).name
            print(f"{a:12.6g} {n:10.6g} {ds['eta_max'].values[i, j]:18.12g} "
                  f"{regimes.EDGE_KINDS[k]:<20} {name}")
    from .files import netcdf_output

    try:
        # Checksums, as on sweep results: a damaged file fails to read instead of changing.
        if traced:
            enc = {v: {"fletcher32": True} for v in ds.variables
                   if ds[v].ndim > 0 and ds[v].dtype.kind in "fiub"}
            netcdf_output(args.output, lambda tmp: ds.to_netcdf(tmp, encoding=enc))
        if args.plot is not None:
            from .plot import regimes as plot_regimes

            plot_regimes.boundary_figure(ds, path=args.plot)
    except OSError as exc:
        from .files import WriteError

        raise CliError(str(exc) if isinstance(exc, WriteError) else f"cannot write: {exc}",
                       EXIT_FAILURE) from None
    return EXIT_OK


def _same_boundary(path, A, N, lo, hi, coarse):
    """The Dataset in ``path`` if it was traced with these arguments (note: reused), None if there
    is no file; CliError if it is another file (kept unless --overwrite)."""
    if not os.path.exists(path):
        return None
    import numpy as np
    import xarray as xr

    try:
        ds = xr.load_dataset(path)
    except (OSError, ValueError, RuntimeError):
        ds = None
    if ds is not None and "eta_max" in ds:
        a = ds.attrs
        if (ds["A"].size == len(A) and ds["N"].size == len(N)
                and np.array_equal(ds["A"].values, A) and np.array_equal(ds["N"].values, N)
                and (a.get("eta_search_min"), a.get("eta_search_max"), a.get("n_coarse"))
                == (lo, hi, coarse)):
            _note(f"{path} was traced with these arguments; reused (add --overwrite to trace "
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
    p.add_argument("--no-asymptote", dest="asymptote", action="store_false",
                   help="do not overlay the Appendix C asymptotics (N = 1)")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="figure to write")


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
            out[name.strip()] = float(value)
        except ValueError:
            raise CliError(f"--at: expected NAME=VALUE[,NAME=VALUE]; got {text!r}") from None
    return out


def _resolve_at(ds, args, at: dict) -> dict:
    """``--at`` values replaced by the grid values they match (exactly, or with --nearest the
    nearest, noted on stderr); CliError naming the dimensions still to fix, with an example."""
    from .parameters import DIMS as dims
    from .query import QueryError, match_coordinate

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
            _note(f"--nearest: --at {name}={value:.10g} is not a grid value; took the nearest, "
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


@register("plot", "plot a result file: regime map, Delta against a parameter, or profiles",
          _plot_arguments)
def _plot(args: argparse.Namespace) -> int:
    at = parse_at(args.at)
    if args.boundary is not None and not args.regime:
        raise CliError("--boundary goes with --regime")
    if args.regime and args.hue is not None:
        raise CliError("--hue does not go with --regime")
    _figure_output(args.output)
    check_not_input(args.output, [args.results, args.boundary], "-o")
    from . import query
    from .plot import lines as plot_lines
    from .plot import regimes as plot_regimes
    try:
        ds = query.open_results(args.results)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    try:
        # Read (and so checksum) first: a damaged file is reported as such, whatever else is wrong.
        try:
            ds = ds.load()
        except (OSError, RuntimeError) as exc:
            raise _read_or_write_failure(exc, args.results, ds, None) from None
        at = _resolve_at(ds, args, at)
        boundary = None
        if args.boundary is not None:
            import xarray as xr

            try:
                boundary = xr.load_dataset(args.boundary)
            except (OSError, ValueError) as exc:
                raise CliError(f"--boundary: cannot read {args.boundary!r}: {exc}") from None
            if "eta_max" not in boundary:
                raise CliError(f"--boundary: {args.boundary!r} is not a 'boundary' result")
        try:
            with Progress("plot", "drawing " + _FIRST_RUN * args.regime, delay=1.0) as bar:
                if args.regime:
                    if boundary is None:
                        # The figure only draws data: the traced edge is computed here, on the
                        # coarse (A, N) grid the map asks for.
                        grid = plot_regimes.regime_trace_grid(ds, args.x, args.y, at)
                        if grid is not None:
                            from . import regimes

                            def traced(k, n):
                                bar.update(f"tracing the edge eta_max: {k}/{n} (A, N) pairs")

                            boundary = regimes.trace_boundary(*grid, progress=traced)
                    plot_regimes.regime_map(ds, args.x, args.y, at, boundary=boundary,
                                            path=args.output)
                else:
                    plot_lines.line_plot(ds, args.x, args.y, args.hue, at,
                                         asymptote=args.asymptote, path=args.output)
        except (ValueError, KeyError) as exc:
            raise CliError(str(exc).strip("'\"")) from None
        except OSError as exc:
            raise CliError(f"-o: cannot write {args.output!r}: {exc}", EXIT_FAILURE) from None
    finally:
        ds.close()
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
                   "no verdict and the exit code is 0 (a full run exits 1 if a target is missed)")
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
    from .measure import workprecision

    try:
        with Progress("bench", "starting") as bar:
            def log(message):
                bar.line(f"{PROG}: bench: {message}")
                bar.update(f"running; last: {message}")

            rep = workprecision.run(output, quick=args.quick, scipy_points=args.scipy_points,
                                    command=command, log=log)
    except OSError as exc:
        raise CliError(f"cannot write the report into {output!r}: {exc}", EXIT_FAILURE) from None
    # An "(informative)" target is reported, not required.
    missed = [t for t in rep.targets if t.passed is False and "(informative)" not in t.text]
    for target in rep.targets:
        line = target.line().replace("**", "")
        print(("quick set, not a verdict: " if args.quick else "") + line)
    print("wrote " + ", ".join(str(p) for p in rep.paths.values()))
    if missed and not args.quick:
        _error(f"{len(missed)} required target(s) of the report missed (the FAIL lines above); "
               "the report is written")
        return EXIT_FAILURE
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
