"""Why a point has (or has no) solution: one code, one name, one message.

Kernels return these codes as plain integers; files carry them as int8 with CF
``flag_values`` / ``flag_meanings``; people read the messages. The names are part of the file
format: do not rename them.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

# Plain integers for Numba kernels (an IntEnum member is a Python object there).
OK = 0
WALL_INADMISSIBLE = 1
EPS_TOO_LARGE_AXIS = 2
EPS_TOO_LARGE_PATH = 3
AXIS_SPIN_UNBOUNDED = 4
INTEGRATION_FAILED = 5


class Status(IntEnum):
    """Outcome of one point; ``Status(code).message`` says why in one line."""

    ok = OK
    wall_inadmissible = WALL_INADMISSIBLE
    eps_too_large_axis = EPS_TOO_LARGE_AXIS
    eps_too_large_path = EPS_TOO_LARGE_PATH
    axis_spin_unbounded = AXIS_SPIN_UNBOUNDED
    integration_failed = INTEGRATION_FAILED

    @property
    def message(self) -> str:
        return MESSAGES[self]


MESSAGES = {
    Status.ok: "solved: stresses reach the wall and the spin vanishes on the axis",
    Status.wall_inadmissible: (
        "A < 1 - 2N^2: the yield condition has no real sigma_yx at the wall for any couple "
        "stress (Appendix A)"
    ),
    Status.eps_too_large_axis: (
        "eps too large at the axis: (A-1) eps L + 2(A+1) N < 0, the axis series (eq:20) has "
        "no admissible root"
    ),
    Status.eps_too_large_path: (
        "eps too large along the path: the stress path left the yield-admissible region "
        "(D = 0) before the wall, at xi_stop (NaN within ~1e-5 of the axis edge, where the "
        "location is below double-precision resolution)"
    ),
    Status.axis_spin_unbounded: (
        "1 - 2N^2 < A < -1: only the root m(0) = +NL reaches the wall, and on it the spin "
        "grows without bound towards the axis, so omega(0) = 0 fails (Appendix A)"
    ),
    Status.integration_failed: (
        "the integrator exhausted its step budget or step size inside the solvable region"
    ),
}


def cf_flag_attrs() -> dict:
    """CF attributes for an int8 ``status`` variable (``flag_values`` / ``flag_meanings``)."""
    return {
        "flag_values": np.array([s.value for s in Status], dtype=np.int8),
        "flag_meanings": " ".join(s.name for s in Status),
        "long_name": "solution status",
    }
