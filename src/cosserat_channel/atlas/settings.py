"""The atlas's constants: tolerances, degrees, depths, the undecided band, the file format."""

from __future__ import annotations

UNDECIDED = -1  # classify's code for a point the atlas cannot decide: a solve decides it
TOL_MIN = 1e-8  # how well the edge itself is known (regimes.EDGE_RTOL), relative in eta
TOL_MAX = 1e-1
DEGREE = 8  # Chebyshev degree per cell and direction to start with: 81 nodes
MAX_DEGREE = 32  # a cell's degree per direction grows (doubling: nested nodes) up to this
RATE_GEOMETRIC = 0.5  # coefficient decay per degree below which a tail is extrapolated
TAIL_SAFETY = 2.0  # factor on the extrapolated tail
REFINE_GAIN = 4.0  # a refinement that does not cut the estimate by this much stops (noise)
ROUNDOFF = 1e-13  # floor of an estimate: round-off of the interpolant of log eta
# Factor on the two-degree sum where the coefficients do not decay, per unit of the cell's
# largest degree. One trace off by d (a node landed low in a ragged stretch of the solver's
# edge) puts only ~3d/p into that sum at degree p (measured at p = 16: 0.16 d for a node on a
# side, 0.28 d inside), while the interpolant is off by d next to that node: p times the sum
# leaves a margin of about 2.5.
PLATEAU_SAFETY = 1.0
MAX_DEPTH = 6  # splits of a root cell; the raster of leaves is (roots * 2^depth)^2
MAX_DEPTH_LIMIT = 8
SAFETY = 2.0  # undecided band: SAFETY * max(tol, the cell's error estimate), relative in eta
TRACE_WIDEN = 2.0  # traces search [lo / TRACE_WIDEN, hi * TRACE_WIDEN] (see the module notes)
TAU_OF_TOL = 0.125  # continued transitions are verified by a bracket this many tol either side
NEAR_NODE = 0.03  # a node with no interpolant over it continues from a traced one this close (A, N)
NEAR_SPREAD = 0.05  # ... with this relative uncertainty
DEFAULT_TOL = 1e-8  # the edge itself is known to ~1e-8 (TOL_MIN)
DEFAULT_A = (-1.0, 5.0)
DEFAULT_N = (0.3, 3.0)
ROOT_CELL = 1.0  # the root cells are about this wide in A and N
FORMAT = "cosserat-channel atlas 4"  # 4: an error per transition (leaf_transition_error)
# 3: noise bands of the traces (sample_bands, leaf_band)
# 1: every leaf of the atlas's degree; 2: leaves of their own degrees (leaf_degree). Both are read
# with zero bands: their traces bisected the status at tangential edges (see the module notes).
FORMATS = ("cosserat-channel atlas 1", "cosserat-channel atlas 2", "cosserat-channel atlas 3",
           FORMAT)
ANSWERED_GRID = 17  # points per direction where a transition's distance from the range is read
