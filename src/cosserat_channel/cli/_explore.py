"""The ``explore`` command: the interactive explorer (:mod:`cosserat_channel.explorer`) in a browser."""

from __future__ import annotations

import argparse
import os
import sys

from .common import EXIT_OK, CliError, interrupted, interruptible, register


def _explore_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", type=int, default=0,
                   help="port on 127.0.0.1 (default: a free one; the address is printed)")
    p.add_argument("--no-browser", action="store_true",
                   help="do not open a browser tab (a remote machine: tunnel the port with ssh -L)")
    p.add_argument("-o", "--output-dir", default=".", metavar="DIR",
                   help="where the page's export button writes its sweep file and figures "
                   "(default: the current directory; no file is ever replaced)")


@register("explore", "the parameter space in a browser: sliders for (eps, L, K, A, N), the "
          "point's status, profiles and outputs, the solvability map, one output against one "
          "parameter", _explore_arguments)
def _explore(args: argparse.Namespace) -> int:
    if not 0 <= args.port <= 65535:
        raise CliError(f"--port must be in [0, 65535]; got {args.port}")
    if not os.path.isdir(args.output_dir):
        raise CliError(f"-o/--output-dir: {args.output_dir!r} is not a directory")
    from ..explorer import serve

    try:
        with interruptible():
            serve(args.port, args.output_dir, open_browser=not args.no_browser)
    except OSError as exc:
        raise CliError(f"cannot serve on 127.0.0.1:{args.port}: {exc.strerror or exc}") from None
    except KeyboardInterrupt as exc:
        code = interrupted(exc, "the explorer stopped")
        # The process is the server and nothing else: end it now, without waiting for what its
        # workers still compute (the first run's compilation takes minutes).
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return EXIT_OK
