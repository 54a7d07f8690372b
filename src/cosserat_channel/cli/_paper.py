"""The ``paper`` command: the paper's figures 2-12, table 1 and Appendix A beside ours."""

from __future__ import annotations

import argparse
import os

from .common import (
    EXIT_FAILURE,
    EXIT_OK,
    FIRST_RUN,
    CliError,
    Progress,
    interrupted,
    interruptible,
    register,
)


def _paper_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="directory for <figure>.png and comparison.md (created if missing; its "
                   "parent must exist)")
    p.add_argument("--coarse", action="store_true",
                   help="small grids: a quick look (about ten seconds once compiled)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the files of an earlier run in DIR (without it they are kept)")


@register("paper", "draw the paper's figures 2-12, table 1 and Appendix A's eps = 0.33 with the "
          "paper's numbers beside ours (PNG files and comparison.md)", _paper_arguments)
def _paper(args: argparse.Namespace) -> int:
    from .. import paper

    written = []
    try:
        with interruptible(), Progress("paper", "solving " + FIRST_RUN, delay=1.0) as bar:
            paths = paper.write_paper_figures(args.output, coarse=args.coarse,
                                              overwrite=args.overwrite,
                                              progress=bar.report, written=written)
    except KeyboardInterrupt as exc:
        names = ", ".join(os.path.basename(p) for p in written)
        return interrupted(exc, f"{names} finished and kept in {args.output} (comparison.md "
                           "is written after the last figure)" if written else
                           "no figure was finished")
    except ValueError as exc:  # the output directory or its files: checked before any work
        raise CliError(f"-o: {exc}") from None
    except OSError as exc:
        raise CliError(f"-o: cannot write: {exc}", EXIT_FAILURE) from None
    print("\n".join(paths))
    return EXIT_OK
