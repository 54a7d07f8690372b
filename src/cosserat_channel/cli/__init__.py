"""The ``cosserat-channel`` command line.

Each subcommand is one entry in :data:`~.common.COMMANDS`: a function that adds its arguments
to its parser and a function that runs it and returns the exit code. Add a subcommand with
:func:`~.common.register` in a module listed in :data:`COMMAND_MODULES`; :func:`main` needs no
change. This module holds the parser and :func:`main`; what the commands share (the registry,
the error and progress lines, the point and material arguments, the checks of outputs and
inputs) is :mod:`.common`'s, with public names. The commands live by theme in ``_point``
(point, phase-plane), ``_sweeps`` (run, query, info), ``_regimes`` (boundary, plot),
``_atlas`` (atlas), ``_reports`` (stability, bench), ``_paper`` (paper), ``_fit`` (fit) and
``_explore`` (explore).

Layer: the top one. May import every package; nothing imports it. The computing packages are
imported inside the commands, so that ``--help`` and a refused input never load the kernels.

Exit codes: 0 for an answer (a point without solution is an answer: its status says why), 1 for
a failure after the input was accepted (e.g. the plot file could not be written), 2 for input
the program rejects (argparse errors, parameters outside the model's domain), 130 (143) when
Ctrl-C (SIGTERM) stops a long command, which keeps what it finished (:func:`~.common.interrupted`). Every
error is one line on stderr, ``cosserat-channel: error: <message>``, never a traceback.
"""

from __future__ import annotations

import argparse
import gc
import os
import re
import sys

from . import _point, _sweeps, _regimes, _atlas, _reports, _paper, _fit, _explore
from .common import (COMMANDS, EXIT_FAILURE, EXIT_USAGE, PROG, CliError, error, interruptible,
                     interrupted)

# The commands register themselves on import (common.register); --help lists them in this order.
COMMAND_MODULES = (_point, _sweeps, _regimes, _atlas, _reports, _paper, _fit, _explore)

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
            # The parameters' flags differ from others in case alone (--l is --L, not --rtol).
            close = [k for k in known if k.lower() == flag.lower()] or \
                difflib.get_close_matches(flag, known, n=1, cutoff=0.6)
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
        with interruptible(term=False):  # Ctrl-C while Numba loads a kernel: see interruptible
            code = args._run(args)
        sys.stdout.flush()  # a reader gone (``| head -1``) shows here, not at the interpreter's exit
        return code
    except _ParserExit as exc:
        return exc.code
    except CliError as exc:
        error(str(exc))
        return exc.code
    except BrokenPipeError:
        _stdout_to_devnull()
        error("standard output was closed before everything was printed (broken pipe)")
        return EXIT_FAILURE
    except KeyboardInterrupt as exc:  # a command that keeps no partial work says so itself
        return interrupted(exc, "stopped before the command finished (its files are written "
                           "whole or not at all)")


def console() -> None:
    """The ``cosserat-channel`` command (and ``python -m cosserat_channel.cli``): :func:`main` on
    the process's arguments, its code the exit status."""
    code = main()
    # What is alive now lives until the process ends: the collector's passes over it at the
    # interpreter's exit (numba's, LLVM's and the libraries' objects, a third of a second after
    # every command that loaded the kernels) are skipped. Exit handlers run and objects are
    # released as always; what only the collector would free (reference cycles) is left to the
    # end of the process.
    gc.freeze()
    sys.exit(code)


def _stdout_to_devnull() -> None:
    """Point standard output at /dev/null, so that the interpreter's last flush of what is still
    buffered does not fail again (a second BrokenPipeError, printed at exit)."""
    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, sys.stdout.fileno())
        os.close(fd)
    except (OSError, ValueError):  # no file descriptor (an in-memory stream): nothing to do
        pass

