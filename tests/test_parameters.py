"""Parameter ranges and checks: one definition for the API, sweep files and the command line."""

import math

import numpy as np
import pytest

from cosserat_channel.parameters import (
    DIMS,
    PARAMETERS,
    ParameterError,
    check_material,
    check_point,
    check_tolerances,
    check_values,
)

FIG2 = (1 / 30, 10.0, 0.5, 1 / 3, 1.0)


@pytest.mark.parametrize("name, value", [
    ("eps", 0.0),  # open at 0
    ("eps", 1.5),  # above 1
    ("L", -1.0),
    ("K", -1e-300),  # K = 0 is allowed, anything below is not
    ("N", 0.0),
    ("A", math.inf),
    ("L", math.nan),
    ("L", 10**400),  # a Python int too large for a float
    ("L", True),  # a bool is not a length
    ("L", np.bool_(True)),
    ("L", "10"),  # nor is a string
    ("A", 1 + 2j),
])
def test_bad_values_name_the_parameter_and_its_range(name, value):
    """Each bad value raises ParameterError naming the parameter and its interval."""
    point = dict(zip(DIMS, FIG2), **{name: value})
    with pytest.raises(ParameterError) as info:
        check_point(*(point[d] for d in DIMS))
    assert str(info.value).startswith(f"{name} ")
    assert PARAMETERS[name].interval in str(info.value)


def test_good_values_come_back_as_floats():
    """Accepted values are returned as Python floats, numpy scalars included."""
    got = check_point(np.float32(0.5), np.int64(10), 0, 1 / 3, 1)
    assert all(type(v) is float for v in got) and got[2] == 0.0


def test_check_values_matches_the_scalar_check():
    """The vectorised axis check accepts and rejects exactly what the scalar check does."""
    assert check_values("eps", np.logspace(-7, 0, 1000)).dtype == np.float64
    with pytest.raises(ParameterError, match=r"^eps = 1.5 is outside the allowed range \(0, 1\]"):
        check_values("eps", [0.1, 1.5, 2.0])


def test_tolerances_and_material():
    """Tolerance ranges and the material's defaults and cross-check."""
    assert check_tolerances(1e-8, 1e-12) == (1e-8, 1e-12)
    with pytest.raises(ParameterError, match="rtol"):
        check_tolerances(1e-14, 1e-12)
    full = check_material({"d_p": 0.002, "rho_p": 2940, "phi": 25})
    assert full["Lambda"] == 817.0 and full["g"] == 9.81
    with pytest.raises(ParameterError, match="nu_min"):
        check_material({"d_p": 0.002, "rho_p": 2940, "phi": 25, "nu_min": 0.7})
    with pytest.raises(ParameterError, match="unknown key"):
        check_material({"d_p": 0.002, "rho_p": 2940, "phi": 25, "colour": 1})
