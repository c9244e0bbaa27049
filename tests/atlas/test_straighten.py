"""Seam straightening (atlas/straighten.py): a seam between two charts replaced by the shortest path between its
ends through them, kept where both charts still flatten bijectively within the bound."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology, chart_mesh, glue_inside
from heatparam.atlas.flatten import flatten_charts
from heatparam.atlas.merge import Layouts
from heatparam.atlas.straighten import Straightening

from conftest import assert_corner_lengths_kept


def _wavy_pair(crease: bool = False):
    """A flat square split by a wavy line into charts 0 (left) and 1, each laid out by LSCM: (topo, chart, glued,
    layouts). ``crease``: the seam's edges marked as creases (a feature line)."""
    s = datasets.flat_square(h=0.08)
    C = s.V[s.F].mean(axis=1)
    left = C[:, 0] < 0.25 * np.sin(4 * C[:, 1])
    topo = Topology.build(s.V, s.F)
    chart = np.where(left, 0, 1)
    charts = [np.flatnonzero(left), np.flatnonzero(~left)]
    glued = glue_inside(topo, charts[0]) | glue_inside(topo, charts[1])
    if crease:
        h = np.arange(3 * len(s.F))
        topo.crease[(topo.opp >= 0) & (chart[h // 3] != chart[np.maximum(topo.opp, 0) // 3])] = True
    fl = flatten_charts(topo, charts, glued)
    layouts = Layouts(len(s.F))
    layouts.add([0, 1], charts, fl, [0, 1], [True, True])
    return topo, chart, glued, layouts


def _seam_ends(topo, chart):
    h = np.arange(len(topo.opp))
    seam = (topo.opp > h) & (chart[h // 3] != chart[np.maximum(topo.opp, 0) // 3])
    ha, hb = topo.ends()
    v = np.concatenate([ha[seam], hb[seam]])
    ends = np.flatnonzero(np.bincount(v) == 1)
    return ends, float(topo.hlen[seam].sum())


def test_a_wavy_seam_becomes_the_shortest_path_and_the_layouts_stay_exact():
    """On a flat square the wavy seam is replaced by the shortest edge path between its ends (the square is convex:
    the mesh's own shortest path, as scipy finds it); both charts stay disks, and their layouts (the kept faces
    where they were, the moved faces their extension) are still an exact isometry: every corner-to-corner length
    as in 3D."""
    topo, chart, glued, layouts = _wavy_pair()
    ends, before = _seam_ends(topo, chart)
    ha, hb = topo.ends()
    G = sp.csr_matrix((topo.hlen, (ha, hb)), shape=(len(topo.V),) * 2)
    shortest = float(dijkstra(G, directed=False, indices=ends[0])[ends[1]])
    stats = Straightening(topo, chart, glued, layouts, 1.0 + 1e-7).run()
    assert stats["straightened"] == 1
    ends_after, after = _seam_ends(topo, chart)
    assert set(ends_after) == set(ends)  # the ends stay where they were
    assert after < 0.8 * before
    np.testing.assert_allclose(after, shortest, rtol=1e-12)
    assert stats["seam_length"] == [round(before, 6), round(after, 6)]
    for c in (0, 1):
        faces = np.flatnonzero(chart == c)
        _, Fl, vert = chart_mesh(topo, faces, glued)
        n_edges = len(np.unique(np.sort(np.concatenate([Fl[:, [0, 1]], Fl[:, [1, 2]], Fl[:, [2, 0]]]), axis=1),
                                axis=0))
        assert len(vert) - n_edges + len(Fl) == 1  # a disk
    assert_corner_lengths_kept(layouts.uv, topo.V, topo.F, rtol=1e-6)
    assert layouts.checked().all()


def test_a_seam_along_a_crease_stays():
    """A seam on a feature line (every edge a crease) is left where it is."""
    topo, chart, glued, layouts = _wavy_pair(crease=True)
    before = chart.copy()
    stats = Straightening(topo, chart, glued, layouts, 1.0 + 1e-7).run()
    assert stats["straightened"] == 0 and stats["tried"] == 0
    assert (chart == before).all()


def test_a_straightening_over_the_bound_is_not_kept():
    """When the straightened charts cannot be laid out within the bound (here a bound below any map's), the charts,
    their glued half-edges and their layouts stay as they were."""
    topo, chart, glued, layouts = _wavy_pair()
    before = (chart.copy(), glued.copy(), layouts.uv.copy())
    stats = Straightening(topo, chart, glued, layouts, 0.5).run()
    assert stats["tried"] == 1 and stats["straightened"] == 0
    assert (chart == before[0]).all() and (glued == before[1]).all() and (layouts.uv == before[2]).all()
