"""The ``point`` and ``phase-plane`` commands: one point of the model."""

from __future__ import annotations

import argparse
import json
import math

from ..parameters import MATERIAL, ParameterError, TOLERANCES
from .common import (
    EXIT_OK,
    CLOSURE_ARGS,
    MATERIAL_ARGS,
    POINT_ARGS,
    SOLVING,
    CliError,
    Progress,
    add_material_arguments,
    add_overwrite_argument,
    add_point_arguments,
    figure_output,
    publish_figure,
    material_from_args,
    note,
    number,
    point_from_args,
    register,
    tolerances_from_args,
)

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
    add_overwrite_argument(out, "FILE.png")


@register("point", "solve one point (eps, L, K, A, N) and print its outputs", _point_arguments)
def _point(args: argparse.Namespace) -> int:
    try:
        inputs = point_from_args(args)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    material = material_from_args(args)
    tolerances = tolerances_from_args(args)
    if args.plot is not None:
        figure_output(args.plot, "--plot", overwrite=args.overwrite)
        from .. import plot

    import numpy as np

    from ..solver.point import solve_point

    profile = np.linspace(0.0, 1.0, 401) if args.plot is not None else None
    try:
        with Progress("point", SOLVING, delay=2.0):
            result = solve_point(
                args.eps, args.L, args.K, args.A, args.N,
                material=material, profile=profile, **tolerances,
            )
    except ParameterError as exc:
        raise CliError(str(exc)) from None

    # The figure first: a reader that leaves early (| head) loses no file.
    if args.plot is not None:
        if not result.ok:
            note(f"no profile to plot (status {result.status.name}); {args.plot} not written")
        else:
            publish_figure(plot.point_profiles(result), args.plot, "--plot",
                           overwrite=args.overwrite)
    if args.json:
        # allow_nan=False: to_dict maps NaN to null, and the output must stay strict JSON.
        data = result.to_dict()
        if inputs:
            data["inputs"] = inputs  # the engineers' inputs that eps and N came from
        print(json.dumps(data, allow_nan=False))
    else:
        tol = {k: tolerances.get(k, p.default) for k, p in TOLERANCES.items()}
        print(format_point_table(result, tol, material, inputs))
    return EXIT_OK


def _row(name: str, value, unit: str = "", text: str = "") -> str:
    v = f"{value:.10g}" if isinstance(value, float) else str(value)
    return f"  {name:<17} {v:>18}  {unit:<19} {text}".rstrip()


def format_point_table(result, tolerances: dict, material: dict | None,
                       inputs: dict | None = None) -> str:
    """The human-readable report of one point: parameters, status, outputs, counters.

    ``inputs``: the engineers' inputs eps and N came from (:func:`point_from_args`), listed
    first, with eps and N marked as derived from them.
    """
    from ..outputs import OUTPUTS
    from ..parameters import PHYSICAL

    inputs = inputs or {}
    lines = ["parameters"]
    for name, value in inputs.items():
        if material is not None and name in material:
            continue  # listed with the material below
        param = PHYSICAL.get(name) or MATERIAL[name]
        lines.append(_row(name, float(value), param.units, param.long_name.split(" in ")[0]))
    derived = {"eps": "(from W and d_p)" if "W" in inputs else "",
               "N": "(from delta_w and phi)" if "delta_w" in inputs else ""}
    for _, dest, text in POINT_ARGS:
        how = derived.get(dest, "")
        lines.append(_row(dest, getattr(result, dest), "-",
                          text.split(",")[0] + (f" {how}" if how else "")))
    for k, v in tolerances.items():
        text = "relative tolerance" if k == "rtol" else "absolute tolerance"
        lines.append(_row(k, float(v), "-", text))
    if material is not None:
        for _, dest, _ in MATERIAL_ARGS + CLOSURE_ARGS:
            if dest not in material:
                continue
            lines.append(_row(dest, float(material[dest]), MATERIAL[dest].units,
                              MATERIAL[dest].sentence.rsplit(" in ", 1)[0]))
    lines.append(f"status  {result.status.name}: {result.status.message}")
    outputs = [
        _row(name, float(getattr(result, name)), o.units, o.sentence)
        for name, o in OUTPUTS.items()
        if math.isfinite(getattr(result, name))
    ]
    if outputs:
        lines.append("outputs")
        lines.extend(outputs)
    lines.append("counters  " + " ".join(f"{k}={v}" for k, v in result.counters.items()))
    return "\n".join(lines)



def _phase_plane_arguments(p: argparse.ArgumentParser) -> None:
    for flag, dest, text in POINT_ARGS:
        if dest != "K":
            p.add_argument(flag, dest=dest, type=number, required=True, metavar=dest.upper(),
                           help=text)
    p.add_argument("--nu", type=number, help="solids fraction: plot m_bar = nu m as the paper "
                   "(figure 12: 0.603) instead of m_bar/nu")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="figure to write")
    add_overwrite_argument(p, "FILE.png")


@register("phase-plane", "plot the phase plane of eq:a1/eq:a2 (paper figure 12) for any "
          "(eps, L, A, N)", _phase_plane_arguments)
def _phase_plane(args: argparse.Namespace) -> int:
    if args.nu is not None and not (0.0 < args.nu < 1.0):
        raise CliError(f"--nu must be in (0, 1); got {args.nu:g}")
    figure_output(args.output, overwrite=args.overwrite)
    from .. import regimes
    from ..plot import regimes as plot_regimes
    try:
        with Progress("phase-plane", SOLVING, delay=2.0):
            pp = regimes.phase_plane(args.eps, args.L, args.A, args.N)
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    for tr in pp.trajectories:
        print(f"E{tr.root} from m(0) = {tr.start:+.6g}: {tr.end}"
              + (f" at xi = {tr.xi[-1]:.6g}" if tr.end == "D=0" else "")
              + (f", m(1)/nu = {tr.m[-1]:.10g}" if tr.end == "wall" else ""))
    publish_figure(plot_regimes.phase_plane_figure(pp, nu=args.nu), args.output,
                   overwrite=args.overwrite)
    return EXIT_OK
