"""Which source gives the edge on a grid (``atlas.source.edge_source``): the one rule that
``boundary`` and ``plot --regime`` follow, checked on the shipped atlas and a small one saved
here (reading atlases only: nothing is solved)."""

import math

import numpy as np
import pytest

from cosserat_channel import atlas as at
from cosserat_channel.atlas.source import SourceError, edge_source

A, N = [1 / 3, 2.0], [1.5]


def test_the_shipped_atlas_answers_where_it_holds_its_tolerance():
    notes = []
    source = edge_source(A, N, note=notes.append)
    assert not source.traced and source.which == "shipped"
    assert source.boundary.attrs["atlas"].startswith("shipped atlas whole_plane.nc")
    assert not np.any(source.boundary["eta_error"].values > source.atlas.tol * (1 + 1e-9))
    assert notes == []
    # Just below A = 1/3, N = 1 the atlas states more than its tolerance for eta_min: traced,
    # with a note, unless the caller accepts any stated error (a figure, which marks it).
    notes = []
    assert edge_source([1 / 3], [0.98], note=notes.append).traced
    assert "tracing instead" in notes[0]
    drawn = edge_source([1 / 3], [0.98], tol=math.inf)
    assert not drawn.traced
    assert float(drawn.boundary["eta_error"].values.max()) > drawn.atlas.tol


def test_the_default_atlas_answers_only_for_its_own_eta_range_and_box():
    assert edge_source(A, N, eta_range=(0.01, 50.0)).traced
    assert not edge_source(A, N, eta_range=(1e-3, 100.0)).traced
    box = at.default_atlas()[0].box
    assert edge_source([box[0], box[1] + 1.0], N).traced


def test_trace_asked_is_traced_and_two_sources_are_refused(tmp_path):
    assert edge_source(A, N, trace=True).traced
    with pytest.raises(SourceError) as exc:
        edge_source(A, N, atlas=str(tmp_path / "a.nc"), trace=True)
    assert exc.value.parameter == "trace"


def test_a_given_atlas_answers_for_its_own_range_and_says_where_it_does_not_cover(tmp_path):
    shipped = at.default_atlas()[0]
    path = tmp_path / "mine.nc"
    at.save_atlas(shipped, path)
    notes = []
    source = edge_source([0.0, 1.0], N, atlas=str(path), note=notes.append)
    assert not source.traced and source.which is None and source.path == str(path)
    assert source.boundary.attrs["atlas"].startswith("atlas mine.nc")
    assert notes == []
    wide = [shipped.box[0], shipped.box[1] + 1.0]
    source = edge_source(wide, N, atlas=str(path), note=notes.append)
    assert not source.traced and "outside it the edge is not drawn" in notes[0]
    assert np.isnan(source.boundary["eta_max"].values[1]).all()
    with pytest.raises(SourceError) as exc:
        edge_source(A, N, atlas=str(path), eta_range=(0.01, 50.0))
    assert exc.value.parameter == "eta_range" and "differs from the atlas's" in str(exc.value)
    with pytest.raises(SourceError) as exc:
        edge_source(A, N, atlas=str(tmp_path / "missing.nc"))
    assert exc.value.parameter == "atlas"
