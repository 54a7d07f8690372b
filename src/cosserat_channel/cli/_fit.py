"""The ``fit`` command: calibrate the model's inputs against a CSV of measurements."""

from __future__ import annotations

import argparse
import sys

from ..parameters import ParameterError, TOLERANCES, parse_number
from .common import (
    EXIT_FAILURE,
    EXIT_OK,
    PROG,
    SOLVING,
    CliError,
    Progress,
    add_overwrite_argument,
    check_not_input,
    check_output_path,
    figure_output,
    publish_figure,
    number,
    one_line,
    register,
)

_EPILOG = """\
DATA.csv has a header line and one measurement per line (lines starting with # are comments):
  quantity   an output (%(outputs)s)
             or a profile (%(profiles)s) at the row's xi
  value      the measured value (in the output's units: scaled, or Pa for the *_Pa outputs)
  std_error  its standard error (> 0)
  xi         where a profile is measured, in [0, 1] (empty for the other rows)
  inputs     any that vary by row: %(inputs)s
             (W with d_p gives eps = d_p/W, delta_w with phi gives N = sin(phi)/tan(delta_w));
             an empty cell takes the --fixed or free value
example:
%(example)s
  %(prog)s fit DATA.csv --free L,K --fixed A=1/3,N=1 --bounds L=1:100 -o fit.json --plot fit.png
"""


def _fit_arguments(p: argparse.ArgumentParser) -> None:
    import textwrap

    from ..calibrate.data import CSV_EXAMPLE, INPUTS, profile_quantities, quantities

    def wrapped(names, indent):
        return textwrap.fill(", ".join(names), 90, initial_indent=" " * 35,
                             subsequent_indent=" " * indent).lstrip()

    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = _EPILOG % {
        "outputs": wrapped(quantities(), 13), "profiles": wrapped(profile_quantities(), 13),
        "inputs": wrapped(INPUTS, 13), "prog": PROG,
        "example": "\n".join("  " + line for line in CSV_EXAMPLE.splitlines())}
    p.add_argument("data", metavar="DATA.csv", help="the measurements (format below)")
    p.add_argument("--free", required=True, metavar="NAMES",
                   help="the inputs to fit, comma-separated (e.g. L,K; also A, N, phi, delta_w, "
                   "Lambda ...)")
    p.add_argument("--fixed", action="append", default=[], metavar="NAME=VALUE,...",
                   help="values of the inputs no row gives, e.g. A=1/3,N=1 (a row's own cell "
                   "wins)")
    p.add_argument("--bounds", action="append", default=[], metavar="NAME=LO:HI,...",
                   help="bounds of free inputs, e.g. L=1:100 (default: the input's range)")
    p.add_argument("--start", action="append", default=[], metavar="NAME=VALUE,...",
                   help="where the search starts (default: L=10, K=0.5, A=1/3, N=1, eps=1/30, "
                   "or the input's default)")
    p.add_argument("--rtol", type=number, help="relative tolerance of the solves, in "
                   f"{TOLERANCES['rtol'].interval} (default 1e-10)")
    p.add_argument("--atol", type=number, help="absolute tolerance of the solves, in "
                   f"{TOLERANCES['atol'].interval} (default {TOLERANCES['atol'].default:g})")
    out = p.add_argument_group("output")
    out.add_argument("--json", action="store_true",
                     help="print the result as one JSON object instead of a table")
    out.add_argument("-o", "--output", metavar="OUT.json", help="also write the result as JSON")
    out.add_argument("--plot", metavar="FILE.png", help="draw the residual figure to FILE")
    add_overwrite_argument(out, "OUT.json and FILE.png")


def _pairs(items, option: str, split_range: bool = False) -> dict:
    """``["A=1/3,N=1"]`` -> ``{"A": 1/3, "N": 1.0}`` (``L=1:100`` -> ``(1.0, 100.0)``)."""
    out = {}
    for item in items:
        for part in filter(None, (s.strip() for s in item.split(","))):
            name, sep, value = part.partition("=")
            if not sep or not name.strip():
                raise CliError(f"{option}: expected NAME={'LO:HI' if split_range else 'VALUE'}; "
                               f"got {part!r}")
            try:
                if split_range:
                    lo, colon, hi = value.partition(":")
                    if not colon:
                        raise ValueError(f"expected LO:HI; got {value!r}")
                    parsed = (parse_number(lo), parse_number(hi))
                else:
                    parsed = parse_number(value)
            except ValueError as exc:
                raise CliError(f"{option} {name.strip()}: {exc}") from None
            out[name.strip()] = parsed
    return out


@register("fit", "calibrate: fit the model's inputs (L, K, A, N, phi, ...) to measurements in a "
          "CSV by weighted least squares", _fit_arguments)
def _fit(args: argparse.Namespace) -> int:
    fixed = _pairs(args.fixed, "--fixed")
    bounds = _pairs(args.bounds, "--bounds", split_range=True)
    start = _pairs(args.start, "--start")
    for path, option in ((args.output, "-o"), (args.plot, "--plot")):
        if path is not None:
            check_not_input(path, [args.data], option)
    if args.output is not None:
        check_output_path(args.output, "-o", overwrite=args.overwrite)
    if args.plot is not None:
        figure_output(args.plot, "--plot", overwrite=args.overwrite)
    if args.output is not None and args.output == args.plot:
        raise CliError("-o and --plot name the same file: give two")
    import warnings

    from ..calibrate import estimate as fit_
    from ..calibrate.data import read_data

    tolerances = {k: getattr(args, k) for k in ("rtol", "atol") if getattr(args, k) is not None}
    try:
        data = read_data(args.data)
        with Progress("fit", SOLVING, delay=2.0), warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always", fit_.FitWarning)
            result = fit_.fit(data, args.free, fixed, bounds, start, **tolerances)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    for w in seen:
        if issubclass(w.category, fit_.FitWarning):
            print(f"{PROG}: warning: {one_line(str(w.message))}", file=sys.stderr)
    if args.plot is not None:
        publish_figure(result.plot(), args.plot, "--plot", overwrite=args.overwrite)
    if args.output is not None:
        from ..files import OutputAppeared, write_text

        def write(f):
            # piece by piece: a million rows' JSON is never one string nor one dict
            f.writelines(result.json_chunks())
            f.write("\n")

        try:
            write_text(args.output, write, replace=args.overwrite)
        except OutputAppeared as exc:
            raise CliError(f"-o: {exc}", EXIT_FAILURE) from None
        except OSError as exc:
            raise CliError(f"-o: cannot write {args.output!r}: {exc.strerror or exc}",
                           EXIT_FAILURE) from None
    if args.json:
        sys.stdout.writelines(result.json_chunks())
        sys.stdout.write("\n")
    else:
        print(result.summary())
    return EXIT_OK
