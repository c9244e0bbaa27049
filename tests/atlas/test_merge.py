"""Merge tests (atlas/merge.py): the smaller chart laid out against the larger one's layout (an extension), or the
union flattened whole where the extension cannot decide."""

from __future__ import annotations

import copy

import numpy as np

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology, chart_mesh, glue_inside
from heatparam.atlas.flatten import flatten_charts
from heatparam.atlas.merge import Layouts, Merging
from heatparam.atlas.stretches import border_stretches

from conftest import assert_corner_lengths_kept


def _two_charts(V, F, left):
    """The faces split by ``left`` (m,) bool into charts 0 (left) and 1, each laid out by LSCM: (topo, glued,
    layouts, members, the pair's longest common stretch)."""
    topo = Topology.build(V, F)
    members = {0: np.flatnonzero(left), 1: np.flatnonzero(~left)}
    glued = np.zeros(3 * len(F), dtype=bool)
    for faces in members.values():
        glued |= glue_inside(topo, faces)
    fl = flatten_charts(topo, [members[0], members[1]], glued)
    assert fl.ok(np.inf).all()
    layouts = Layouts(len(F))
    layouts.add([0, 1], [members[0], members[1]], fl, [0, 1], [True, True])
    h = np.flatnonzero((topo.opp >= 0) & left[np.arange(3 * len(F)) // 3])
    h = h[~left[topo.opp[h] // 3]]  # chart 0's half of the common border
    return topo, glued, layouts, members, border_stretches(topo, h)[0]


def _merging(topo, left, glued, layouts, bound):
    """The merging of charts 0 (``left``) and 1 with these glued half-edges and layouts."""
    return Merging(topo, np.where(left, 0, 1), glued, layouts, bound)


def test_extension_of_a_flat_chart_is_exact():
    """The smaller chart laid out against the larger one's layout, the stretch pinned where the larger has it: on a
    flat square (split along a wavy line) the union is an exact isometry, every corner-to-corner length as in 3D
    (wrong pins, or UVs written to the wrong corners, would stretch the faces along the stretch)."""
    s = datasets.flat_square(h=0.08)
    C = s.V[s.F].mean(axis=1)
    left = C[:, 0] < 0.3 * np.sin(3 * C[:, 1])  # chart 1 (the larger) keeps its layout, chart 0 is extended over
    topo, glued, layouts, members, st = _two_charts(s.V, s.F, left)
    assert len(members[0]) < len(members[1]) and len(st) > 5
    before = layouts.uv[3 * members[1][:, None] + np.arange(3)].copy()
    ok, undecided = _merging(topo, left, glued, layouts, 1.0 + 1e-7).extension_tests([(0, 1, st)])
    assert ok[0] and not undecided[0]
    assert (layouts.uv[3 * members[1][:, None] + np.arange(3)] == before).all()  # the larger chart stays put
    assert_corner_lengths_kept(layouts.uv, s.V, s.F, rtol=1e-7)
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
        topo, glued, layouts, members, st = _two_charts(V, F, left)
        ok, undecided = _merging(topo, left, glued, layouts, np.inf).extension_tests([(0, 1, st)])
        assert ok[0] == expect and not undecided[0]


def test_extension_that_would_close_a_cut_is_refused():
    """Two halves of a flat fan cut open along one edge from its centre: merged along the other half's edge, the
    union closes the cut, its border touching itself at the centre (both border edges there leave the same vertex,
    so no pair of edges crosses): refused. The same on a cone (less than 2π at the centre) passes."""
    from conftest import slit_fan

    for apex, expect in ((0.0, False), (0.4, True)):
        V, F = slit_fan(apex=apex)
        left = np.arange(len(F)) < len(F) // 2
        topo, glued, layouts, members, st = _two_charts(V, F, left)
        ok, undecided = _merging(topo, left, glued, layouts, np.inf).extension_tests([(0, 1, st)])
        assert ok[0] == expect and not undecided[0]


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
    topo, glued, layouts, members, st = _two_charts(s.V, s.F, left)
    for c in (0, 1):
        cut, h = _slit(topo, glued, members, c, st)
        lay = copy.deepcopy(layouts)
        if c == 0:  # the larger chart's layout with the cut: its two corners at v a little apart
            lay.add([0], [members[0]], flatten_charts(topo, [members[0]], cut), [0], [True])
            _, Fl, _ = chart_mesh(topo, members[0], cut)
            row = Fl[np.searchsorted(members[0], h // 3), h % 3]
            lay.uv[(3 * members[0][:, None] + np.arange(3))[Fl == row]] += 1e-3
        ok, undecided = _merging(topo, left, cut, lay, np.inf).extension_tests([(0, 1, st)])
        assert undecided[0] and not ok[0]
        whole = _merging(topo, left, cut, copy.deepcopy(lay), np.inf).union_tests([(0, 1, st)])
        assert not whole[0]  # not a disk
    ok, undecided = _merging(topo, left, glued, layouts, np.inf).extension_tests([(0, 1, st)])
    assert ok[0] and not undecided[0]  # no cut: one corner each at every vertex of the stretch
