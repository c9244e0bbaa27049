"""Region growing (atlas/grow.py): farthest-point seeds, regions that are disks, halves of a chart."""

from __future__ import annotations

import numpy as np

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology
from heatparam.atlas.grow import farthest_seeds, grow, halves

from hostile import split_edge


def test_seeds_from_the_direct_csr_graph_match_the_coo_graph():
    """farthest_seeds builds the face graph's CSR arrays directly (its rows ascend); forced through COO (the path of
    a mesh with a two-faced pocket, where COO sums the duplicate entry) it picks the same seeds on random face sets."""
    V, F = datasets.torus(n_major=24, n_minor=10)
    direct, coo = Topology.build(V, F), Topology.build(V, F)
    assert not direct.double_neighbours()
    coo._double = True
    rng = np.random.default_rng(5)
    for _ in range(20):
        faces = np.sort(rng.choice(len(F), size=int(rng.integers(2, len(F))), replace=False))
        k, seed = int(rng.integers(1, 6)), int(rng.integers(0, 3))
        assert np.array_equal(farthest_seeds(direct, faces, k, seed), farthest_seeds(coo, faces, k, seed))
    pillow = Topology.build(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 1]]))
    assert pillow.double_neighbours()  # two faces, neighbours across all three edges
    assert sorted(farthest_seeds(pillow, np.arange(2), 2, 0).tolist()) == [0, 1]


def _is_disk(topo, faces) -> bool:
    """Euler characteristic 1 and one piece: V - E + F of the faces welded inside."""
    from heatparam.atlas.chart_topology import chart_mesh, glue_inside

    Vl, Fl, _ = chart_mesh(topo, faces, glue_inside(topo, faces))
    a, b = Fl.ravel(), Fl[:, [1, 2, 0]].ravel()
    edges = len(np.unique(np.minimum(a, b) * len(Vl) + np.maximum(a, b)))
    return len(Vl) - edges + len(Fl) == 1


def test_grown_regions_cover_the_faces_once_each_a_disk():
    V, F = datasets.torus(n_major=24, n_minor=10)
    topo = Topology.build(V, F)
    regions = grow(topo, np.arange(len(F)), 60.0, 80)
    assert len(regions) > 1
    assert np.array_equal(np.sort(np.concatenate(regions)), np.arange(len(F)))
    assert all(_is_disk(topo, r) for r in regions)


def test_halves_split_a_chart_into_two_welded_disks():
    V, F = datasets.capped_cylinder(n_theta=24, n_z=8)
    topo = Topology.build(V, F)
    faces = grow(topo, np.arange(len(F)), 60.0, len(F))[0]
    parts = halves(topo, faces, np.zeros(3 * len(F), dtype=bool), 0)
    assert len(parts) == 2
    assert np.array_equal(np.sort(np.concatenate([p for p, _ in parts])), faces)
    for p, glued in parts:
        assert _is_disk(topo, p) and glued[(3 * p[:, None] + np.arange(3)).ravel()].any()
    assert halves(topo, faces[:1], np.zeros(3 * len(F), dtype=bool), 0) == []


def test_halves_split_where_growing_leaves_one_piece(monkeypatch):
    """Where growing from the two seeds leaves one piece (on a CAD part's flat chart the first seed took every face,
    and the chart the pipeline refused became one chart per face), each face goes to the nearer seed on the face
    graph: two connected halves of like size."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    import heatparam.atlas.grow as grow_module

    s = datasets.flat_square(h=0.05)
    topo = Topology.build(s.V, s.F)
    faces = np.arange(len(s.F))
    monkeypatch.setattr(grow_module, "grow", lambda topo, faces, *a: [faces])
    parts = halves(topo, faces, np.zeros(3 * len(s.F), dtype=bool), 0)
    assert len(parts) == 2
    assert np.array_equal(np.sort(np.concatenate([p for p, _ in parts])), faces)
    for p, glued in parts:
        assert 0.4 < len(p) / len(faces) < 0.6
        h = (3 * p[:, None] + np.arange(3)).ravel()
        inner = h[glued[h]]
        loc = np.searchsorted(p, np.stack([inner // 3, topo.opp[inner] // 3]))
        G = sp.coo_matrix((np.ones(len(inner)), (loc[0], loc[1])), shape=(len(p), len(p)))
        assert connected_components(G, directed=False)[0] == 1
    assert halves(topo, faces[:1], np.zeros(3 * len(s.F), dtype=bool), 0) == []


def test_zero_area_faces_grow_into_their_neighbours_regions_even_as_seeds():
    """A zero-area face joins a region with faces that have an area, whether it is reached or picked as a seed (its
    region's normal is its neighbour's until a face with an area joins)."""
    V, F = datasets.torus(n_major=24, n_minor=10)
    for f in (3, 100, 400):
        V, F = split_edge(V, F, f)
    topo = Topology.build(V, F)
    zero = np.arange(len(F) - 3 * 2 + 1, len(F), 2)  # split_edge's zero-area faces: every second new row
    assert np.allclose(topo.areas[zero], 0.0)
    for seed in range(4):
        regions = grow(topo, np.arange(len(F)), 60.0, 80, seed)
        assert np.array_equal(np.sort(np.concatenate(regions)), np.arange(len(F)))
        assert all(len(r) > 1 and _is_disk(topo, r) for r in regions if np.isin(zero, r).any())
    for g in topo.opp[3 * zero[0]:3 * zero[0] + 3] // 3:  # the zero-area face and a neighbour: one region,
        pair = np.sort([zero[0], g])  # whichever of the two seeds it
        seeds = {int(farthest_seeds(topo, pair, 1, seed)[0]) for seed in range(8)}
        assert seeds == set(pair.tolist())
        for seed in range(8):
            assert [r.tolist() for r in grow(topo, pair, 60.0, 2, seed)] == [pair.tolist()]
