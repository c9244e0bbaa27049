"""Segmentation (atlas/segment.py): every chart's checked layout is bijective, and a region that fails its check is
split from its own seeds."""

from __future__ import annotations

import numpy as np

import heatparam.atlas.segment as segment_module
from heatparam import datasets
from heatparam.atlas.chart_topology import Topology
from heatparam.atlas.segment import proxy_bound, segment


def test_segmented_charts_layouts_are_bijective():
    """Every chart's checked layout (``Segmentation.corner_uv``) has no flipped face, no two overlapping triangles
    (an exact check, independent of the border crossings the merges test) and stays within the bound; the excess
    cone with a loose bound makes the merges depend on the crossing test alone."""
    from heatparam.atlas.overlap import count_overlaps

    from conftest import excess_cone

    for (V, F), bound in ((datasets.torus(n_major=24, n_minor=10), 1.05), (excess_cone(), 50.0)):
        seg = segment(Topology.build(V, F), bound)
        k = int(seg.chart.max()) + 1
        assert seg.checked.all() and (seg.iso <= proxy_bound(bound)).all()
        for c in range(k):
            faces = np.flatnonzero(seg.chart == c)
            corners = 3 * faces[:, None] + np.arange(3)
            U = seg.corner_uv[corners]
            e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
            assert (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0).all()
            assert count_overlaps(seg.corner_uv, corners) == 0
        if bound > 2:
            assert k >= 2  # the whole cone in one chart would overlap itself


def test_a_failing_region_is_split_from_its_own_seeds_at_the_same_cone(monkeypatch):
    """Segmentation step 2: a region whose quick flattening fails is grown again at the same cone from
    ``SPLIT_SEEDS`` farthest seeds of its own (not shrunk with a narrower cone), into at least two pieces, each
    checked in turn; the pieces of one generation are flattened in one solve."""
    calls, flattened = [], []
    real_grow, real_flatten = segment_module.grow, segment_module.flatten_charts

    def grow(topo, faces, cone, target, seed=0):
        out = real_grow(topo, faces, cone, target, seed)
        calls.append((len(faces), cone, target, len(out)))
        return out

    def flatten(topo, charts, glued, bound=np.inf):
        flattened.append(len(charts))
        return real_flatten(topo, charts, glued, bound)

    real_merge = segment_module.merge

    def merge(*a, **k):
        flattened.append("merge")
        return real_merge(*a, **k)

    monkeypatch.setattr(segment_module, "grow", grow)
    monkeypatch.setattr(segment_module, "flatten_charts", flatten)
    monkeypatch.setattr(segment_module, "merge", merge)
    V, F = datasets.torus()
    seg = segment(Topology.build(V, F), 1.05)
    first, *splits = calls
    assert seg.stats["regrown"] == len(splits) > 1
    for n, cone, target, pieces in splits:
        assert cone == first[1] and target == -(-n // segment_module.SPLIT_SEEDS) and pieces >= 2
    growth = flattened[:flattened.index("merge")]  # the regions' checks, one flattening per generation
    assert sum(growth) == seg.stats["grown"] == first[3] + sum(p for *_, p in splits)
    assert growth[0] == first[3] and len(growth) < 1 + len(splits)  # splits of one generation flattened together
    assert seg.checked.all()
