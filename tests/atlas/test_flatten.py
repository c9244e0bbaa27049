"""Quick flattenings of many charts in one LSCM solve (atlas/flatten.py): each chart gets the map it gets alone,
whatever the row order, and its own flips, crossings and disk test."""

from __future__ import annotations

import numpy as np

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology, chart_mesh
from heatparam.atlas.flatten import (
    flatten_charts,
    flatten_components,
    lscm,
    lscm_groups,
    quick_flatten,
    segment_layout,
    triangle_layout,
)
from heatparam.atlas.segment import segment

from conftest import slit_fan
from hostile import split_edge


def _torus_charts():
    V, F = datasets.torus(n_major=24, n_minor=10)
    topo = Topology.build(V, F)
    seg = segment(topo, 1.05)
    return topo, seg, [np.flatnonzero(seg.chart == c) for c in range(int(seg.chart.max()) + 1)]


def test_charts_flattened_together_match_each_alone():
    topo, seg, groups = _torus_charts()
    assert len(groups) >= 3
    fl = flatten_charts(topo, groups, seg.glued)
    for i, faces in enumerate(groups):
        alone = flatten_charts(topo, [faces], seg.glued)
        assert np.isclose(fl.iso[i], alone.iso[0], rtol=1e-9) and fl.flips[i] == alone.flips[0]
        Vl, Fl, vert, uv = fl.chart(i)
        assert len(Fl) == len(faces) and (np.sort(vert) == np.sort(alone.vert)).all()
        # the same map up to a rigid motion: equal edge lengths, face by face (both list the chart's faces in
        # order; a vertex on a seam inside the chart has several rows, so rows are not matched by vertex)
        A = uv[Fl]
        Vb, Fb, vb, uvb = alone.chart(0)
        assert (vb[Fb] == vert[Fl]).all()
        B = uvb[Fb]
        la = np.linalg.norm(A[:, 1] - A[:, 0], axis=1)
        lb = np.linalg.norm(B[:, 1] - B[:, 0], axis=1)
        np.testing.assert_allclose(la, lb, rtol=1e-7, atol=1e-12)
    assert fl.ok(np.inf).all()  # the segmentation's charts are bijective under the proxy


def test_pins_do_not_depend_on_the_row_order():
    """LSCM's map depends on its two pins; they come from the geometry, so listing a chart's faces in another
    order gives the same distortion (a merge test and the final flattening agree)."""
    topo, seg, groups = _torus_charts()
    big = max(groups, key=len)
    rng = np.random.default_rng(3)
    a = flatten_charts(topo, [big], seg.glued)
    b = flatten_charts(topo, [rng.permutation(big)], seg.glued)
    assert np.isclose(a.iso[0], b.iso[0], rtol=1e-9)


def test_charts_not_wanted_get_their_meshes_but_no_layout():
    """``flatten_charts(want=)`` (the joint polish lays out only the charts without a checked layout): the others
    keep their meshes and disk tests, get no layout (iso inf, crossings not checked), and the wanted charts get the
    layouts they get in a full flattening."""
    topo, seg, groups = _torus_charts()
    want = np.arange(len(groups)) % 2 == 0
    full = flatten_charts(topo, groups, seg.glued)
    part = flatten_charts(topo, groups, seg.glued, want=want)
    np.testing.assert_array_equal(part.Fl, full.Fl)
    np.testing.assert_array_equal(part.disk, full.disk)
    assert np.isinf(part.iso[~want]).all() and (part.crossings[~want] == -1).all()
    np.testing.assert_allclose(part.iso[want], full.iso[want], rtol=1e-9)
    for i in np.flatnonzero(want):
        np.testing.assert_allclose(part.chart(i)[3], full.chart(i)[3], atol=1e-9)


def test_each_chart_reports_its_own_failures():
    """A non-disk union (two charts glued along everything they share, closing a loop) and a folded chart sit in
    the same batch as good charts: only they fail."""
    V, F = datasets.torus(n_major=16, n_minor=8)
    topo = Topology.build(V, F)
    ring = np.arange(len(F))  # the whole torus welded: not a disk
    whole = np.ones(3 * len(F), dtype=bool)
    fl = flatten_charts(topo, [ring], whole)
    assert not fl.disk[0] and not fl.ok(np.inf)[0]
    one = np.array([0])
    fl = flatten_charts(topo, [one, np.array([5, 6])], np.zeros(3 * len(F), dtype=bool))
    assert fl.disk[0] and fl.ok(np.inf)[0] and not fl.disk[1]  # faces 5 and 6 unwelded: two pieces


def test_quick_flatten_of_a_flat_chart_is_an_isometry():
    s = datasets.flat_square(h=0.1)
    uv, iso, bij = quick_flatten(s.V, s.F)
    assert bij and iso < 1.0 + 1e-7  # an exact isometry, to the sparse solve's accuracy (~1e-9 measured)
    topo = Topology.build(s.V, s.F)
    Vl, Fl, _ = chart_mesh(topo, np.arange(len(s.F)), np.ones(3 * len(s.F), dtype=bool))
    assert len(Fl) == len(s.F)


def test_lscm_lays_a_zero_area_face_out_as_a_thin_triangle_of_the_right_orientation():
    """igl's cotangents are NaN on a zero-area face (the whole layout was NaN, the chart never passed its check); the
    mollified least-squares map lays it out thin and positive, its neighbours as before to within the mollification."""
    s = datasets.flat_disk(h=0.2)
    V, F = split_edge(s.V, s.F, 30)
    uv, iso, bijective = quick_flatten(V, F)
    assert bijective and np.isfinite(uv).all() and iso < 1.01
    T = uv[F]
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    sa = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert (sa > 0).all() and sa[-1] < 0.05 * np.median(sa)  # the zero-area face: the last one
    plain, _, _ = quick_flatten(s.V, s.F)
    assert np.abs(uv[:len(s.V)] - plain).max() < 1e-3  # the flat disk's own map, all but unchanged


def test_lscm_without_zero_area_faces_is_igls():
    import igl

    s = datasets.cylinder_patch(h=0.2)
    b, bc = np.array([0, 5]), np.array([[0.0, 0.0], [1.0, 0.0]])
    res = igl.lscm(s.V, s.F, b, bc)
    assert np.array_equal(lscm(s.V, s.F, b, bc), np.asarray(res[0] if isinstance(res, tuple) else res))


def test_segment_layout_keeps_every_length():
    V = np.array([[0.0, 0, 0], [1, 1, 1], [3, 3, 3], [2, 2, 2], [9, 9, 9]])
    F = np.array([[0, 2, 1], [1, 2, 3]])
    uv = segment_layout(V, F)
    for f in F:
        for i, j in ((0, 1), (1, 2), (2, 0)):
            assert np.isclose(np.linalg.norm(uv[f[i]] - uv[f[j]]), np.linalg.norm(V[f[i]] - V[f[j]]))
    assert (uv[:, 1] == 0).all() and (uv[4] == 0).all()  # on one line; the unused row at 0
    bent = np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0]])  # two point-like faces, not on one line
    assert segment_layout(bent, np.array([[0, 1, 2], [1, 0, 3]])) is None


def test_triangle_layout_keeps_a_slivers_lengths_and_area():
    """A sliver (area 6e-10 of its longest edge squared, pybullet's diff_carrier_cover.stl) has no finite LSCM
    layout; laid out exactly it keeps its three lengths and its area, counter-clockwise."""
    V = np.array([[5.0, -17.42691993713379, 10.418510437011719], [5.0, -17.42691993713379, 10.418511390686035],
                  [5.0, -17.42691993713379, 10.418512344360352]])
    V[:, 0] = [14.000001907348633, 0.7090072631835938, -13.022712707519531]
    F = np.array([[0, 1, 2]])
    assert quick_flatten(V, F)[0] is None
    uv = triangle_layout(V, F)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        assert np.isclose(np.linalg.norm(uv[i] - uv[j]), np.linalg.norm(V[i] - V[j]), rtol=1e-12)
    a3 = 0.5 * np.linalg.norm(np.cross(V[1] - V[0], V[2] - V[0]))
    e1, e2 = uv[1] - uv[0], uv[2] - uv[0]
    assert np.isclose(0.5 * (e1[0] * e2[1] - e1[1] * e2[0]), a3, rtol=1e-9)


def test_a_chart_whose_border_touches_itself_is_refused():
    """A flat fan cut open along one edge is a disk whose every isometric layout closes the cut, the border
    touching itself at the centre (a CAD part's chart folded round a vertex whose angles add up to 2π): its
    flattening is not a proof of bijectivity, whichever way rounding puts the cut's sides (a hair apart, or a hair
    across: the edge test alone caught some of these fans and not others). Lifted into a cone (less than 2π at
    the centre) it is."""
    for sectors in range(5, 17):
        for apex, ok in ((0.0, False), (0.4, True)):
            V, F = slit_fan(sectors, apex=apex)
            _, iso, flips, cross, disk, _ = flatten_components(V, F, np.zeros(len(F), dtype=np.int64), 1)
            assert disk[0] and flips[0] == 0 and iso[0] < 1.01
            assert (cross[0] == 0) == ok, (sectors, apex)


def test_a_chart_with_a_zero_area_face_does_not_mollify_the_others():
    """Charts flattened together with one that has a zero-area face: only that one is laid out on mollified
    triangles. Mollified with it, slivers (a CAD part's: edges of 1e-3, a height of 1e-6) came out at iso 10.9."""
    rng = np.random.default_rng(0)
    s = datasets.flat_square(h=0.1)
    V0 = s.V.copy()
    V0[:, 2] = 0.2 * np.sin(2 * V0[:, 0])
    Vs, Fs, n = [V0], [s.F], len(V0)
    for j in range(4):  # slivers, one chart each
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        Vs.append(np.array([0.26, 0.1 * j, 0.05]) + np.array([[0, 0, 0], [3.5e-3, 0, 0], [8.7e-4, 7e-7, 0]]) @ R.T)
        Fs.append(np.array([[n, n + 1, n + 2]]))
        n += 3
    fgroup = np.r_[np.zeros(len(s.F), dtype=np.int64), np.arange(1, 5)]
    V, F = np.vstack(Vs), np.vstack(Fs)
    uv, iso, _, _, _, vgroup = flatten_components(V, F, fgroup, 5)
    # a chart of two faces, one of zero area (its corners on a line)
    Vz = np.vstack([V, [[5.0, 0, 0], [6, 0, 0], [5.5, 1, 0], [5.5, 0, 0]]])
    Fz = np.vstack([F, [[n, n + 3, n + 2], [n, n + 1, n + 3]]])
    uvz, isoz, flipsz, _, _, _ = flatten_components(Vz, Fz, np.r_[fgroup, 5, 5], 6)
    np.testing.assert_allclose(isoz[1:5], 1.0, atol=1e-9)
    np.testing.assert_array_equal(uvz[:n], uv)  # the others as without it
    assert flipsz[5] == 0 and isoz[5] < 1.05


def test_pinned_groups_with_a_zero_area_face_are_solved_apart():
    """The merges' and the straightening's extensions (several small charts pinned in one solve): a group with a
    zero-area face is laid out on mollified triangles apart, the others exactly as without it."""
    V = np.array([[0.0, 0, 0], [3.5e-3, 0, 0], [8.7e-4, 7e-7, 0],  # a sliver, pinned on its long edge
                  [5.0, 0, 0], [6, 0, 0], [5.5, 1, 0], [5.5, 0, 0]])  # a face and a zero-area face
    F = np.array([[0, 1, 2], [3, 6, 5], [3, 4, 6]])
    b, bc = np.array([0, 1, 3, 4]), np.array([[0.0, 0], [3.5e-3, 0], [5, 0], [6, 0]])
    uv = lscm_groups(V, F, np.array([0, 1, 1]), b, bc, np.array([False, False, True]))
    alone = lscm_groups(V[:3], F[:1], np.array([0]), b[:2], bc[:2], np.array([False]))
    np.testing.assert_array_equal(uv[:3], alone)
    np.testing.assert_allclose(uv[2], V[2, :2], atol=1e-12)  # the sliver exact
    mollified = lscm(V, F, b, bc, degenerate=True)  # all in one mollified solve: the sliver strays
    assert np.abs(mollified[2] - V[2, :2]).max() > 1e-7
