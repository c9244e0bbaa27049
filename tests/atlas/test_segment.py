"""Segmentation's batched flattenings (atlas/segment.py): many charts in one LSCM solve give each chart the map it
gets alone, whatever the row order, and report each chart's own flips, crossings and disk test."""

from __future__ import annotations

import copy
import sys

import numpy as np

from heatparam import datasets
from heatparam.atlas.segment import Topology, chart_mesh, flatten_charts, quick_flatten, segment


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


def _two_charts(V, F, left):
    """The faces split by ``left`` (m,) bool into two charts, each laid out by LSCM: (topo, glued, layouts, members,
    the pair's longest common stretch)."""
    seg_mod = sys.modules["heatparam.atlas.segment"]
    topo = Topology.build(V, F)
    members = {0: np.flatnonzero(left), 1: np.flatnonzero(~left)}
    glued = np.zeros(3 * len(F), dtype=bool)
    for faces in members.values():
        glued |= seg_mod._glue_inside(topo, faces)
    fl = flatten_charts(topo, [members[0], members[1]], glued)
    assert fl.ok(np.inf).all()
    layouts = seg_mod._Layouts(len(F))
    layouts.add([0, 1], [members[0], members[1]], fl, [0, 1], [True, True])
    h = np.flatnonzero((topo.opp >= 0) & left[np.arange(3 * len(F)) // 3])
    h = h[~left[topo.opp[h] // 3]]  # chart 0's half of the common border
    return seg_mod, topo, glued, layouts, members, seg_mod._stretches(topo, h)[0]


def test_extension_of_a_flat_chart_is_exact():
    """The smaller chart laid out against the larger one's layout, the stretch pinned where the larger has it: on a
    flat square (split along a wavy line) the union is an exact isometry, every corner-to-corner length as in 3D
    (wrong pins, or UVs written to the wrong corners, would stretch the faces along the stretch)."""
    s = datasets.flat_square(h=0.08)
    C = s.V[s.F].mean(axis=1)
    left = C[:, 0] < 0.3 * np.sin(3 * C[:, 1])  # chart 1 (the larger) keeps its layout, chart 0 is extended over
    seg_mod, topo, glued, layouts, members, st = _two_charts(s.V, s.F, left)
    assert len(members[0]) < len(members[1]) and len(st) > 5
    before = layouts.uv[3 * members[1][:, None] + np.arange(3)].copy()
    ok, undecided = seg_mod._extension_tests(topo, glued, layouts, members, [(0, 1, st)], 1.0 + 1e-7)
    assert ok[0] and not undecided[0]
    assert (layouts.uv[3 * members[1][:, None] + np.arange(3)] == before).all()  # the larger chart stays put
    U = layouts.uv.reshape(-1, 3, 2)
    P = s.V[s.F]
    for j in range(3):
        lu = np.linalg.norm(U[:, (j + 1) % 3] - U[:, j], axis=1)
        lp = np.linalg.norm(P[:, (j + 1) % 3] - P[:, j], axis=1)
        np.testing.assert_allclose(lu, lp, rtol=1e-7)
    # the two sides of the stretch meet: chart 0's corners on it sit where chart 1's do
    h = st
    o = topo.opp[h]
    np.testing.assert_array_equal(layouts.uv[h], layouts.uv[o - o % 3 + (o % 3 + 1) % 3])


def test_extension_that_would_overlap_is_refused():
    """A cone with more than 2π around its apex, cut open along a generator, in two halves: each flattens, the
    union overlaps itself (its boundary crosses), so the extension is refused whatever the distortion bound; the
    same split of a cone with less than 2π passes."""
    from conftest import excess_cone

    for wave, expect in ((0.35, False), (0.0, True)):  # apex angle ~1.6 × 2π, and a plain cone (~0.86 × 2π)
        V, F = excess_cone(wave=wave)
        if not wave:
            V[:, 2] = 0.6 * np.linalg.norm(V[:, :2], axis=1)
        C = V[F].mean(axis=1)
        left = np.arctan2(C[:, 1], C[:, 0]) < 0.0
        seg_mod, topo, glued, layouts, members, st = _two_charts(V, F, left)
        ok, undecided = seg_mod._extension_tests(topo, glued, layouts, members, [(0, 1, st)], np.inf)
        assert ok[0] == expect and not undecided[0]


def test_segmented_charts_layouts_are_bijective():
    """Every chart's checked layout (``Segmentation.corner_uv``) has no flipped face, no two overlapping triangles
    (an exact check, independent of the border crossings the merges test) and stays within the bound; the excess
    cone with a loose bound makes the merges depend on the crossing test alone."""
    from heatparam.atlas.overlap import count_overlaps
    from heatparam.atlas.segment import proxy_bound

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


def _slit(topo, glued, members, c, st):
    """``glued`` with chart c cut open along two edges from a vertex in the middle of the stretch ``st`` into the
    chart (v → u → w, u and w inner vertices); (the cut glued, the first half-edge cut)."""
    ha, hb = topo.ends()
    inner = np.intersect1d(hb[st], ha[st])  # the stretch's vertices between two of its edges
    v = int(inner[len(inner) // 2])
    h_all = np.arange(len(glued))
    mine = np.isin(h_all // 3, members[c])
    on_border = np.zeros(len(topo.V), dtype=bool)
    on_border[ha[mine & ~glued]] = True
    h1 = np.flatnonzero(glued & mine & (ha == v) & ~on_border[hb])[0]
    u = hb[h1]
    h2 = np.flatnonzero(glued & mine & (ha == u) & ~on_border[hb] & (hb != v))[0]
    cut = glued.copy()
    for h in (h1, h2):
        cut[h] = cut[topo.opp[h]] = False
    return cut, h1


def test_extension_along_a_seam_of_either_chart_is_left_to_a_whole_flattening():
    """A chart cut open along one edge from a vertex in the middle of the stretch has two corners there: gluing
    along the stretch would close the cut's mouth into a hole (an annulus, not a chart). The larger chart cut: its
    two corners at two places, the smaller chart's one corner cannot be pinned to both; the smaller chart cut: two
    corners pinned to one place. Either way the test is undecided (the merge then flattens the union whole, whose
    disk test refuses it: a two-edge cut closed at both ends is a hole) rather than passed."""
    s = datasets.flat_square(h=0.08)
    C = s.V[s.F].mean(axis=1)
    left = C[:, 0] > -0.3  # chart 0 (the larger) keeps its layout, chart 1 is extended over
    seg_mod, topo, glued, layouts, members, st = _two_charts(s.V, s.F, left)
    for c in (0, 1):
        cut, h = _slit(topo, glued, members, c, st)
        lay = copy.deepcopy(layouts)
        if c == 0:  # the larger chart's layout with the cut: its two corners at v a little apart
            lay.add([0], [members[0]], flatten_charts(topo, [members[0]], cut), [0], [True])
            _, Fl, _ = chart_mesh(topo, members[0], cut)
            row = Fl[np.searchsorted(members[0], h // 3), h % 3]
            lay.uv[(3 * members[0][:, None] + np.arange(3))[Fl == row]] += 1e-3
        ok, undecided = seg_mod._extension_tests(topo, cut, lay, members, [(0, 1, st)], np.inf)
        assert undecided[0] and not ok[0]
        whole = seg_mod._union_tests(topo, cut, copy.deepcopy(lay), members, [(0, 1, st)], np.inf)
        assert not whole[0]  # not a disk
    ok, undecided = seg_mod._extension_tests(topo, glued, layouts, members, [(0, 1, st)], np.inf)
    assert ok[0] and not undecided[0]  # no cut: one corner each at every vertex of the stretch


def test_a_failing_region_is_split_from_its_own_seeds_at_the_same_cone(monkeypatch):
    """Segmentation step 2: a region whose quick flattening fails is grown again at the same cone from
    ``SPLIT_SEEDS`` farthest seeds of its own (not shrunk with a narrower cone), into at least two pieces, each
    checked in turn; the pieces of one generation are flattened in one solve."""
    seg_mod = sys.modules["heatparam.atlas.segment"]
    calls, flattened = [], []
    real_grow, real_flatten = seg_mod.grow, seg_mod.flatten_charts

    def grow(topo, faces, cone, target, seed=0):
        out = real_grow(topo, faces, cone, target, seed)
        calls.append((len(faces), cone, target, len(out)))
        return out

    def flatten(topo, charts, glued, bound=np.inf):
        flattened.append(len(charts))
        return real_flatten(topo, charts, glued, bound)

    real_merge = seg_mod._merge

    def merge(*a, **k):
        flattened.append("merge")
        return real_merge(*a, **k)

    monkeypatch.setattr(seg_mod, "grow", grow)
    monkeypatch.setattr(seg_mod, "flatten_charts", flatten)
    monkeypatch.setattr(seg_mod, "_merge", merge)
    V, F = datasets.torus()
    seg = segment(Topology.build(V, F), 1.05)
    first, *splits = calls
    assert seg.stats["regrown"] == len(splits) > 1
    for n, cone, target, pieces in splits:
        assert cone == first[1] and target == -(-n // seg_mod.SPLIT_SEEDS) and pieces >= 2
    growth = flattened[:flattened.index("merge")]  # the regions' checks, one flattening per generation
    assert sum(growth) == seg.stats["grown"] == first[3] + sum(p for *_, p in splits)
    assert growth[0] == first[3] and len(growth) < 1 + len(splits)  # splits of one generation flattened together
    assert seg.checked.all()


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


def test_seeds_from_the_direct_csr_graph_match_the_coo_graph():
    """_seeds builds the face graph's CSR arrays directly (its rows ascend); forced through COO (the path of a mesh
    with a two-faced pocket, where COO sums the duplicate entry) it picks the same seeds on random face sets."""
    import importlib

    S = importlib.import_module("heatparam.atlas.segment")
    V, F = datasets.torus(n_major=24, n_minor=10)
    direct, coo = Topology.build(V, F), Topology.build(V, F)
    assert not direct.double_neighbours()
    coo._double = True
    rng = np.random.default_rng(5)
    for _ in range(20):
        faces = np.sort(rng.choice(len(F), size=int(rng.integers(2, len(F))), replace=False))
        k, seed = int(rng.integers(1, 6)), int(rng.integers(0, 3))
        assert np.array_equal(S._seeds(direct, faces, k, seed), S._seeds(coo, faces, k, seed))
    pillow = Topology.build(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 1]]))
    assert pillow.double_neighbours()  # two faces, neighbours across all three edges
    assert sorted(S._seeds(pillow, np.arange(2), 2, 0).tolist()) == [0, 1]
