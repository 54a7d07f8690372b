"""The vocabulary of the solvability data: phase-plane region codes, kinds of a traced edge.

:mod:`cosserat_channel.regimes` produces data coded with these values and
:mod:`cosserat_channel.plot.regimes` draws it. Both import the codes from here, so that the
figures can read the data without importing the module that runs the solver (plotting takes
data, it never solves). Nothing but constants: no numpy, no numba.
"""

from __future__ import annotations

# Search range of eta = eps L: eps <= 1 and L up to ~100 (model.md's ranges of interest). The
# traced boundary Dataset records the range it searched in its attributes; these are the defaults.
ETA_SEARCH_MIN = 1e-3
ETA_SEARCH_MAX = 100.0
# Log-spaced samples of a fresh trace's coarse pass over that range, before bisection.
ETA_COARSE = 48

# Kinds of a traced edge (int8 flag in the boundary Dataset).
EDGE_BOUNDED = 0  # ok just below eta_max, not ok just above: a true edge inside the range
EDGE_UNBOUNDED = 1  # ok at the upper end of the range: eta_max is that end, a lower bound only
EDGE_NONE = 2  # no ok point anywhere in the range
EDGE_KINDS = ("bounded", "unbounded_in_range", "no_solution")

# Sign regions of the phase plane (values of regimes.PhasePlane.region).
REGION_D_NEGATIVE = 0
REGION_EP_POS_EM_NEG = 1
REGION_EM_POS = 2  # then E+ > 0 too (E+ >= E-)
REGION_EP_NEG = 3  # then E- < 0 too; only for A < -1
REGION_LABELS = {
    REGION_D_NEGATIVE: r"$D<0$",
    REGION_EP_POS_EM_NEG: r"$E_{+}>0,\ E_{-}<0$",
    REGION_EM_POS: r"$E_{-}>0$ (and $E_{+}>0$)",
    REGION_EP_NEG: r"$E_{+}<0$ (and $E_{-}<0$)",
}
