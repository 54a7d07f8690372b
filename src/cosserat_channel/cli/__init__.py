"""The ``cosserat-channel`` command line.

Each subcommand is one entry in :data:`COMMANDS`: a function that adds its arguments to its
parser and a function that runs it and returns the exit code. Add a subcommand with
:func:`register`; :func:`main` needs no change. This module holds what the commands share (the
parser, the error and progress lines, the point and material arguments, the output checks); the
commands live by theme in ``_point`` (point, phase-plane), ``_sweeps`` (run, query, info),
``_regimes`` (boundary, plot), ``_atlas`` (atlas), ``_reports`` (stability, bench) and
``_paper`` (paper).

Layer: the top one. May import every package; nothing imports it. The computing packages are
imported inside the commands, so that ``--help`` and a refused input never load the kernels.

Exit codes: 0 for an answer (a point without solution is an answer: its status says why), 1 for
a failure after the input was accepted (e.g. the plot file could not be written), 2 for input
the program rejects (argparse errors, parameters outside the model's domain), 130 (143) when
Ctrl-C (SIGTERM) stops a long command, which keeps what it finished (:func:`interrupted`). Every
error is one line on stderr, ``cosserat-channel: error: <message>``, never a traceback.

Heavy modules (numba through :mod:`.solve`, matplotlib through :mod:`.plot`) are imported inside
the commands, so ``--help`` and argument errors answer at once. Nothing imports this module.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
from dataclasses import dataclass
from typing import Callable

from ..parameters import (  # noqa: F401 (ParameterError: for the commands)
    DIMS,
    MATERIAL,
    MATERIAL_REQUIRED,
    PARAMETERS,
    PHYSICAL,
    TOLERANCES,
    ParameterError,
    N_from_friction,
    eps_from_width,
    parse_number,
)
from ..regime_codes import ETA_SEARCH_MAX, ETA_SEARCH_MIN

PROG = "cosserat-channel"
# The eta range that boundary and atlas search by default, as their --eta-range option reads it.
ETA_RANGE = f"{ETA_SEARCH_MIN:g}:{ETA_SEARCH_MAX:g}"
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
    An option this parser does not know is named first, with the closest known spelling
    (``--esp``: did you mean ``--eps``?), since argparse would report the required option it
    then misses instead.
    """

    def parse_known_args(self, args=None, namespace=None):
        self._given = list(sys.argv[1:] if args is None else args)
        namespace, extras = super().parse_known_args(args, namespace)
        if any(word.startswith("--") for word in extras):
            self.error("unrecognized arguments: " + " ".join(extras))  # named by this parser
        return namespace, extras

    def error(self, message):
        typo = self._unknown_option()
        raise CliError(typo or message + _negative_value_hint(message, getattr(self, "_given", ())),
                       EXIT_USAGE)

    def _unknown_option(self) -> str | None:
        import difflib

        known = [s for s in self._option_string_actions if s.startswith("--")]
        for word in getattr(self, "_given", ()):
            if word == "--":
                break
            flag = word.split("=", 1)[0]
            if not flag.startswith("--") or flag in self._option_string_actions:
                continue
            close = difflib.get_close_matches(flag, known, n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]}?" if close else f"; see '{self.prog} --help'"
            return f"unrecognized option {flag}{hint}"
        return None

    def exit(self, status=0, message=None):
        if message:
            sys.stderr.write(message)
        raise _ParserExit(status)


def _negative_value_hint(message: str, argv) -> str:
    """What to type when argparse took a negative number for an option (``--A -1e3``).

    argparse reads ``-1e3`` (and ``-inf``, ``-.5e-3``) as an option, since only plain negative
    integers and decimals look like numbers to it; ``--A=-1e3`` reaches the option whole.
    """
    m = re.match(r"argument (\S+): expected one argument", message)
    if not m:
        return ""
    flags = m.group(1).split("/")
    for flag, value in zip(argv, argv[1:]):
        if flag in flags and value.startswith("-"):
            try:
                float(value)
            except ValueError:
                continue
            return f" (a negative value goes after '=': {flag}={value})"
    return ""


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


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The top-level parser with one subparser per registered command.

    With ``command`` (a registered name) only that subparser gets its arguments: the others
    are listed but not configured, since some configurations import what their help text
    quotes (the atlas's defaults, the fit's quantities).
    """
    from .. import __version__

    # allow_abbrev=False: an abbreviation that works today breaks when a later option shares it.
    parser = _Parser(prog=PROG, description=DESCRIPTION, epilog=EPILOG, allow_abbrev=False,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for cmd in COMMANDS.values():
        p = sub.add_parser(cmd.name, help=cmd.help, description=cmd.help, allow_abbrev=False)
        if command not in COMMANDS or command == cmd.name:
            cmd.configure(p)
        p.set_defaults(_run=cmd.run)
    return parser


def main(argv=None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    if argv is None:
        argv = sys.argv[1:]
    # The top level takes no option with a value: the first word that is not an option names
    # the command.
    command = next((a for a in argv if not a.startswith("-")), None)
    try:
        args = build_parser(command).parse_args(argv)
        code = args._run(args)
        sys.stdout.flush()  # a reader gone (``| head -1``) shows here, not at the interpreter's exit
        return code
    except _ParserExit as exc:
        return exc.code
    except CliError as exc:
        _error(str(exc))
        return exc.code
    except BrokenPipeError:
        _stdout_to_devnull()
        _error("standard output was closed before everything was printed (broken pipe)")
        return EXIT_FAILURE
    except KeyboardInterrupt as exc:  # a command that keeps no partial work says so itself
        return interrupted(exc, "stopped before the command finished (its files are written "
                           "whole or not at all)")


def _stdout_to_devnull() -> None:
    """Point standard output at /dev/null, so that the interpreter's last flush of what is still
    buffered does not fail again (a second BrokenPipeError, printed at exit)."""
    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, sys.stdout.fileno())
        os.close(fd)
    except (OSError, ValueError):  # no file descriptor (an in-memory stream): nothing to do
        pass


def _error(message: str) -> None:
    print(f"{PROG}: error: {_one_line(message)}", file=sys.stderr)


def _note(message: str) -> None:
    print(f"{PROG}: note: {_one_line(message)}", file=sys.stderr)


def _one_line(message: str) -> str:
    """``message`` on one line, with what a terminal would obey (a file's names and attributes
    quoted in it) escaped."""
    from ..results.flags import printable

    return printable(" ".join(str(message).split()))


EXIT_INTERRUPTED = 130  # 128 + SIGINT: what a shell reports after Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread where Ctrl-C raises KeyboardInterrupt (see
    :func:`interruptible`)."""


@contextlib.contextmanager
def interruptible():
    """Inside, SIGTERM raises :class:`Terminated`, so that one ``except KeyboardInterrupt`` keeps
    what is finished after Ctrl-C and after a ``kill`` alike; :func:`interrupted` reports it."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupted(exc: KeyboardInterrupt, kept: str) -> int:
    """One line, ``interrupted; <kept>`` (``terminated`` after SIGTERM); the exit code, 130 or 143."""
    term = isinstance(exc, Terminated)
    _error(f"{'terminated' if term else 'interrupted'}; {kept}")
    return EXIT_TERMINATED if term else EXIT_INTERRUPTED


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

    def report(self, done: int, total: int | None, text: str = "") -> None:
        """The package's one progress protocol, ``progress(done, total, text)``, as the line
        ``done/total text`` (``done text`` where the total is not known yet)."""
        count = f"{done}/{total}" if total is not None else f"{done}"
        self.update(f"{count} {text}".rstrip())

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
def number(text: str) -> float:
    """argparse type of every numeric input: a float or an exact fraction (``--eps 1/30``).

    nan and inf pass: they must reach the parameter checks, whose message names the parameter
    and its range (one message for the API and the command line).
    """
    try:
        return parse_number(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or a fraction a/b; got {text!r}") \
            from None


_POINT_ARGS = tuple((f"--{d}", d, f"{PARAMETERS[d].sentence}, in {PARAMETERS[d].interval}")
                    for d in DIMS)
_MATERIAL_ARGS = tuple(("--" + k.replace("_", "-"), k, MATERIAL[k].sentence) for k in MATERIAL_REQUIRED)
# The engineers' inputs that give eps and N (parameters.eps_from_width, N_from_friction): the
# flag, its destination, the parameter it gives and the material input it needs.
_PHYSICAL_ARGS = (("--W", "W", "eps", "d_p"), ("--delta-w", "delta_w", "N", "phi"))



def add_point_arguments(p: argparse.ArgumentParser) -> None:
    """``--eps --L --K --A --N`` (eps or --W, N or --delta-w) and ``--rtol --atol``."""
    g = p.add_argument_group("point (eps, L, K, A, N; numbers or exact fractions such as 1/30)")
    alternative = {gives: flag for flag, _, gives, _ in _PHYSICAL_ARGS}
    for flag, dest, text in _POINT_ARGS:
        other = alternative.get(dest)
        g.add_argument(flag, dest=dest, type=number, required=other is None,
                       metavar=dest.upper(), help=text + (f" (or {other})" if other else ""))
    e = p.add_argument_group("engineering inputs (instead of --eps, --N; the point's report "
                             "gives the eps and N they make)")
    for flag, dest, gives, needs in _PHYSICAL_ARGS:
        param = PHYSICAL[dest]
        how = {"eps": "eps = d_p/W", "N": "N = sin(phi)/tan(delta_w)"}[gives]
        e.add_argument(flag, dest=dest, type=number, metavar=param.units.upper()[:3],
                       help=f"{param.long_name}, in {param.interval}, with --"
                       f"{needs.replace('_', '-')}: {how}")
    t = p.add_argument_group("tolerances")
    for name, param in TOLERANCES.items():
        t.add_argument(f"--{name}", type=number,
                       help=f"{param.sentence} of both integrations, in {param.interval} "

                       f"(default {param.default:g})")


def point_from_args(args: argparse.Namespace) -> dict:
    """Set ``args.eps`` and ``args.N`` from ``--W``/``--delta-w`` where given; returns the
    engineers' inputs used (``{"W": ..., "d_p": ...}``, empty without them). CliError when a
    parameter is given both ways or neither, or its material input is missing; ParameterError
    (one line) when a value or what it makes is out of range."""
    used = {}
    for flag, dest, gives, needs in _PHYSICAL_ARGS:
        value, direct = getattr(args, dest), getattr(args, gives)
        needs_flag = "--" + needs.replace("_", "-")
        if value is None:
            if direct is None:
                raise CliError(f"give --{gives}, or {flag} with {needs_flag}")
            continue
        if direct is not None:
            raise CliError(f"--{gives} and {flag} both give {gives}: give one")
        if getattr(args, needs) is None:
            raise CliError(f"{flag} needs {needs_flag} ({MATERIAL[needs].long_name})")
        convert = eps_from_width if gives == "eps" else N_from_friction
        setattr(args, gives, convert(getattr(args, needs), value))
        used.update({dest: value, needs: getattr(args, needs)})
    return used


def add_material_arguments(p: argparse.ArgumentParser) -> None:
    """``--d-p --rho-p --phi``: all three or none (d_p with --W, phi with --delta-w alone)."""
    g = p.add_argument_group("material (all three or none; adds nu and wall stresses in Pa)")
    for flag, dest, text in _MATERIAL_ARGS:
        g.add_argument(flag, dest=dest, type=number, help=text)


def material_from_args(args: argparse.Namespace) -> dict | None:
    """The ``material`` mapping for :func:`solve.solve_point`, or None; CliError if partial.

    ``--d-p`` given for ``--W`` only, or ``--phi`` for ``--delta-w`` only, is no material.
    """
    given = {dest: getattr(args, dest) for _, dest, _ in _MATERIAL_ARGS}
    consumed = {needs for _, dest, _, needs in _PHYSICAL_ARGS if getattr(args, dest, None)
                is not None}
    if all(v is None for k, v in given.items() if k not in consumed):
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


def add_overwrite_argument(p: argparse.ArgumentParser, what: str = "the output") -> None:
    """``--overwrite``: without it no command replaces a file that exists."""
    p.add_argument("--overwrite", action="store_true",
                   help=f"replace {what} if it exists (without it an existing file is kept)")


def check_output_path(path: str, option: str, *, overwrite: bool, stream: bool = True) -> None:
    """Raise CliError unless a file can be written at ``path`` (checked before any work; see
    :func:`files.output_problem`); a file already there is kept unless ``overwrite``."""
    from ..files import output_problem

    problem = output_problem(path, stream=stream, overwrite=overwrite)
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
        # One reader of the file at a time: HDF5 re-reading a damaged file through a second
        # handle while the first is open once ended in SIGBUS.
        ds.close()
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



def _figure_output(path: str, option: str = "-o", *, overwrite: bool) -> None:
    """Check a figure path before any work (:func:`check_output_path`, a format Agg can write)."""
    check_output_path(path, option, overwrite=overwrite)
    from .. import plot

    try:
        plot.figure_format(path)
    except ValueError as exc:
        raise CliError(f"{option}: {exc}") from None




# The commands register themselves on import; they come last because they import the pieces above.
from . import _point, _sweeps, _regimes, _atlas, _reports, _paper, _fit  # noqa: E402, F401, I001 (this order is --help's)

