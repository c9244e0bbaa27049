"""The joint polish of a segmentation's charts (atlas/polish.py)."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology
from heatparam.atlas.polish import polish_charts
from heatparam.atlas.segment import segment
from heatparam.refine import RefineParams


@pytest.fixture(scope="module")
def charts():
    """A torus segmented to 1.05: (topology, segmentation, each chart's faces)."""
    topo = Topology.build(*datasets.torus(n_major=24, n_minor=10))
    seg = segment(topo, 1.05)
    return topo, seg, [np.flatnonzero(seg.chart == c) for c in np.unique(seg.chart)]


def test_polished_charts_are_bijective_and_less_distorted(charts):
    topo, seg, groups = charts
    done, rest, rep = polish_charts(topo, groups, seg, limit=1.05, params=RefineParams())
    assert len(done) + len(rest) == len(groups) == rep["charts"] and len(done) > len(rest)
    assert rep["iterations"] > 0 and all(c.info["iso_mean"] <= 1.05 and c.info["flips"] == 0 for c in done)
    polished, _, _ = polish_charts(topo, groups, seg, limit=None, params=RefineParams())
    kept, _, rep0 = polish_charts(topo, groups, seg, limit=None, params=None)
    assert not rep0["used"] and len(polished) == len(kept) == len(groups)
    assert sum(c.info["iso_mean"] for c in polished) < sum(c.info["iso_mean"] for c in kept)
    for c, g in zip(polished, groups, strict=True):
        assert np.array_equal(c.faces, g) and len(c.Fl) == len(g) and len(c.uv) == len(c.vert)


def test_a_chart_over_the_limit_is_left_to_the_caller(charts):
    topo, seg, groups = charts
    done, rest, _ = polish_charts(topo, groups, seg, limit=1.0, params=None)
    assert not done and rest == list(range(len(groups)))
