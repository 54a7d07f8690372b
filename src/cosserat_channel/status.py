"""Why a point has (or has no) solution: one code, one name, one message, one colour.

Each status is one line of :class:`Status`; everything else (the messages people read, the CF
``flag_values`` / ``flag_meanings`` of files, the colours of regime maps) is read from it, so a new
status is a change to this module alone (plus the kernel that reports it). Kernels return the codes
as plain integers (an IntEnum member is a Python object there), hence the module constants below.
The names are part of the file format: do not rename them.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Status(IntEnum):
    """Outcome of one point; ``Status(code).message`` says why in one line."""

    # name = code, colour on regime maps, message
    ok = 0, "#4daf4a", "solved: stresses reach the wall and the spin vanishes on the axis"
    wall_inadmissible = 1, "#999999", (
        "A < 1 - 2N^2: the yield condition has no real sigma_yx at the wall for any couple "
        "stress (Appendix A)"
    )
    eps_too_large_axis = 2, "#ff7f00", (
        "eps too large at the axis: (A-1) eps L + 2(A+1) N < 0, the axis series (eq:20) has "
        "no admissible root"
    )
    eps_too_large_path = 3, "#e41a1c", (
        "eps too large along the path: the stress path left the yield-admissible region "
        "(D = 0) before the wall, at xi_stop (NaN within ~1e-5 of the axis edge, where the "
        "location is below double-precision resolution)"
    )
    axis_spin_unbounded = 4, "#984ea3", (
        "1 - 2N^2 < A < -1: only the root m(0) = +NL reaches the wall, and on it the spin "
        "grows without bound towards the axis, so omega(0) = 0 fails (Appendix A)"
    )
    integration_failed = 5, "#000000", (
        "the integrator exhausted its step budget or step size inside the solvable region"
    )

    def __new__(cls, code: int, color: str, message: str):
        member = int.__new__(cls, code)
        member._value_ = code
        member.color = color
        member.message = message
        return member


# The version of the CF conventions every NetCDF file the tool writes follows (result, boundary
# and atlas files alike).
CONVENTIONS = "CF-1.8"

# Plain integers for Numba kernels.
OK = int(Status.ok)
WALL_INADMISSIBLE = int(Status.wall_inadmissible)
EPS_TOO_LARGE_AXIS = int(Status.eps_too_large_axis)
EPS_TOO_LARGE_PATH = int(Status.eps_too_large_path)
AXIS_SPIN_UNBOUNDED = int(Status.axis_spin_unbounded)
INTEGRATION_FAILED = int(Status.integration_failed)


def cf_flag_attrs() -> dict:
    """CF attributes for an int8 ``status`` variable (``flag_values`` / ``flag_meanings``)."""
    return {
        "flag_values": np.array([s.value for s in Status], dtype=np.int8),
        "flag_meanings": " ".join(s.name for s in Status),
        "long_name": "solution status",
        "standard_name": "status_flag",
        "description": "why the point has, or has no, solution (one flag per status)",
    }
