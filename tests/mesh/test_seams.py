"""mesh: validation lives in test_io/test_cli (bad input at the door); here the seams that cut holes open."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from heatparam import datasets
from heatparam.mesh import boundary_loops, cut_open, edge_graph, hole_seams, validate_mesh
from heatparam.operators import edge_lengths


@pytest.fixture(scope="module")
def holes():
    s = datasets.cylinder_with_holes()
    return s, validate_mesh(s.V, s.F)


def _edges(F):
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    return {tuple(e) for e in E.tolist()}


def test_seams_join_every_hole_to_the_border(holes):
    s, info = holes
    loops = info.boundary_loops
    paths = hole_seams(s.V, s.F, loops)
    assert len(paths) == len(loops) - 1 == 2
    owner = np.full(len(s.V), -1)
    for i, lp in enumerate(loops):
        owner[lp] = i
    edges = _edges(s.F)
    joined = []
    for p in paths:
        assert owner[p[0]] >= 0 and owner[p[-1]] >= 0 and owner[p[0]] != owner[p[-1]]  # two different loops
        assert (owner[p[1:-1]] < 0).all()  # through interior vertices only
        assert all(tuple(sorted(e)) in edges for e in zip(p[:-1].tolist(), p[1:].tolist(), strict=True))
        joined.append({int(owner[p[0]]), int(owner[p[-1]])})
    # a spanning tree of the three loops: both holes reach the border, directly or through the other hole
    assert set().union(*joined) == {0, 1, 2} and joined[0] != joined[1]


def test_seams_are_the_shortest_links(holes):
    """Each seam is as short as the shortest edge path between its two loops (Dijkstra from one loop), and the
    tree is the cheapest: its total is at most any other two links that span the three loops."""
    s, info = holes
    loops = info.boundary_loops
    G = edge_graph(s.F, edge_lengths(s.V, s.F), len(s.V))
    d = {i: dijkstra(G, directed=False, indices=lp, min_only=True) for i, lp in enumerate(loops)}
    link = {(i, j): d[i][loops[j]].min() for i in range(3) for j in range(3) if i < j}
    owner = {int(v): i for i, lp in enumerate(loops) for v in lp}
    total = 0.0
    for p in hole_seams(s.V, s.F, loops):
        length = np.linalg.norm(np.diff(s.V[p], axis=0), axis=1).sum()
        i, j = sorted((owner[int(p[0])], owner[int(p[-1])]))
        assert length == pytest.approx(link[i, j], rel=1e-12)
        total += length
    assert total == pytest.approx(sum(link.values()) - max(link.values()), rel=1e-12)


def test_cut_open_leaves_a_disk(holes):
    s, info = holes
    paths = hole_seams(s.V, s.F, info.boundary_loops)
    Vs, Fs, src = cut_open(s.V, s.F, paths)
    cut = validate_mesh(Vs, Fs)
    assert cut.n_holes == 0 and len(cut.boundary_loops) == 1
    assert np.array_equal(Vs, s.V[src]) and np.array_equal(src[Fs], s.F)  # the same faces, row for row
    on_seam = np.unique(np.concatenate(paths))
    assert len(Vs) == len(s.V) + len(on_seam)  # every seam vertex split in two (disjoint seams)
    assert np.array_equal(np.bincount(src, minlength=len(s.V))[on_seam], np.full(len(on_seam), 2))
    # the new border runs along both sides of every seam: its length grows by twice the seams' length
    seam_len = sum(np.linalg.norm(np.diff(s.V[p], axis=0), axis=1).sum() for p in paths)
    border = sum(np.linalg.norm(Vs[lp] - Vs[np.roll(lp, -1)], axis=1).sum() for lp in cut.boundary_loops)
    before = sum(np.linalg.norm(s.V[lp] - s.V[np.roll(lp, -1)], axis=1).sum() for lp in info.boundary_loops)
    assert border == pytest.approx(before + 2 * seam_len, rel=1e-12)
    assert boundary_loops(Fs)[0].size == cut.boundary_loops[0].size


def test_no_holes_no_seams():
    s = datasets.cylinder_patch()
    info = validate_mesh(s.V, s.F)
    assert hole_seams(s.V, s.F, info.boundary_loops) == []
    Vs, Fs, src = cut_open(s.V, s.F, [])
    assert np.array_equal(Vs, s.V) and np.array_equal(Fs, s.F) and np.array_equal(src, np.arange(len(s.V)))
