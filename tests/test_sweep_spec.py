"""Sweep files: grid forms, every rejection path, the shipped sweeps, provenance hash."""

import copy
import hashlib
import pathlib
import re

import numpy as np
import pytest

from cosserat_channel import outputs, parameters
from cosserat_channel.parameters import ParameterError
from cosserat_channel.sweep.spec import (
    DIMS,
    SweepError,
    SweepSpec,
    load_sweep,
)

SWEEPS = sorted((pathlib.Path(__file__).parents[1] / "sweeps").glob("*.toml"))
FIG2_MATERIAL = {"d_p": 0.002, "rho_p": 2940, "phi": 25}

GOOD = """\
# a comment
[grid]
eps = {logspace = [-3, -1, 5]}
L = [2, 5, 10]
K = {linspace = [0, 1, 3]}
A = 0.3333333333333333
N = 1

[material]
d_p = 0.002
rho_p = 2940
phi = 25

[solver]
rtol = 1e-6
atol = 1e-10

[output]
path = "out/x.nc"
variables = ["Delta", "nu", "stage1_steps"]
profile_points = 11
"""


def _grid(**override):
    """A valid mapping (one point) with grid entries replaced."""
    grid = {"eps": 0.1, "L": 10, "K": 0.5, "A": 1 / 3, "N": 1.0}
    grid.update(override)
    return {"grid": grid}


def _write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_file_fields(tmp_path):
    """A full sweep file gives every field: axes, material with defaults, tolerances, output."""
    path = _write(tmp_path, GOOD)
    spec = load_sweep(path)
    assert isinstance(spec, SweepSpec)
    assert spec.shape == (5, 3, 3, 1, 1) and spec.size == 45
    assert list(spec.coords()) == list(DIMS)
    assert spec.material == parameters.check_material(FIG2_MATERIAL)
    assert (spec.rtol, spec.atol) == (1e-6, 1e-10)
    assert spec.output_path == "out/x.nc"
    assert spec.variables == ("Delta", "nu", "stage1_steps")
    assert spec.profile_points == 11
    assert spec.text == GOOD
    assert spec.source == str(path)


@pytest.mark.parametrize(
    "form, expected",
    [
        (0.25, np.array([0.25])),  # one number
        (1, np.array([1.0])),  # an integer becomes float64
        ([0.3, 0.1, 0.2], np.array([0.3, 0.1, 0.2])),  # a list keeps file order
        ({"linspace": [0.1, 0.5, 5]}, np.linspace(0.1, 0.5, 5)),
        ({"logspace": [-3, -1, 12]}, np.logspace(-3, -1, 12)),
        ({"logspace": [-2, -2, 1]}, np.array([0.01])),  # num = 1
    ],
)
def test_grid_forms_exact(form, expected):
    """Each grid form gives exactly numpy's values, as float64, in order."""
    spec = load_sweep(_grid(eps=form))
    assert spec.eps.dtype == np.float64 and spec.eps.ndim == 1
    np.testing.assert_array_equal(spec.eps, expected)


def test_defaults():
    """Without solver/output/material: default tolerances, dimensionless variables, no path."""
    spec = load_sweep(_grid())
    assert (spec.rtol, spec.atol) == (parameters.DEFAULT_RTOL, parameters.DEFAULT_ATOL)
    assert spec.material is None and spec.output_path is None and spec.profile_points is None
    dimensionless = tuple(n for n, o in outputs.OUTPUTS.items() if not o.material)
    assert spec.variables == dimensionless
    with_material = load_sweep({**_grid(), "material": FIG2_MATERIAL})
    assert with_material.variables == dimensionless + outputs.material_outputs()
    assert set(with_material.variables) == set(outputs.OUTPUTS)


def test_axes_are_read_only():
    """The spec is frozen and its axes cannot be changed in place."""
    spec = load_sweep(_grid(L=[1, 2]))
    with pytest.raises(ValueError):
        spec.L[0] = 5.0
    with pytest.raises(AttributeError):
        spec.rtol = 1.0


BAD = [
    # (mapping, key the message must name)
    ({"grid": {"eps": 0.1, "L": 1, "K": 1, "A": 1}}, "grid"),  # N missing
    (_grid(eps={"logspace": [1, 2]}), "grid.eps"),  # two numbers instead of three
    (_grid(eps={"logspace": [-2, -1, 0]}), "grid.eps"),  # num = 0
    (_grid(L={"linspace": [1, 2, 2.5]}), "grid.L"),  # num not an integer
    (_grid(L={"linspace": [1, 2, True]}), "grid.L"),  # num a boolean
    (_grid(L={"linspace": [1, 2, 3], "logspace": [0, 1, 2]}), "grid.L"),  # two forms
    (_grid(L={"range": [1, 2, 3]}), "grid.L"),  # unknown form
    (_grid(K=[]), "grid.K"),  # empty list
    (_grid(K="0.5"), "grid.K"),  # a string
    (_grid(K=["0.5"]), "grid.K[0]"),  # a string inside a list
    (_grid(A=True), "grid.A"),  # a boolean
    (_grid(A=[1.0, True]), "grid.A[1]"),
    (_grid(eps=2.0), "grid.eps"),  # eps > 1
    (_grid(eps=0.0), "grid.eps"),  # eps = 0
    (_grid(L=[1, -1]), "grid.L"),  # L <= 0
    (_grid(K=-0.1), "grid.K"),  # K < 0
    (_grid(A=float("inf")), "grid.A"),  # A not finite
    (_grid(N=float("nan")), "grid.N"),  # N not finite
    (_grid(N=0), "grid.N"),  # N = 0
    (_grid(L={"logspace": [0, 400, 2]}), "grid.L"),  # 1e400 overflows to inf
    (_grid(eps={"linspace": [0.1, float("nan"), 3]}), "grid.eps"),
    (_grid(L=[1, 2, 1]), "grid.L"),  # duplicate value
    (_grid(K={"linspace": [1, 1, 3]}), "grid.K"),  # duplicates from linspace
    (_grid(Q=1), "grid"),  # unknown grid key
    ({**_grid(), "solve": {}}, "sweep"),  # unknown table
    ({**_grid(), "material": {"d_p": 0.002, "rho_p": 2940}}, "material"),  # phi missing
    ({**_grid(), "material": {**FIG2_MATERIAL, "phi": 95}}, "material.phi"),
    ({**_grid(), "material": {**FIG2_MATERIAL, "colour": 1}}, "material"),
    ({**_grid(), "material": {**FIG2_MATERIAL, "d_p": "0.002"}}, "material.d_p"),  # string
    ({**_grid(), "material": {**FIG2_MATERIAL, "nu_min": 0.7}}, "material.nu_min"),
    ({**_grid(), "solver": {"rtol": 0}}, "solver.rtol"),
    ({**_grid(), "solver": {"atol": -1}}, "solver.atol"),
    ({**_grid(), "solver": {"rtol": "1e-8"}}, "solver.rtol"),
    ({**_grid(), "solver": {"method": "rk45"}}, "solver"),
    ({**_grid(), "output": {"path": 3}}, "output.path"),
    ({**_grid(), "output": {"variables": ["Delta", "delta"]}}, "output.variables"),
    ({**_grid(), "output": {"variables": ["nu"]}}, "output.variables"),  # needs material
    ({**_grid(), "output": {"variables": ["sigma_xx_wall_Pa"]}}, "output.variables"),
    ({**_grid(), "output": {"variables": []}}, "output.variables"),
    ({**_grid(), "output": {"variables": ["Delta", "Delta"]}}, "output.variables"),
    ({**_grid(), "output": {"profile_points": 1}}, "output.profile_points"),
    ({**_grid(), "output": {"profile_points": 10002}}, "output.profile_points"),
    ({**_grid(), "output": {"profile_points": 11.0}}, "output.profile_points"),
    ({**_grid(), "output": {"format": "nc"}}, "output"),
    ({"grid": [1, 2]}, "grid"),  # not a table
    (  # 300 * 1000 * 100,000 points > 1e10
        _grid(eps={"logspace": [-3, -1, 300]}, L={"linspace": [1, 2, 1000]},
              K={"linspace": [0, 1, 100_000]}),
        "grid",
    ),
]


@pytest.mark.parametrize("mapping, key", BAD)
def test_rejections_name_the_key(mapping, key):
    """Every malformed sweep raises SweepError (a ParameterError) on one line naming the key."""
    with pytest.raises(SweepError) as info:
        load_sweep(mapping)
    msg = str(info.value)
    assert isinstance(info.value, ParameterError) and isinstance(info.value, ValueError)
    assert msg.startswith(key + ":") or msg.startswith(key + " ") or msg.startswith(key + ".")
    assert "\n" not in msg


def test_rejection_messages_are_specific():
    """The messages carry the offending value, the allowed keys or the grid size."""
    with pytest.raises(SweepError, match=r"grid\.eps: logspace needs .*got \[1, 2\]"):
        load_sweep(_grid(eps={"logspace": [1, 2]}))
    with pytest.raises(SweepError, match=r"grid\.L: L = -1\.0 is outside"):
        load_sweep(_grid(L=[1, -1]))
    with pytest.raises(SweepError, match=r"allowed: grid, material, solver, output"):
        load_sweep({**_grid(), "solve": {}})
    with pytest.raises(SweepError, match=r"duplicate value\(s\) 1\.0"):
        load_sweep(_grid(L=[1, 2, 1]))
    with pytest.raises(SweepError, match=r"30,000,000,000 points"):
        load_sweep(_grid(eps={"logspace": [-3, -1, 300]}, L={"linspace": [1, 2, 1000]},
                         K={"linspace": [0, 1, 100_000]}))
    # 3e8 points were refused when the whole grid had to fit in memory; the disk is the limit now
    assert load_sweep(_grid(eps={"logspace": [-3, -1, 300]}, L={"linspace": [1, 2, 1000]},
                            K={"linspace": [0, 1, 1000]})).size == 300_000_000
    with pytest.raises(SweepError, match=r"valid: Delta, xi_p"):
        load_sweep({**_grid(), "output": {"variables": ["delta"]}})


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("[grid\neps = 1\n", "invalid TOML"),  # malformed table header
        ("[grid]\neps = \n", "invalid TOML"),  # missing value
        ("[grid]\neps = 0.1\neps = 0.2\n", "invalid TOML"),  # key defined twice
        ("[grid]\neps = 0.1\nL = 1\nK = 1\nA = 1\nN = 1\n[output]\npath = 'a'\n"
         "profile_points = true\n", "output.profile_points"),
    ],
)
def test_bad_files(tmp_path, text, fragment):
    """Malformed TOML is one line naming the file; file errors keep the file name in front."""
    path = _write(tmp_path, text)
    with pytest.raises(SweepError) as info:
        load_sweep(path)
    msg = str(info.value)
    assert msg.startswith(str(path) + ": ") and fragment in msg and "\n" not in msg


def test_missing_and_binary_files(tmp_path):
    """A missing file, a directory and non-UTF-8 bytes are SweepErrors, not OSErrors."""
    with pytest.raises(SweepError, match="no such sweep file"):
        load_sweep(tmp_path / "absent.toml")
    with pytest.raises(SweepError, match="directory"):
        load_sweep(tmp_path)
    p = tmp_path / "b.toml"
    p.write_bytes(b"\xff\xfe[grid]")
    with pytest.raises(SweepError, match="UTF-8"):
        load_sweep(p)
    with pytest.raises(SweepError, match="path or a mapping"):
        load_sweep(42)
    for signature in (b"\x89HDF\r\n\x1a\n", b"CDF\x01"):  # NetCDF-4 and classic
        p.write_bytes(signature + bytes(64))
        with pytest.raises(SweepError, match="is a NetCDF file .* not a sweep file"):
            load_sweep(p)


@pytest.mark.parametrize("grid, hinted", [
    # values where exponents belong: eps from 10**0.001 = 1.002 on is outside (0, 1] ...
    (dict(eps={"logspace": [0.001, 0.1, 12]}), "logspace = [-3, -1, num]"),
    # ... and L up to 1e30 puts eps L outside the solver's range
    (dict(L={"logspace": [1, 30, 4]}), "logspace = [0, 1.47712, num]"),
    # a linspace or exponents that are simply out of range get no hint
    (dict(eps={"linspace": [0.5, 2, 3]}), None),
    (dict(eps={"logspace": [-3, 1, 3]}), None),
])
def test_logspace_given_values_hints_at_exponents(grid, hinted):
    mapping = {"grid": {**dict(eps=0.01, L=10, K=0.5, A=0.3, N=1.0), **grid}}
    with pytest.raises(SweepError) as info:
        load_sweep(mapping)
    message = str(info.value)
    assert ("exponents of 10" in message) == (hinted is not None), message
    if hinted:
        assert hinted in message


@pytest.mark.parametrize("path", SWEEPS, ids=[p.name for p in SWEEPS])
def test_shipped_sweeps_load(path):
    """Every shipped sweep file loads, has a comment header and an output path."""
    spec = load_sweep(path)
    assert spec.size >= 1
    assert spec.text.startswith("#")
    assert spec.output_path and spec.output_path.endswith(".nc")


def test_shipped_sweeps_are_the_package_data():
    """sweeps/ of a clone and the package's examples are one set of files, the same texts."""
    from cosserat_channel.sweep.spec import examples

    assert examples() == {p.stem: p.read_text() for p in SWEEPS}


def test_shipped_sweeps_content():
    """The shipped sweeps ask what their headers say."""
    names = {p.name for p in SWEEPS}
    assert {"quickstart.toml", "paper_fig7.toml", "paper_fig8.toml", "paper_fig9.toml",
            "regimes_A_N.toml", "large_5d.toml"} <= names
    root = SWEEPS[0].parent
    large = load_sweep(root / "large_5d.toml")
    assert large.size >= 10_000_000 and large.material is None
    assert large.variables == ("Delta", "slip", "m_wall", "sigma_yx_wall")
    fig7 = load_sweep(root / "paper_fig7.toml")
    np.testing.assert_allclose(1 / fig7.eps[[0, -1]], [600, 5], rtol=1e-12)
    fig9 = load_sweep(root / "paper_fig9.toml")
    assert fig9.K[0] == 0 and fig9.K[-1] == 300 and np.any(np.isclose(fig9.K, 201))
    regimes = load_sweep(root / "regimes_A_N.toml")
    assert regimes.shape == (1, 1, 1, 161, 109)
    quick = load_sweep(root / "quickstart.toml")
    assert quick.material["d_p"] == 0.002 and quick.output_path == "demo/quickstart.nc"
    assert quick.profile_points is None


def test_hash_is_stable_and_tracks_text(tmp_path):
    """sha256 is the hash of the file text: equal for equal text, different after an edit."""
    a = load_sweep(_write(tmp_path, GOOD, "a.toml"))
    b = load_sweep(_write(tmp_path, GOOD, "b.toml"))
    assert a.sha256 == b.sha256 == hashlib.sha256(GOOD.encode()).hexdigest()
    c = load_sweep(_write(tmp_path, GOOD.replace("# a comment", "# another comment"), "c.toml"))
    assert c.sha256 != a.sha256


def test_mapping_input():
    """A mapping gives the same spec as the file, a canonical JSON text and no source."""
    mapping = {
        "grid": {"eps": {"logspace": [-3, -1, 5]}, "L": [2, 5, 10], "K": {"linspace": [0, 1, 3]},
                 "A": 1 / 3, "N": 1},
        "output": {"variables": ["Delta", "slip"]},
    }
    spec = load_sweep(mapping)
    assert spec.source is None
    np.testing.assert_array_equal(spec.eps, np.logspace(-3, -1, 5))
    assert spec.variables == ("Delta", "slip")
    # Key order does not change the canonical text or the hash; values do.
    reordered = {"output": mapping["output"], "grid": dict(reversed(mapping["grid"].items()))}
    assert load_sweep(reordered).sha256 == spec.sha256
    changed = copy.deepcopy(mapping)
    changed["grid"]["N"] = 2
    assert load_sweep(changed).sha256 != spec.sha256
    assert '"grid"' in spec.text


def test_grid_takes_width_and_wall_friction():
    """[grid] W (m) and delta_w (degrees) give the eps and N axes through the [material]'s d_p
    and phi, in file order; each mistake is named by its key."""
    from cosserat_channel.parameters import N_from_friction

    material = {"d_p": 0.00229, "rho_p": 1180, "phi": 30}
    spec = load_sweep({"grid": {"W": [0.155, 0.06], "L": 10, "K": 0.5, "A": 1 / 3,
                                "delta_w": {"linspace": [8, 12, 3]}}, "material": material})
    np.testing.assert_array_equal(spec.eps, [0.00229 / 0.155, 0.00229 / 0.06])
    np.testing.assert_array_equal(spec.N, [N_from_friction(30, d) for d in (8.0, 10.0, 12.0)])
    for grid, mat, named in [
        ({"W": 0.1, "eps": 0.1, "N": 1}, material, "grid: eps and W both give eps"),
        ({"W": 0.1, "N": 1}, None, "grid.W: needs a [material] table"),
        ({"W": [0.1, 0.001], "N": 1}, material, "grid.W: eps = d_p/W = 2.29 is outside"),
        ({"eps": 0.1, "delta_w": [10, 90]}, material, "grid.delta_w: delta_w = 90.0"),
        ({"eps": 0.1}, material, "missing required key(s) N (or delta_w)"),
    ]:
        mapping = {"grid": {"L": 10, "K": 0.5, "A": 0.3, **grid}}
        if mat:
            mapping["material"] = mat
        with pytest.raises(SweepError, match=re.escape(named)):
            load_sweep(mapping)


def test_output_compress_key():
    grid = {"eps": 0.1, "L": 10, "K": 0.5, "A": 0.3, "N": 1}
    assert load_sweep({"grid": grid}).compress == "zlib"
    assert load_sweep({"grid": grid, "output": {"compress": "zstd"}}).compress == "zstd"
    with pytest.raises(SweepError, match="output.compress: must be one of 'zlib', 'zstd', 'none'"):
        load_sweep({"grid": grid, "output": {"compress": "gzip"}})
