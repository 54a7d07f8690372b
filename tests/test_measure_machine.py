"""measure/machine.py: what every report and benchmark prints about where it ran."""

import re

from cosserat_channel.measure import machine


def test_cpu_model_and_machine_line():
    """A CPU model (never empty), and the machine line with the core count and the OS."""
    cpu = machine.cpu_model()
    assert cpu.strip()
    line = machine.machine()
    assert line.startswith(cpu + ", ") and re.search(r", \d+ cores, ", line)


def test_versions_name_the_solver_exactly():
    """Version, git revision and source digest of the package, then the libraries, extras last."""
    text = machine.versions(dask="9.9", numbalsoda="not installed")
    assert text.startswith("cosserat-channel ")
    assert re.search(r"package sources sha256 [0-9a-f]{12}\)", text)
    for lib in ("Python", "numba", "numpy", "scipy"):
        assert f", {lib} " in text
    assert text.endswith(", dask 9.9, numbalsoda not installed")
    assert re.fullmatch(r"[0-9a-f]{12}", machine.source_digest())
    assert machine.git_revision()  # a short hash, or "unknown" outside a checkout
