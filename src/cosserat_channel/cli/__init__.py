"""The ``cosserat-channel`` command line.

Each subcommand is one entry in :data:`COMMANDS`: a function that adds its arguments to its
parser and a function that runs it and returns the exit code. Add a subcommand with
:func:`register`; :func:`main` needs no change. This module holds what the commands share (the
parser, the error and progress lines, the point and material arguments, the output checks); the
commands live by theme in ``_point`` (point, phase-plane), ``_sweeps`` (run, query, info),
``_regimes`` (boundary, plot), ``_atlas`` (atlas) and ``_reports`` (stability, bench).

Exit codes: 0 for an answer (a point without solution is an answer: its status says why), 1 for
a failure after the input was accepted (e.g. the plot file could not be written), 2 for input
the program rejects (argparse errors, parameters outside the model's domain). Every error is one
line on stderr, ``cosserat-channel: error: <message>``, never a traceback.

Heavy modules (numba through :mod:`.solve`, matplotlib through :mod:`.plot`) are imported inside
the commands, so ``--help`` and argument errors answer at once. Nothing imports this module.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass
from typing import Callable

from ..parameters import (  # noqa: F401 (ParameterError: for the commands)
    DIMS,
    MATERIAL,
    MATERIAL_REQUIRED,
    PARAMETERS,
    TOLERANCES,
    ParameterError,
)

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
    from .. import __version__

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


HEARTBEAT = 60.0  # seconds between Progress's lines when stderr is not a terminal


class Progress:
    """A live status line on stderr while a command works.

    ``with Progress("boundary") as p: ... p.update("3/8 edges")`` redraws
    ``cosserat-channel: boundary: 3/8 edges (0:12)`` in place, with the elapsed time ticking
    every half second; the line is cleared at the end. Nothing is drawn before ``delay``
    seconds, so a command that finishes quickly shows nothing. With stderr redirected (a file,
    a pipe, a batch job's log) the same text is printed as a line of its own every
    ``heartbeat`` seconds instead (none in a command shorter than that), so that a long run's
    log shows it is alive. :meth:`line` prints a permanent line above it.
    """

    def __init__(self, what: str, text: str = "", delay: float = 0.0, stream=None,
                 heartbeat: float = HEARTBEAT):
        import threading

        self.stream = stream or sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.what, self.text, self.delay, self.heartbeat = what, text, delay, heartbeat
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._tick, daemon=True)
        self._drawn = False

    def __enter__(self):
        import time

        self._t0 = time.monotonic()
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
        if self.enabled:
            while not self._stop.wait(0.5):
                self._draw()
            return
        while not self._stop.wait(self.heartbeat):
            with self._lock:
                print(self._status(), file=self.stream, flush=True)

    def _status(self) -> str:
        import time

        minutes, seconds = divmod(int(time.monotonic() - self._t0), 60)
        return f"{PROG}: {self.what}: {self.text} ({minutes}:{seconds:02d})"

    def _draw(self) -> None:
        import shutil
        import time

        if not self.enabled or self._stop.is_set():
            return
        if time.monotonic() - self._t0 < self.delay:
            return
        text = self._status()
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
_POINT_ARGS = tuple((f"--{d}", d, f"{PARAMETERS[d].sentence}, in {PARAMETERS[d].interval}")
                    for d in DIMS)
_MATERIAL_ARGS = tuple(("--" + k.replace("_", "-"), k, MATERIAL[k].sentence) for k in MATERIAL_REQUIRED)


def add_point_arguments(p: argparse.ArgumentParser) -> None:
    """``--eps --L --K --A --N`` (required) and ``--rtol --atol``."""
    g = p.add_argument_group("point (eps, L, K, A, N)")
    for flag, dest, text in _POINT_ARGS:
        g.add_argument(flag, dest=dest, type=float, required=True, metavar=dest.upper(), help=text)
    t = p.add_argument_group("tolerances")
    for name, param in TOLERANCES.items():
        t.add_argument(f"--{name}", type=float,
                       help=f"{param.sentence} of both integrations, in {param.interval} "
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
    from ..files import output_problem

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



def open_results(path: str):
    """The result file at ``path``, opened lazily; a CliError (one line) when it cannot be."""
    from ..results import selection

    try:
        return selection.open_results(path)
    except ParameterError as exc:
        raise CliError(str(exc)) from None


def _read_or_write_failure(exc: BaseException, results: str, ds, output: str | None) -> CliError:
    """One line for an error met while reading ``results`` or writing ``output``.

    Both raise the same types (netCDF4 reports a damaged chunk and a full disk alike as
    ``RuntimeError: NetCDF: HDF error``), so the file is read through once more to tell them
    apart: a damaged result file says so, whatever the output.
    """
    from ..results import light, selection
    from ..files import WriteError

    if isinstance(ds, light.LightFile):  # read through in chunks, with dask
        with open_results(results) as chunked:
            problem = selection.read_problem(chunked)
    else:
        problem = selection.read_problem(ds)
    if problem:
        return CliError(f"{results}: {problem}", EXIT_FAILURE)
    if isinstance(exc, WriteError):
        return CliError(f"-o: {exc}", EXIT_FAILURE)
    if isinstance(exc, OSError):
        where = repr(output) if output is not None else "standard output"
        return CliError(f"cannot write {where}: {exc.strerror or exc}", EXIT_FAILURE)
    return CliError(f"{results}: cannot read: {' '.join(str(exc).split())}", EXIT_FAILURE)



def _figure_output(path: str, option: str = "-o") -> None:
    """Check a figure path before any work (writable directory, a format Agg can write)."""
    check_output_path(path, option)
    from .. import plot

    try:
        plot.figure_format(path)
    except ValueError as exc:
        raise CliError(f"{option}: {exc}") from None




# The commands register themselves on import; they come last because they import the pieces above.
from . import _point, _sweeps, _regimes, _atlas, _reports, _paper  # noqa: E402, F401, I001 (this order is --help's)

