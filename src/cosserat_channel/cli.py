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

PROG = "cosserat-channel"
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
    parser = _Parser(prog=PROG, description=__doc__.splitlines()[0], allow_abbrev=False)
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


# ---------------------------------------------------------------------------------------------
# Shared argument groups and checks
# ---------------------------------------------------------------------------------------------
# Numbers are parsed with float() only: nan and inf must reach solve.check_point, whose message
# names the parameter and its range (one message for the API and the command line).
_POINT_ARGS = (
    ("--eps", "eps", "d_p/W, particle diameter over channel half-width, in (0, 1]"),
    ("--L", "L", "Cosserat length in particle diameters, > 0"),
    ("--K", "K", "wall roughness (u = eps K omega at the wall), >= 0"),
    ("--A", "A", "yield-surface constant a2/a1"),
    ("--N", "N", "sin(phi)/tan(delta), > 0"),
)
_MATERIAL_ARGS = (
    ("--d-p", "d_p", "particle diameter d_p in m"),
    ("--rho-p", "rho_p", "particle density rho_p in kg/m^3"),
    ("--phi", "phi", "angle of internal friction phi in degrees"),
)


def add_point_arguments(p: argparse.ArgumentParser) -> None:
    """``--eps --L --K --A --N`` (required) and ``--rtol --atol``."""
    g = p.add_argument_group("point (eps, L, K, A, N)")
    for flag, dest, text in _POINT_ARGS:
        g.add_argument(flag, dest=dest, type=float, required=True, metavar=dest.upper(), help=text)
    t = p.add_argument_group("tolerances")
    t.add_argument("--rtol", type=float,
                   help="relative tolerance of both integrations, in [1e-13, 1) "
                   "(default: solve_point's)")
    t.add_argument("--atol", type=float, help="absolute tolerance, > 0 (default: solve_point's)")


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
    directory = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise CliError(f"{option}: cannot write {path!r}: it is a directory")
    if not os.path.isdir(directory):
        raise CliError(f"{option}: cannot write {path!r}: directory {directory!r} does not exist")
    if not os.access(directory, os.W_OK | os.X_OK):
        raise CliError(f"{option}: cannot write {path!r}: directory {directory!r} is not writable")


# ---------------------------------------------------------------------------------------------
# point
# ---------------------------------------------------------------------------------------------
# Outputs of PointResult in table order: (field, unit, description).
_MATERIAL_UNITS = {"d_p": "m", "rho_p": "kg/m^3", "phi": "deg"}


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
        result = solve.solve_point(
            args.eps, args.L, args.K, args.A, args.N,
            material=material, profile=profile, **tolerances,
        )
    except solve.ParameterError as exc:
        raise CliError(str(exc)) from None

    if args.json:
        # allow_nan=False: to_dict maps NaN to null, and the output must stay strict JSON.
        print(json.dumps(result.to_dict(), allow_nan=False))
    else:
        tol = {"rtol": tolerances.get("rtol", solve.DEFAULT_RTOL),
               "atol": tolerances.get("atol", solve.DEFAULT_ATOL)}
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
    from .solve import OUTPUTS

    lines = ["parameters"]
    for _, dest, text in _POINT_ARGS:
        lines.append(_row(dest, getattr(result, dest), "-", text.split(",")[0]))
    for k, v in tolerances.items():
        text = "relative tolerance" if k == "rtol" else "absolute tolerance"
        lines.append(_row(k, float(v), "-", text))
    if material is not None:
        for _, dest, text in _MATERIAL_ARGS:
            unit = _MATERIAL_UNITS[dest]
            lines.append(_row(dest, float(material[dest]), unit, text.rsplit(" in ", 1)[0]))
    lines.append(f"status  {result.status.name}: {result.status.message}")
    outputs = [
        _row(name, float(getattr(result, name)), unit, text)
        for name, (unit, text) in OUTPUTS.items()
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
                   help="nearest value of a coordinate, e.g. L=10 (repeatable)")
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
    from . import query
    from .solve import ParameterError

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
            selection = query.select(ds, sel, ranges, where, variables, " ".join(clauses))
        except ParameterError as exc:
            raise CliError(str(exc)) from None
        if selection.count() == 0:
            _note("the selection is empty: no point matches")
        try:
            if args.format == "netcdf":
                query.write_netcdf(selection, args.output)
            elif args.output is not None:
                writer = {"table": lambda f: f.write(query.format_table(selection)),
                          "csv": lambda f: query.write_csv(selection, f),
                          "json": lambda f: query.write_json(selection, f)}[args.format]
                query.write_text(args.output, writer)
            else:
                sys.stdout.write(query.render(selection, args.format))
        except OSError as exc:
            raise CliError(f"-o: cannot write {args.output!r}: {exc}", EXIT_FAILURE) from None
    finally:
        ds.close()
    return EXIT_OK


def _info_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", metavar="OUT.nc", help="a result file written by 'run'")


@register("info", "describe a result file: dimensions, variables, status counts, provenance",
          _info_arguments)
def _info(args: argparse.Namespace) -> int:
    from . import query
    from .solve import ParameterError

    try:
        ds = query.open_results(args.results)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    try:
        sys.stdout.write(query.describe(ds, args.results))
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
    output = args.output or spec.output_path
    if output is None:
        output = os.path.splitext(os.path.basename(args.sweep))[0] + ".nc"
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
        raise CliError(f"cannot write {output!r}: {exc}", EXIT_FAILURE) from None
    except KeyboardInterrupt:
        _error(f"interrupted; finished blocks are kept in {output}.partial/, run the same "
               "command again to resume")
        return 130
    finally:
        logger.removeHandler(handler)
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
