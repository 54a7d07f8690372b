"""The solvability atlas: every change of feasibility in ``eta = eps L`` over a box of ``(A, N)``.

By the similarity of model.md a point's status depends on ``(eta, A, N)`` only. At each ``(A, N)``
:func:`cosserat_channel.regimes.trace_edge` finds the ``eta`` where feasibility changes (the
*transitions*: ``eta_max``, and ``eta_min`` where small ``eta`` fails too) and whether the lowest
searched ``eta`` is feasible. Together, the *signature* ``(feasible_low, n_transitions)`` and the
transitions say the status of every ``eta`` at that ``(A, N)``.

The atlas interpolates them. The box is cut into a quadtree of cells; on each cell the transitions
are sampled on a tensor grid of Chebyshev-Lobatto nodes (``degree + 1`` per side to start with)
and interpolated in ``log eta`` by the tensor Chebyshev polynomial through them. A cell is split
into four when its nodes do not all have the same signature (an ``eta_min`` appears, a window
of solutions closes, the wall line crosses it). Nodes that differ only by a transition that left
the searched range (``eta_min`` below it, ``eta_max`` above it) are aligned first
(:func:`.signatures._unify`: the nodes beyond the crossing get it clamped at the range's end); such a cell
is split only where the clamped transition reaches into the answered range. Where they agree, the error
estimate of the interpolant (:func:`.chebyshev._estimate`: the Chebyshev tail of each direction, extrapolated
where the coefficients decay geometrically) decides: below ``tol`` the cell is a leaf; above it the
degree is doubled along a direction whose coefficients still decay (the nodes are nested: every
trace is kept), else the cell is split. A cell that the node/focus switch crosses
(:func:`~cosserat_channel.physics.analytic.node_focus_switch_N`, known in closed form) is split rather
than raised in degree while it can be: the edge is not analytic across that curve, so a higher
degree buys little there; and a refinement that does not cut the tail (the raw
two-degree sum) by :data:`REFINE_GAIN` ends it (the traces are then noisier than ``tol``: the solver's edge is not
smooth at that level). Splits go down to ``max_depth``. There a cell whose nodes align keeps
the interpolants of its transitions, each with its own estimate, except a clamped one that reaches
into the answered range, which is kept as the envelope of its nodes' values
(:func:`.signatures._cluster_columns`); a cell still mixed becomes an *envelope* leaf: it decides wherever
its nodes agree and states, per cluster of transitions between, the width it leaves undecided
(``leaf_transition_error``); a leaf whose estimate is still
above ``tol`` keeps its own estimate, which :func:`classify` uses in place of ``tol``. No leaf is
left without an answer (``leaf_n = -1``, unresolved, appears only in files of older formats). A
transition whose interpolant stays outside the answered ``eta`` range by twice its estimate need
not meet ``tol``: no answered point depends on where it is.

The traces are continued (:func:`regimes.continue_edge`): each node's transitions are predicted
(by the interpolant of the cell's coarser grid, its parent's, or the nearest traced node),
corrected on the smooth ``D(1)`` and verified by a sign bracket ``TAU_OF_TOL * tol`` wide; a
trace is made afresh only where that fails. ``attrs["solves_per_edge_point"]`` records the cost.

Why not python-adaptive's ``Learner2D``: it interpolates piecewise-linearly on a triangulation, so
its error falls like ``h^2``; the edge is analytic, and the Chebyshev cells reach 1e-8 with a few
hundred traces where the edge is smooth (289 on A in [-0.5, 0.5], N in [1, 1.25]), while a linear
interpolant needs millions (measured in ``benchmarks/bench_atlas.py``
and ``docs/performance.md``). It also learns one scalar, while a point here has zero to two
transitions and the number changes across the plane.

Numerics. The transitions are those of :func:`~cosserat_channel.regimes.trace_edge`: bisected
by :func:`~cosserat_channel.regimes.bisect_edge` to ``regimes.ETA_XTOL`` (1e-10 relative) with
the solver at ``regimes.EDGE_RTOL``, except at tangential edges, where the stress path runs into
the node of the yield condition at the wall and ``D(1) ~ c (eta_max - eta)^2``: there the status
is decided by the noise of ``D(1)`` within ~1e-6 of the edge, and the transition is the node's
closed-form ``eta`` once ``D(1)`` sampled well below the edge confirms it
(``regimes.node_edge_eta``; scipy's DOP853 puts the zero of ``D(1)`` within 5e-9 of it). Where
the edge is known is thus about 1e-8 relative (how far it moves with the solver's tolerance), so
``tol`` is at least :data:`TOL_MIN`. Every trace also states its *noise band*, how close to the
transition the solver's status stops being reliable (~1e-6 at tangential edges, up to ~1e-6 at
transversal ones next to the node/focus switch ``N^2 = (5 + 3A)/2`` where ``D(1)`` rises slowly,
1e-9 to 1e-7 elsewhere); a leaf keeps the largest of its nodes' bands and :func:`classify` leaves
points within it undecided. On the focus side of that switch, over about 0.15 in N, the status
bisection's edge is itself noise at up to ~1e-7 (a near-double zero of stage 1's ``D(1)``, whose
noise is ~1e-13): where a trace's band exceeds ``regimes.SMOOTH_BAND`` the transition is instead
the zero of ``regimes.smooth_wall_D``, ``D(1)`` marched as a state of its own next to the wall
(smooth in ``eta``, noise ~1e-18; an independent scipy march puts the model's edge within 1e-9
of it), so the atlas interpolates a smooth function there too. The traces search twice the
claimed range of ``eta`` each way, so that a transition just outside the claimed range keeps the
signature of the cells next to it and is interpolated, not lost.

Reading an atlas (:func:`load_atlas`, :func:`classify`, :meth:`Atlas.boundary`) imports numpy
and xarray only: building one (:func:`build_atlas`) imports the solver. Which source gives the
edge on a grid, an atlas (the cached, the shipped or a given one) or a trace, is decided once,
by :func:`edge_source`, for every caller.

Layer: above :mod:`cosserat_channel.regimes` (which the build calls for its traces); below the
figures and the command line. Reading and deciding (:mod:`.interpolant`, :mod:`.decide`,
:mod:`.store`, :mod:`.source`, :mod:`.chebyshev`, :mod:`.settings`, :mod:`.signatures`) import
numpy and xarray only; the build (:mod:`.build`, :mod:`.tracer`, :mod:`.assemble`) imports
``regimes`` and the solver's ``Workspace`` when it runs. May import besides:
:mod:`~cosserat_channel.physics.analytic` and the vocabulary modules (parameters, status,
regime_codes, files, netcdf_policy). Never imports plotting, sweeps or the CLI.
"""

from __future__ import annotations

from .build import build_atlas, check_build_arguments  # noqa: F401
from .chebyshev import lobatto  # noqa: F401
from .decide import Plane, classify  # noqa: F401
from .interpolant import Atlas  # noqa: F401
from .source import EdgeSource, SourceError, edge_source  # noqa: F401
from .settings import *  # noqa: F401,F403 (the atlas's constants, under the names callers use)
from .store import (  # noqa: F401
    cache_path,
    default_atlas,
    describe,
    from_dataset,
    load_atlas,
    load_traces,
    partial_path,
    save_atlas,
    save_traces,
    shipped_path,
    to_dataset,
    traces_key,
)
