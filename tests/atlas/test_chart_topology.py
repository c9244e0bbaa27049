"""A chart's own mesh (atlas/chart_topology.py): corners welded across the glued half-edges only, as the connected
components of the corner graph."""

from __future__ import annotations

import numpy as np

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology, chart_mesh, glue_inside

from hostile import split_edge


def _chart_mesh_by_scipy(topo, faces, glued, group):
    """The reference for :func:`chart_mesh`: corners welded across glued half-edges (within a group), labelled by
    ``scipy.sparse.csgraph.connected_components`` of the corner graph, the first corner naming each vertex."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    k, m = len(faces), len(topo.F)
    rows = {(int(g), int(f)): i for i, (g, f) in enumerate(zip(group, faces, strict=True))}
    r, c = [], []
    for i, (g, f) in enumerate(zip(group, faces, strict=True)):
        for j in range(3):
            o = int(topo.opp[3 * f + j])
            if o < 0 or not glued[3 * f + j] or (int(g), o // 3) not in rows:
                continue
            b, kk = rows[(int(g), o // 3)], o % 3
            r += [3 * i + j, 3 * i + (j + 1) % 3]
            c += [3 * b + (kk + 1) % 3, 3 * b + kk]
    G = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(3 * k, 3 * k))
    _, lab = connected_components(G, directed=False)
    first = np.array([np.flatnonzero(lab == x)[0] for x in range(lab.max() + 1)])
    assert m  # (a mesh)
    return lab.reshape(k, 3), topo.F[faces].ravel()[first]


def test_chart_mesh_welds_corners_as_connected_components_do():
    """chart_mesh labels welded corners by pointer jumping along each vertex's fan: the labels and vertices of
    scipy's connected components, on random face sets, glued half-edges (symmetric or not) and groups (disjoint,
    and with faces in several groups), on meshes with poles of high valence (capped cylinder: 48 faces)."""
    rng = np.random.default_rng(7)
    for V, F in (datasets.capped_cylinder(n_theta=48, n_z=4), datasets.torus(n_major=16, n_minor=8),
                 datasets.closed_cube(n=3)):
        topo = Topology.build(V, F)
        m = len(F)
        for t in range(12):
            faces = np.sort(rng.choice(m, size=int(rng.integers(1, m)), replace=False))
            glued = rng.random(3 * m) < (1.0 if t % 4 == 0 else rng.random())
            if t % 3 == 0:
                glued |= glued[np.maximum(topo.opp, 0)] & (topo.opp >= 0)
            group = np.zeros(len(faces), dtype=np.int64)
            if t % 2:
                more = np.sort(rng.choice(m, size=int(rng.integers(1, m)), replace=False))
                if t % 4 == 1:
                    more = np.setdiff1d(more, faces)  # disjoint groups (the table path)
                faces = np.concatenate([faces, more])
                group = np.r_[group, np.ones(len(more), dtype=np.int64)]
            Vl, Fl, vert = chart_mesh(topo, faces, glued, group)
            lab, ref_vert = _chart_mesh_by_scipy(topo, faces, glued, group)
            assert np.array_equal(Fl, lab) and np.array_equal(vert, ref_vert)
            assert np.array_equal(Vl, V[vert])


def test_glue_inside_welds_exactly_the_edges_between_the_faces():
    V, F = datasets.closed_cube(n=3)
    topo = Topology.build(V, F)
    faces = np.arange(0, len(F), 2)
    g = glue_inside(topo, faces)
    inside = np.isin(np.arange(len(F)), faces)
    h = np.arange(3 * len(F))
    want = inside[h // 3] & (topo.opp >= 0) & inside[np.maximum(topo.opp, 0) // 3]
    np.testing.assert_array_equal(g, want)


def test_cube_corners_are_cones_and_its_edges_creases():
    V, F = datasets.closed_cube(n=3)
    topo = Topology.build(V, F)
    corners = np.flatnonzero(np.abs(topo.defect) > 1.0)
    assert len(corners) == 8 and all(topo.cones()[v] for v in corners)
    np.testing.assert_allclose(topo.defect[corners], np.pi / 2)
    assert topo.crease.any() and not topo.crease[topo.opp < 0].any()


def test_a_zero_area_face_takes_a_neighbours_normal_and_no_crease():
    """A zero-area face has no normal of its own: with a zero one every edge of it was a crease (issue 45)."""
    V, F = datasets.closed_cube(n=4)
    V, F = split_edge(V, F, 5)
    topo = Topology.build(V, F)
    z = len(F) - 1  # split_edge's zero-area face
    nb = topo.opp[3 * z:3 * z + 3] // 3
    assert any(np.array_equal(topo.normals[z], topo.normals[g]) for g in nb)
    assert np.isclose(np.linalg.norm(topo.normals[z]), 1.0) and not topo.crease[3 * z:3 * z + 3].all()
