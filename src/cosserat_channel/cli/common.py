"""What the ``cosserat-channel`` commands share: the registry they add themselves to, the
exit codes and one-line errors, the progress line, the point and material arguments, and the
checks of outputs and inputs made before any work.

A command module imports what it needs from here and registers its ``run`` with
:func:`register`; :mod:`cosserat_channel.cli` builds the parser from :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from dataclasses import dataclass
from typing import Callable

from ..parameters import (
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
EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT: what a shell reports after Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM


class CliError(Exception):
    """An error reported as one line on stderr with the given exit code (no traceback)."""

    def __init__(self, message: str, code: int = EXIT_USAGE):
        super().__init__(message)
        self.code = code


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


def error(message: str) -> None:
    """``cosserat-channel: error: <message>`` on stderr, on one line."""
    print(f"{PROG}: error: {one_line(message)}", file=sys.stderr)


def note(message: str) -> None:
    """``cosserat-channel: note: <message>`` on stderr, on one line."""
    print(f"{PROG}: note: {one_line(message)}", file=sys.stderr)


def one_line(message: str) -> str:
    """``message`` on one line, with what a terminal would obey (a file's names and attributes
    quoted in it) escaped."""
    from ..results.flags import printable

    return printable(" ".join(str(message).split()))


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread where Ctrl-C raises KeyboardInterrupt (see
    :func:`interruptible`)."""


def _inside_llvm(frame) -> bool:
    """Whether ``frame`` or a caller of it is llvmlite's Python code, which LLVM calls back from
    C while Numba loads or compiles a kernel: an exception raised there is lost in the callback
    and leaves LLVM with a buffer it never got, and the process dies of SIGSEGV."""
    while frame is not None:
        if frame.f_globals.get("__name__", "").startswith("llvmlite"):
            return True
        frame = frame.f_back
    return False


@contextlib.contextmanager
def interruptible(term: bool = True):
    """Inside, SIGTERM raises :class:`Terminated` (with ``term``), so that one ``except
    KeyboardInterrupt`` keeps what is finished after Ctrl-C and after a ``kill`` alike;
    :func:`interrupted` reports it.

    A signal that arrives while LLVM runs llvmlite's callbacks is raised again 50 ms later, until
    the main thread is out of them (see :func:`_inside_llvm`)."""
    import os
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(stop):
        def stopped(signum, frame):
            if _inside_llvm(frame):
                again = threading.Timer(0.05, os.kill, (os.getpid(), signum))
                again.daemon = True
                again.start()
                return
            raise stop

        return stopped

    handled = {signal.SIGTERM: handler(Terminated)} if term else {}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        handled[signal.SIGINT] = handler(KeyboardInterrupt)
    previous = {signum: signal.signal(signum, h) for signum, h in handled.items()}
    try:
        yield
    finally:
        for signum, h in previous.items():
            signal.signal(signum, h)


def interrupted(exc: KeyboardInterrupt, kept: str) -> int:
    """One line, ``interrupted; <kept>`` (``terminated`` after SIGTERM); the exit code, 130 or 143."""
    term = isinstance(exc, Terminated)
    error(f"{'terminated' if term else 'interrupted'}; {kept}")
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
FIRST_RUN = "(the first run of a new version compiles the solver: about a minute)"
SOLVING = "solving " + FIRST_RUN


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


POINT_ARGS = tuple((f"--{d}", d, f"{PARAMETERS[d].sentence}, in {PARAMETERS[d].interval}")
                    for d in DIMS)
MATERIAL_ARGS = tuple(("--" + k.replace("_", "-"), k, MATERIAL[k].sentence) for k in MATERIAL_REQUIRED)
# The material's optional inputs (gravity, the closure's constants), each with its default.
CLOSURE_ARGS = tuple(("--" + k.replace("_", "-"), k, f"{MATERIAL[k].sentence} (default {MATERIAL[k].default:g})")
                     for k in MATERIAL if k not in MATERIAL_REQUIRED)
# The engineers' inputs that give eps and N (parameters.eps_from_width, N_from_friction): the
# flag, its destination, the parameter it gives and the material input it needs.
PHYSICAL_ARGS = (("--W", "W", "eps", "d_p"), ("--delta-w", "delta_w", "N", "phi"))


def add_point_arguments(p: argparse.ArgumentParser) -> None:
    """``--eps --L --K --A --N`` (eps or --W, N or --delta-w) and ``--rtol --atol``."""
    g = p.add_argument_group("point (eps, L, K, A, N; numbers or exact fractions such as 1/30)")
    alternative = {gives: flag for flag, _, gives, _ in PHYSICAL_ARGS}
    for flag, dest, text in POINT_ARGS:
        other = alternative.get(dest)
        g.add_argument(flag, dest=dest, type=number, required=other is None,
                       metavar=dest.upper(), help=text + (f" (or {other})" if other else ""))
    e = p.add_argument_group("engineering inputs (instead of --eps, --N; the point's report "
                             "gives the eps and N they make)")
    for flag, dest, gives, needs in PHYSICAL_ARGS:
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
    for flag, dest, gives, needs in PHYSICAL_ARGS:
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
    for flag, dest, text in MATERIAL_ARGS:
        g.add_argument(flag, dest=dest, type=number, help=text)
    g = p.add_argument_group("gravity and the closure's constants (with the material)")
    for flag, dest, text in CLOSURE_ARGS:
        g.add_argument(flag, dest=dest, type=number, help=text)


def material_from_args(args: argparse.Namespace) -> dict | None:
    """The ``material`` mapping for :func:`~cosserat_channel.solver.point.solve_point`, or None; CliError if partial.

    ``--d-p`` given for ``--W`` only, or ``--phi`` for ``--delta-w`` only, is no material.
    """
    given = {dest: getattr(args, dest) for _, dest, _ in MATERIAL_ARGS}
    closure = {dest: getattr(args, dest) for _, dest, _ in CLOSURE_ARGS
               if getattr(args, dest, None) is not None}
    consumed = {needs for _, dest, _, needs in PHYSICAL_ARGS if getattr(args, dest, None)
                is not None}
    if all(v is None for k, v in given.items() if k not in consumed):
        if closure:
            flags = ", ".join(f for f, dest, _ in CLOSURE_ARGS if dest in closure)
            raise CliError(f"{flags}: only with a material (--d-p, --rho-p and --phi)")
        return None
    missing = [flag for flag, dest, _ in MATERIAL_ARGS if given[dest] is None]
    if missing:
        raise CliError(
            "--d-p, --rho-p and --phi go together; missing " + ", ".join(missing)
        )
    return {**given, **closure}


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


def read_or_write_failure(exc: BaseException, results: str, ds, output: str | None) -> CliError:
    """One line for an error met while reading ``results`` or writing ``output``.

    Both raise the same types (netCDF4 reports a damaged chunk and a full disk alike as
    ``RuntimeError: NetCDF: HDF error``), so the file is read through once more to tell them
    apart: a damaged result file says so, whatever the output.
    """
    from ..results import damage, light, selection
    from ..files import WriteError

    if isinstance(exc, damage.DamagedFile):  # found in what was read: no second reading
        return CliError(f"{results}: {exc}", EXIT_FAILURE)
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


def publish_figure(fig, path: str, option: str = "-o", *, overwrite: bool) -> None:
    """Write a figure the user named (checked before the work by :func:`figure_output`): over
    an existing file only with ``overwrite``; a file that appeared meanwhile is kept and the
    figure put beside it, one line (:class:`..files.OutputAppeared`), exit 1."""
    from .. import plot
    from ..files import WriteError

    try:
        plot.save_figure(fig, path, replace=overwrite)
    except WriteError as exc:
        raise CliError(f"{option}: {exc}", EXIT_FAILURE) from None
    except OSError as exc:
        raise CliError(f"{option}: cannot write {path!r}: {exc.strerror or exc}",
                       EXIT_FAILURE) from None


def figure_output(path: str, option: str = "-o", *, overwrite: bool) -> None:
    """Check a figure path before any work (:func:`check_output_path`, a format Agg can write)."""
    check_output_path(path, option, overwrite=overwrite)
    from .. import plot

    try:
        plot.figure_format(path)
    except ValueError as exc:
        raise CliError(f"{option}: {exc}") from None
