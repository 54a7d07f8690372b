"""Where the model has a solution: the phase plane of Appendix A and the edge of solvability.

By the similarity of model.md, whether a point has a solution depends on ``(eta = eps L, A, N)``
only. :func:`trace_edge` finds every ``eta`` where feasibility changes at one ``(A, N)`` (the
*transitions*: ``eta_max``, and ``eta_min`` where small ``eta`` fails too), :func:`trace_boundary`
does so on a grid and returns a Dataset. Given a neighbour's transitions, :func:`continue_edge`
corrects each on a smooth scalar at the wall and verifies it by a sign bracket (about three
stage-1 marches a transition, against ~80 for coarse samples and bisections); at tangential edges
the transition is the node's closed form (:func:`node_edge_eta`).

Layer: above the solver (:mod:`cosserat_channel.solver`) and the physics
(:mod:`~cosserat_channel.physics.model`, :mod:`~cosserat_channel.physics.analytic`); below the
atlas, the figures and the command line. May import numpy, scipy and xarray, and from the
package ``solver``, ``physics``, ``status``, ``parameters`` and ``regime_codes``; never an
integrator (stage 1 is marched by the solver, :mod:`cosserat_channel.solver.wall`), numba, the
atlas, plotting, sweeps or the CLI.

Modules: :mod:`.phase` (figure 12's data; scipy, no numba), :mod:`.wall` (scalars at the wall,
from the solver's stage-1 kernels), :mod:`.edge` (the :class:`Edge` record, :func:`bisect_edge`),
:mod:`.continuation` (predict and correct), :mod:`.trace` (an edge at a point, on a grid) and
:mod:`.boundary` (the boundary Dataset, one layout for traced and atlas data; xarray, no numba).
The names below load their module on first use, so that the phase plane and the boundary
Dataset are read without the solver.
"""

from __future__ import annotations

import importlib

from ..physics.analytic import axis_edge_eta  # noqa: F401 (its home is analytic.py; callers import it here)
from ..regime_codes import (  # noqa: F401 (the codes of this data: callers import them here)
    EDGE_BOUNDED,
    EDGE_KINDS,
    EDGE_NONE,
    EDGE_UNBOUNDED,
    ETA_SEARCH_MAX,
    ETA_SEARCH_MIN,
    REGION_D_NEGATIVE,
    REGION_EM_POS,
    REGION_EP_NEG,
    REGION_EP_POS_EM_NEG,
    REGION_LABELS,
)

_HOMES = {
    "phase": ("wall_line_A", "axis_line_N", "yield_D", "d_zero_curve", "nullcline_curve",
              "Trajectory", "PhasePlane", "phase_trajectory", "phase_plane",
              "_series_coefficient"),
    "wall": ("EDGE_RTOL", "EDGE_ATOL", "EDGE_MAX_STEPS", "PROBE_XTOL", "PROBE_OFFSETS",
             "D_NOISE", "SMOOTH_RTOL", "SMOOTH_MAX_STEPS", "SMOOTH_BAND", "SMOOTH_XTOL", "SMOOTH_WIDEN", "wall_D",
             "smooth_wall_D", "smooth_edge", "node_edge_eta", "Probe", "probe_edge",
             "wall_scalar"),
    "edge": ("Edge", "bisect_edge"),
    "continuation": ("CORRECT_TAU", "CORRECT_MAX_EVALS", "CORRECT_REACH", "NODE_VERIFY",
                     "NODE_VERIFY_BANDS", "BAND_CAP", "Guess", "Corrected",
                     "correct_transition", "continue_edge", "guesses_from"),
    "trace": ("ETA_COARSE", "ETA_XTOL", "NODE_AGREE", "SLOPE_STEP", "BOUNDARY_NEAR",
              "BOUNDARY_SPREAD", "trace_edge", "trace_boundary"),
    "boundary": ("boundary_dataset",),
}
_WHERE = {name: module for module, names in _HOMES.items() for name in names}
__all__ = sorted(n for n in _WHERE if not n.startswith("_"))


def __getattr__(name):
    if name in _HOMES:
        return importlib.import_module(f"{__name__}.{name}")
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
