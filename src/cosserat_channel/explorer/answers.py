"""What the explorer's page asks, answered by the library's public functions; no HTTP here.

The page sends its inputs as typed text (``{"eps": "1/30", "L": "10", ...}``); :func:`read_inputs`
turns them into a point, its material and tolerance, or one line naming the first bad input.
:func:`point` answers with :func:`cosserat_channel.solve_point` (status, outputs,
sensitivities, profiles), :func:`solvability_map` with the atlas's
:func:`~cosserat_channel.atlas.classify` over the ``(A, N)`` plane at the point's ``eps L``,
:func:`line` with :func:`cosserat_channel.solve` over one parameter's range, and :func:`export`
writes the current view as a sweep file and figures drawn by :mod:`cosserat_channel.plot`.
Every answer is a JSON-ready dict. Nothing here computes physics of its own.
"""

from __future__ import annotations

import math
import os
import threading

import numpy as np

from .. import outputs as out_
from .. import status as st
from ..parameters import (DEFAULT_RTOL, DIMS, MATERIAL, MATERIAL_REQUIRED, PARAMETERS, PHYSICAL,
                          TOLERANCES, ParameterError, N_from_friction, check_material, check_point,
                          check_tolerances, eps_from_width, parse_number)

# Points of the profiles (xi in [0, 1]) and of a line over one parameter.
PROFILE_POINTS = 201
LINE_POINTS = 81
# The (A, N) plane the map shows: the shipped whole-plane atlas's box, MAP_A x MAP_N pixels.
MAP_A = 150
MAP_N = 110

# The sliders: each parameter's range on the page (a typed value may lie outside), whether its
# slider moves in log10, and the default point (the paper's figure 2). A line over a parameter
# spans its slider's range.
SLIDERS = {
    "eps": {"lo": 1e-4, "hi": 1.0, "log": True, "default": "1/30"},
    "L": {"lo": 0.1, "hi": 1000.0, "log": True, "default": "10"},
    "K": {"lo": 0.0, "hi": 20.0, "log": False, "default": "0.5"},
    "A": {"lo": -1.0, "hi": 5.0, "log": False, "default": "1/3"},
    "N": {"lo": 0.3, "hi": 3.0, "log": False, "default": "1"},
    "W": {"lo": 1e-3, "hi": 10.0, "log": True, "default": "0.06"},
    "delta_w": {"lo": 1.0, "hi": 89.0, "log": False, "default": "25"},
}
MATERIAL_DEFAULTS = {"d_p": "0.002", "rho_p": "2940", "phi": "25"}  # the paper's figure 2
# eps from W with d_p, N from delta_w with phi (parameters.eps_from_width, N_from_friction).
ALTERNATIVES = {"eps": ("W", "d_p", eps_from_width), "N": ("delta_w", "phi", N_from_friction)}


_ATLAS_LOCK = threading.Lock()


def default_atlas():
    """:func:`cosserat_channel.atlas.default_atlas`, one thread at a time: HDF5, which reads the
    atlas file the first time, crashes the process when two threads open a file at once."""
    from .. import atlas

    with _ATLAS_LOCK:
        return atlas.default_atlas()


def meta() -> dict:
    """What the page is built from: the parameters, outputs, statuses, sliders and defaults."""
    atlas = default_atlas()[0]
    box = list(atlas.box) if atlas is not None else [SLIDERS["A"]["lo"], SLIDERS["A"]["hi"],
                                                      SLIDERS["N"]["lo"], SLIDERS["N"]["hi"]]
    quantity = {**PARAMETERS, **PHYSICAL, **MATERIAL, **TOLERANCES}

    def describe(name):
        q = quantity[name]
        return {"name": name, "sentence": q.sentence, "interval": q.interval, "units": q.units}

    return {
        "parameters": [describe(d) for d in DIMS],
        "alternatives": {k: describe(v[0]) | {"needs": v[1]} for k, v in ALTERNATIVES.items()},
        "material": [describe(k) for k in MATERIAL_REQUIRED],
        "material_defaults": MATERIAL_DEFAULTS,
        "rtol": describe("rtol") | {"default": DEFAULT_RTOL},
        "sliders": SLIDERS,
        "outputs": [{"name": o.name, "units": o.units, "long_name": o.long_name,
                     "material": o.material, "description": o.sentence}
                    for o in out_.OUTPUTS.values()],
        "profiles": {k: {"long_name": q.long_name, "description": q.sentence}
                     for k, q in out_.PROFILES.items()},
        "statuses": [{"code": int(s), "name": s.name, "color": s.color, "message": s.message}
                     for s in st.Status],
        "undecided": {"code": -1, "color": "#d9d9d9",
                      "message": "undecided by the atlas (within its error of an edge): a solve "
                                 "decides"},
        "map_box": box,
    }


def _number(name: str, text) -> float:
    """One typed value as a float; ParameterError naming the input when it is not a number."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text)
    if not isinstance(text, str) or not text.strip():
        raise ParameterError(f"{name}: give a number")
    try:
        return parse_number(text)
    except ValueError:
        raise ParameterError(f"{name}: expected a number or a fraction a/b; got {text!r}") from None


def read_inputs(form: dict) -> dict:
    """The page's inputs as ``{"point": (eps, L, K, A, N), "material", "rtol", "given"}``.

    ``form`` holds typed text by input name: ``eps`` (or ``W`` with ``d_p`` when ``form["eps_from"]
    == "W"``), ``L``, ``K``, ``A``, ``N`` (or ``delta_w`` with ``phi`` when ``form["N_from"] ==
    "delta_w"``), ``rtol``, and the material ``d_p``, ``rho_p``, ``phi`` used when
    ``form["material"]`` is true. ``given`` is what the engineers' inputs were, for the sweep file.
    Raises ParameterError (one line, naming the input and its range) for the first bad input.
    """
    if not isinstance(form, dict):
        raise ParameterError("the page's inputs must be a mapping")
    values, given = {}, {}
    for d in DIMS:
        if d in ALTERNATIVES and form.get(f"{d}_from") == ALTERNATIVES[d][0]:
            alt, needs, convert = ALTERNATIVES[d]
            a, n = _number(alt, form.get(alt)), _number(needs, form.get(needs))
            values[d] = float(convert(n, a))
            given.update({alt: a, needs: n})
        else:
            values[d] = _number(d, form.get(d))
    point = check_point(*(values[d] for d in DIMS))
    material = None
    if form.get("material"):
        material = check_material({k: _number(k, form.get(k)) for k in MATERIAL_REQUIRED})
    rtol = _number("rtol", form.get("rtol", DEFAULT_RTOL))
    check_tolerances(rtol, TOLERANCES["atol"].default)
    return {"point": point, "material": material, "rtol": rtol, "given": given}


def _clean(x):
    """A float for JSON: None where it is not finite."""
    x = float(x)
    return x if math.isfinite(x) else None


def point(form: dict) -> dict:
    """The point of the page's inputs solved: status, outputs, sensitivities and profiles."""
    from .. import solve_point

    inp = read_inputs(form)
    eps, L, K, A, N = inp["point"]
    xi = np.linspace(0.0, 1.0, PROFILE_POINTS)
    r = solve_point(eps, L, K, A, N, rtol=inp["rtol"], material=inp["material"], profile=xi,
                    sensitivities=True)
    answer = {
        "point": dict(zip(DIMS, inp["point"])),
        "eta": eps * L,
        "status": r.status.name,
        "code": int(r.status),
        "message": r.status.message,
        "outputs": {k: _clean(v) for k, v in r.values.items()},
        "sensitivities": {k: {p: _clean(v) for p, v in s.items()}
                          for k, s in (r.sensitivities or {}).items()},
        "profile": None,
    }
    if r.profile is not None:
        answer["profile"] = {k: _json_list(a) for k, a in r.profile.items()}
    return answer


def _json_list(a) -> list:
    """An array as a list of floats for JSON, None where not finite."""
    a = np.asarray(a, dtype=float)
    return np.where(np.isfinite(a), a, None).tolist()


_MAPS: dict = {}
_PLANES: dict = {}
_MAPS_LOCK = threading.Lock()
MAP_CACHE = 64  # maps kept, by (eps L, the atlas): moving K, A or N redraws from here


def solvability_map(form: dict) -> dict:
    """The atlas's status over the (A, N) plane at the point's ``eps L``, without solving.

    ``codes`` is a row per N (from the lowest), a column per A; -1 where the atlas leaves the
    point undecided. The plane's transitions are looked up once per atlas
    (:class:`~cosserat_channel.atlas.Plane`) and each ``eps L``'s map is kept, so that moving
    ``eps`` or ``L`` costs a comparison and moving K, A or N nothing.
    """
    from ..atlas import Plane

    inp = read_inputs(form)
    eps, L = inp["point"][:2]
    atlas, path, which = default_atlas()
    if atlas is None:
        raise ParameterError("no atlas: neither a cached one ('atlas --cache') nor the shipped one "
                             "is there")
    key = (eps * L, path)
    with _MAPS_LOCK:
        hit = _MAPS.get(key)
        plane = _PLANES.get(path)
    if hit is None:
        if plane is None or plane.atlas is not atlas:
            a0, a1, n0, n1 = atlas.box
            A = np.linspace(a0, a1, MAP_A)
            Nv = np.linspace(n0, n1, MAP_N)
            plane = Plane(A[None, :], Nv[:, None], atlas=atlas)
            with _MAPS_LOCK:
                _PLANES[path] = plane
        codes = plane(eps, L)
        hit = {"A": plane.A[0].tolist(), "N": plane.N[:, 0].tolist(),
               "codes": codes.astype(int).tolist(), "atlas": which, "eta": eps * L}
        with _MAPS_LOCK:
            if len(_MAPS) >= MAP_CACHE:
                _MAPS.pop(next(iter(_MAPS)))
            _MAPS[key] = hit
    return hit


def line_axis(name: str, value: float) -> np.ndarray:
    """The values of a line over parameter ``name``: its slider's range, with ``value`` in it."""
    s = SLIDERS[name]
    if s["log"]:
        x = np.logspace(math.log10(s["lo"]), math.log10(s["hi"]), LINE_POINTS)
    else:
        x = np.linspace(s["lo"], s["hi"], LINE_POINTS)
    x = x[PARAMETERS[name].contains(x)]  # e.g. K's slider starts at 0, which K allows
    return np.union1d(x, [value])


def _line_dataset(form: dict):
    """``(Dataset, inputs, parameter, output)`` of the line the page asks for, from :func:`solve`."""
    import xarray as xr

    from .. import solve

    inp = read_inputs(form)
    name, output = form.get("line_x"), form.get("line_y")
    if name not in DIMS:
        raise ParameterError(f"line: the parameter must be one of {', '.join(DIMS)}; got {name!r}")
    if output not in out_.OUTPUTS:
        raise ParameterError(f"line: the output must be one of {', '.join(out_.OUTPUTS)}; "
                             f"got {output!r}")
    if out_.OUTPUTS[output].material and inp["material"] is None:
        raise ParameterError(f"line: {output} needs the material (d_p, rho_p, phi)")
    here = dict(zip(DIMS, inp["point"]))
    x = line_axis(name, here[name])
    args = {d: (xr.DataArray(x, dims=[d], coords={d: x}) if d == name else here[d]) for d in DIMS}
    ds = solve(*(args[d] for d in DIMS), rtol=inp["rtol"], material=inp["material"],
               outputs=[output])
    return ds, inp, name, output


def line(form: dict) -> dict:
    """One output against one parameter over its slider's range, by :func:`solve`."""
    ds, inp, name, output = _line_dataset(form)
    here = dict(zip(DIMS, inp["point"]))
    return {"x_name": name, "y_name": output, "x": ds[name].values.tolist(),
            "y": _json_list(ds[output].values), "status": ds.status.values.tolist(),
            "at": here[name], "point": here, "log": SLIDERS[name]["log"]}


def sweep_toml(inp: dict, name: str, output: str, x: np.ndarray, stem: str) -> str:
    """A sweep file that reproduces the line: ``name`` over ``x``, the other parameters fixed."""
    here = dict(zip(DIMS, inp["point"]))
    lines = ["# The explorer's view: " + f"{output} against {name}, the other parameters fixed.",
             f"#   cosserat-channel run {stem}.toml", "", "[grid]"]
    for d in DIMS:
        if d == name:
            lines.append(f"{d} = [{', '.join(repr(float(v)) for v in x)}]")
        else:
            lines.append(f"{d} = {here[d]!r}")
    for k, v in inp["given"].items():
        lines.append(f"# {k} = {v!r} gave the value above")
    if inp["material"] is not None:
        lines += ["", "[material]"] + [f"{k} = {inp['material'][k]!r}" for k in MATERIAL_REQUIRED]
    lines += ["", "[solver]", f"rtol = {inp['rtol']!r}", "", "[output]", f'path = "{stem}.nc"',
              f'variables = ["{output}"]', ""]
    return "\n".join(lines)


def _free_stem(directory: str, prefix: str = "explore") -> str:
    """The first ``prefix-<n>`` with no file of that stem in ``directory`` (none is replaced)."""
    taken = set(os.listdir(directory))
    n = 1
    while any(f"{prefix}-{n}{ext}" in taken for ext in (".toml", ".png", "-profiles.png", ".nc")):
        n += 1
    return os.path.join(directory, f"{prefix}-{n}")


def export(form: dict, directory: str) -> dict:
    """Write the current view into ``directory``: the line as a sweep file (``explore-<n>.toml``),
    its figure (``explore-<n>.png``) and, where the point is solved, its profiles
    (``explore-<n>-profiles.png``). No file is replaced; returns the paths written."""
    from .. import plot, solve_point
    from ..files import output_problem, write_text
    from ..plot.lines import line_plot

    ds, inp, name, output = _line_dataset(form)
    stem = _free_stem(directory)
    paths = [stem + ".toml", stem + ".png"]
    eps, L, K, A, N = inp["point"]
    r = solve_point(eps, L, K, A, N, rtol=inp["rtol"], material=inp["material"],
                    profile=np.linspace(0.0, 1.0, PROFILE_POINTS))
    if r.profile is not None:
        paths.append(stem + "-profiles.png")
    for p in paths:
        problem = output_problem(p, stream=False)
        if problem:
            raise ParameterError(problem)
    write_text(paths[0], sweep_toml(inp, name, output, ds[name].values, os.path.basename(stem)))
    fig = line_plot(ds, name, output, asymptote=False, path=paths[1])
    fig.clear()
    if r.profile is not None:
        plot.point_profiles(r, path=paths[2]).clear()
    return {"written": paths}
