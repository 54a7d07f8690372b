"""Digests of the solver's outputs, to show that a refactoring changed no bit of any result.

Runs the quickstart and regimes sweeps in memory (reduced and, for quickstart, unreduced) and
``solve_point`` over the test points (with a material, with profiles, with sensitivities), and
prints one SHA-256 per piece. Run it before and after a change and compare the lines::

    .venv/bin/python benchmarks/fingerprint.py > before.txt   # on the old commit
    .venv/bin/python benchmarks/fingerprint.py > after.txt    # on the new one
    diff before.txt after.txt

Only public, long-lived entry points are used (``run_sweep`` on a mapping, ``solve_point``), so
the script runs unchanged on either side of a restructuring.
"""

from __future__ import annotations

import hashlib
import sys
import tomllib
from pathlib import Path

import numpy as np

import cosserat_channel as cc

ROOT = Path(__file__).resolve().parent.parent
SCALARS = ("Delta", "xi_p", "slip", "u_axis", "m_wall", "sigma_yx_wall", "xi_stop", "nu",
           "sigma_xx_wall_Pa", "sigma_xy_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m")
MATERIAL = dict(d_p=0.002, rho_p=2940.0, phi=25.0)
POINTS = [
    (1e-4, 1.0, 0.5, 1 / 3, 1.0), (1e-4, 30.0, 0.1, 1 / 3, 1.0), (1e-4, 3.0, 5.0, 2.0, 2.0),
    (1e-3, 10.0, 100.0, 0.5, 1.5), (1 / 600, 10.0, 0.5, 1 / 3, 1.0), (1 / 30, 10.0, 0.5, 1 / 3, 1.0),
    (1 / 30, 2.0, 0.5, 1 / 3, 1.0), (0.12, 10.0, 0.5, 1 / 3, 1.0), (0.05, 5.0, 1.0, -0.85, 3.0),
    (0.02, 20.0, 0.3, -0.5, 1.2), (0.01, 1.0, 10.0, 2.9, 0.7), (0.2, 15.0, 2.0, 1.0, 1.0),
    (0.3, 10.0, 0.5, 1 / 3, 1.0), (0.32, 10.0, 0.5, 1 / 3, 1.0), (0.33, 10.0, 0.5, 1 / 3, 1.0),
    (0.335, 10.0, 0.5, 1 / 3, 1.0), (0.38, 10.0, 0.5, 1 / 3, 1.0), (0.45, 10.0, 0.5, 1 / 3, 1.0),
    (0.05, 10.0, 0.5, 0.0, 0.7), (0.05, 10.0, 0.5, 0.1, 0.7), (1 / 30, 10.0, 0.5, -1.0, 1.0),
    (1e-6, 10.0, 0.5, -1.0, 2.0), (0.05, 10.0, 0.5, -1.5, 1.5), (1 / 30, 10.0, 300.0, 1 / 3, 1.0),
    (1e-7, 1.0, 0.5, 1 / 3, 1.0), (0.5, 100.0, 1e4, 5.0, 10.0),
]
PROFILE_XI = [0.0, 1e-3, 0.1, 0.5, 0.9, 0.99, 1.0]
FLAGS = ("adjoint", "differences", "unresolved", "no_solution", "undefined")


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a))
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:24]


def _dataset_digest(ds) -> str:
    names = sorted(ds.data_vars) + sorted(ds.coords)
    return _digest(*[np.asarray(ds[n].values) for n in names]) + " " + ",".join(names)


def _sweep(name: str, **kw) -> str:
    mapping = tomllib.loads((ROOT / "sweeps" / f"{name}.toml").read_text())
    mapping.get("output", {}).pop("path", None)
    ds = cc.run_sweep(mapping, workers=1, progress=False, **kw)
    return _dataset_digest(ds)


def _points() -> str:
    from cosserat_channel.solver.point import solve_point

    values = []
    for p in POINTS:
        r = solve_point(*p, material=MATERIAL, profile=PROFILE_XI)
        values.append([float(r.status)] + [float(getattr(r, k)) for k in SCALARS])
        if r.profile is not None:
            values.append(np.concatenate([np.asarray(v, float) for _, v in sorted(r.profile.items())]))
        for rtol in (1e-5, 1e-10):
            q = solve_point(*p, rtol=rtol)
            values.append([float(q.status)] + [float(getattr(q, k)) for k in SCALARS[:7]])
    return _digest(*[np.asarray(v, float) for v in values])


def _sensitivities() -> str:
    """The derivatives and their flags of ``solve_point(sensitivities=True)`` over the points (at
    the default rtol and at 1e-11, with a material and a profile)."""
    from cosserat_channel.solver.point import solve_point

    values = []
    for p in POINTS:
        for rtol in (1e-8, 1e-11):
            r = solve_point(*p, rtol=rtol, material=MATERIAL, profile=PROFILE_XI,
                            sensitivities=True)
            for out, d in sorted(r.sensitivities.items()):
                values.append([d[k] for k in sorted(d)])
                flags = getattr(r, "sensitivity_flags", None) or {}
                values.append([float(FLAGS.index(f)) for _, f in sorted(flags.get(out, {}).items())])
            for _, d in sorted((r.profile_sensitivities or {}).items()):
                values.extend(np.asarray(v, float) for _, v in sorted(d.items()))
    return _digest(*[np.asarray(v, float) for v in values])


def main() -> int:
    print("solve_point", _points())
    print("sensitivities", _sensitivities())
    print("quickstart", _sweep("quickstart"))
    print("quickstart unreduced", _sweep("quickstart", reduce=False))
    print("regimes_A_N", _sweep("regimes_A_N"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
