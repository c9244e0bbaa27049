"""``mesh.topology`` and ``mesh.planar``: one boundary walker, compaction, signed areas, the triangulation wrapper."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam.mesh import (
    boundary_edges,
    boundary_loops,
    compact,
    loop_length,
    loops_outer_first,
    make_ccw,
    polygon_area,
    signed_areas,
    triangulate,
    unique_edges,
)

from conftest import flat_disk


def test_boundary_edges_and_loops_of_a_disk():
    V, F = flat_disk(8)
    E = boundary_edges(F)
    (loop,) = boundary_loops(F)
    assert len(E) == len(loop)
    # consecutive loop vertices are boundary half-edges in face orientation
    he = {tuple(e) for e in E.tolist()}
    assert all((int(a), int(b)) in he for a, b in zip(loop, np.roll(loop, -1), strict=True))


def test_loops_outer_first_sorts_by_length():
    V = np.array([[x, y, 0.0] for y in range(4) for x in range(4)])
    idx = lambda x, y: 4 * y + x  # noqa: E731
    F = []
    for x in range(3):
        for y in range(3):
            if (x, y) == (1, 1):
                continue  # a hole in the middle
            F += [[idx(x, y), idx(x + 1, y), idx(x + 1, y + 1)], [idx(x, y), idx(x + 1, y + 1), idx(x, y + 1)]]
    F = np.array(F)
    loops = loops_outer_first(V, F)
    assert [round(loop_length(V, lp), 9) for lp in loops] == [12.0, 4.0]


def test_unique_edges_and_compaction():
    F = np.array([[0, 1, 2], [0, 2, 3]])
    assert unique_edges(F).tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    used = np.array([True, False, True, True])
    comp = compact(used)
    assert comp.keep.tolist() == [0, 2, 3] and comp.remap.tolist() == [0, -1, 1, 2]
    assert comp.faces(np.array([[0, 2, 3]])).tolist() == [[0, 1, 2]]


def test_signed_areas_orientation_and_polygon_area():
    P = np.array([[0.0, 0], [1, 0], [0, 1]])
    assert signed_areas(P, np.array([[0, 1, 2], [0, 2, 1]])).tolist() == [0.5, -0.5]
    assert make_ccw(P, np.array([[0, 2, 1]])).tolist() == [[0, 1, 2]]
    assert polygon_area(P) == 0.5 and polygon_area(P[::-1]) == -0.5


def test_triangulate_fills_a_polygon_with_a_hole():
    sq = np.array([[0.0, 0], [4, 0], [4, 4], [0, 4]])
    hole = np.array([[1.0, 1], [1, 3], [3, 3], [3, 1]])
    E = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4]])
    P, T = triangulate(np.vstack([sq, hole]), E)
    assert len(P) == 8 and abs(signed_areas(P, T)).sum() == pytest.approx(16 - 4)


def test_sort_based_unique_helpers_agree_with_numpy():
    """unique_ints / unique_inverse (one sort; NumPy 2.4's hashing np.unique is slow on many keys) give np.unique's
    values, first indices and inverse, including repeated, negative and empty inputs."""
    from heatparam.mesh.topology import unique_ints, unique_inverse

    rng = np.random.default_rng(3)
    for x in (rng.integers(-50, 50, 1000), np.array([7, 7, 7]), np.zeros(0, dtype=np.int64), np.arange(10)[::-1]):
        u, first, inv = np.unique(x, return_index=True, return_inverse=True)
        u2, first2, inv2 = unique_inverse(x)
        assert np.array_equal(u, unique_ints(x)) and np.array_equal(u, u2)
        assert np.array_equal(first, first2) and np.array_equal(inv.ravel(), inv2)
        assert np.array_equal(u2[inv2], x)


def test_packed_sort_is_the_stable_argsort():
    """``sort_with_order`` / ``stable_argsort`` (each value's index packed into its low bits, one quicksort) give
    the sorted values and exactly ``np.argsort(kind="stable")``'s permutation (ties in index order), also for
    negative values, one element, and values too wide to pack (the stable argsort itself then)."""
    from heatparam.mesh.topology import sort_with_order, stable_argsort

    rng = np.random.default_rng(4)
    cases = [rng.integers(-5, hi, size) for hi, size in ((3, 500), (1000, 999), (2**30, 1025))]
    cases += [np.array([7]), np.array([2**62, 0, 5, 2**62, -1]), np.zeros(0, dtype=np.int64)]
    for x in cases:
        ref = np.argsort(x, kind="stable")
        xs, order = sort_with_order(x)
        assert np.array_equal(order, ref) and np.array_equal(stable_argsort(x), ref)
        assert np.array_equal(xs, x[ref]) and xs.dtype == x.dtype


@pytest.mark.parametrize("n", [50, 70_000])
def test_connected_labels_are_scipys(n):
    """``connected_labels`` numbers components by their smallest node, as scipy's ``connected_components`` does,
    below ``COMPILED_MIN_NODES`` (scipy) and above it (the compiled union-find): random sparse graphs with isolated
    nodes, self-links and repeated links, and a graph without links."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    from heatparam.mesh.topology import COMPILED_MIN_NODES, connected_labels

    assert (n >= COMPILED_MIN_NODES) == (n > 1000)
    rng = np.random.default_rng(n)
    for links in (0, n // 3, n, 2 * n):
        r, c = rng.integers(0, n, links), rng.integers(0, n, links)
        r[: links // 10] = c[: links // 10]  # self-links
        r, c = np.r_[r, c[:5]], np.r_[c, r[:5]]  # repeated links, both ways
        count, labels = connected_labels(n, r, c)
        ref_count, ref = connected_components(sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)),
                                              directed=False)
        assert count == ref_count and np.array_equal(labels, ref) and labels.dtype == np.int64


def test_degenerate_faces_collinear_and_point_like():
    from heatparam.mesh.topology import degenerate_faces

    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0], [1, 1e-9, 0]])
    F = np.array([[0, 1, 3], [0, 2, 1], [0, 0, 0], [0, 2, 4]])
    assert degenerate_faces(V, F).tolist() == [False, True, True, False]  # a sliver of height 1e-9 has an area


def test_a_triangle_collinear_in_its_files_decimals_has_zero_area():
    """Three corners on one line in a file's decimals (a real CAD file's face) read as a triangle whose area is
    rounding (2 · area 4e-21, above 1e-14 of its squared longest edge): zero area, as the metrics and the atlas then
    treat it (its UV triangle cannot keep that area once packed). The same face with its middle corner 1e-9 off the
    line, and a sliver of that height anywhere, keep their area."""
    from heatparam.mesh.topology import degenerate_faces

    V = np.array([[0.091807, 0.036407, 0.26125], [0.091581, 0.036598, 0.26125], [0.091355, 0.036789, 0.26125]])
    F = np.array([[0, 1, 2]])
    assert degenerate_faces(V, F)[0]
    lifted = V.copy()
    lifted[1, 0] += 1e-9
    assert not degenerate_faces(lifted, F)[0]
    assert not degenerate_faces(lifted + 1e3, F)[0]  # far from the origin: rounding ~1e-16 relative, still a triangle


def test_boundary_edges_memo_follows_the_faces_content():
    """Boundary edges are remembered per face content: asked again they are the same; faces changed in place give
    the new mesh's; a returned array is the caller's own."""
    from heatparam.mesh.topology import _boundary_edges, boundary_edges

    _, F = flat_disk()
    first = boundary_edges(F)
    first[:] = -1  # the caller's copy: the memo keeps its own
    again = boundary_edges(F)
    assert np.array_equal(again, _boundary_edges(np.asarray(F, dtype=np.int64)))
    G = F.copy()
    boundary_edges(G)
    G[0] = G[1]  # in place: face 0's edges lose a face, face 1's gain one
    assert np.array_equal(boundary_edges(G), _boundary_edges(G))
    assert not np.array_equal(boundary_edges(G), again)


def test_vertex_corners_group_each_vertex_corners_in_face_order():
    from heatparam.mesh.topology import vertex_corners

    V, F = flat_disk(6)
    n = len(V) + 2  # two vertices no face uses: empty groups
    corners, starts = vertex_corners(F, n)
    assert len(starts) == n + 1 and starts[0] == 0 and starts[-1] == 3 * len(F)
    assert np.array_equal(corners, np.argsort(F.ravel(), kind="stable"))
    for w in (0, 5, len(V) - 1, len(V), len(V) + 1):
        own = corners[starts[w]:starts[w + 1]]
        assert np.array_equal(own, np.flatnonzero(F.ravel() == w))
        assert (F[own // 3, own % 3] == w).all()
