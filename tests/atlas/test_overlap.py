"""The exact overlap count (atlas/overlap.py) on constructed cases and against polygon clipping."""

from __future__ import annotations

import numpy as np

from heatparam.atlas.overlap import count_overlaps, folded_zero_area, overlapping_pairs, uv_degenerate_faces
from heatparam.metrics import boundary_crossings


def test_overlap_chart_inside_another_is_found_without_boundary_crossings():
    uv = np.array([[0, 0], [10, 0], [0, 10], [1, 1], [2, 1], [1, 2]], dtype=float)
    Fuv = np.array([[0, 1, 2], [3, 4, 5]])
    assert boundary_crossings(uv, Fuv) == 0  # the boundary check alone misses it
    assert overlapping_pairs(uv, Fuv).tolist() == [[0, 1]]


def test_overlap_touching_edges_and_shared_corners_are_not_overlaps():
    # two charts touching along a full edge (distinct rows, equal coordinates)
    uv = np.array([[0, 0], [1, 0], [0, 1], [1, 0], [0, 1], [1, 1]], dtype=float)
    assert count_overlaps(uv, np.array([[0, 1, 2], [3, 5, 4]])) == 0
    # adjacent triangles of one chart sharing an edge (same rows)
    assert count_overlaps(uv[[0, 1, 2, 5]], np.array([[0, 1, 2], [1, 3, 2]])) == 0
    # triangles sharing only a corner
    uv2 = np.array([[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1]], dtype=float)
    assert count_overlaps(uv2, np.array([[0, 1, 2], [0, 3, 4]])) == 0
    # a corner touching the middle of the other's edge (T-junction)
    uv3 = np.array([[0, 0], [2, 0], [0, 2], [1, 0], [2, -1], [0, -1]], dtype=float)
    assert count_overlaps(uv3, np.array([[0, 1, 2], [3, 5, 4]])) == 0


def test_overlap_crossing_and_shared_edge_folded_back():
    uv = np.array([[0, 0], [2, 0], [0, 2], [1, 1.5], [1, -1], [3, 1]], dtype=float)
    assert count_overlaps(uv, np.array([[0, 1, 2], [3, 4, 5]])) == 1
    # a fold: two faces of one chart share an edge and lie on the same side of it
    uv2 = np.array([[0, 0], [1, 0], [0, 1], [0.2, 0.3]], dtype=float)
    assert count_overlaps(uv2, np.array([[0, 1, 2], [0, 1, 3]])) == 1
    assert uv_degenerate_faces(np.array([[0, 0], [1, 1], [2, 2.0]]), np.array([[0, 1, 2]])).tolist() == [True]


def _side(p, q, x) -> float:
    return (q[0] - p[0]) * (x[1] - p[1]) - (q[1] - p[1]) * (x[0] - p[0])


def _clip_area(A: np.ndarray, B: np.ndarray) -> float:
    """Intersection area of two counter-clockwise triangles (Sutherland-Hodgman), the brute-force reference."""
    poly = list(A)
    for i in range(3):
        p, q = B[i], B[(i + 1) % 3]
        out = []
        for j in range(len(poly)):
            c, d = poly[j], poly[(j + 1) % len(poly)]
            sc, sd = _side(p, q, c), _side(p, q, d)
            if sc >= 0:
                out.append(c)
            if sc * sd < 0:
                out.append(c + (d - c) * (sc / (sc - sd)))
        poly = out
        if not poly:
            return 0.0
    P = np.array(poly)
    return 0.5 * abs(np.dot(P[:, 0], np.roll(P[:, 1], -1)) - np.dot(P[:, 1], np.roll(P[:, 0], -1)))


def test_overlap_matches_clipping_on_random_triangles():
    rng = np.random.default_rng(3)
    T = rng.uniform(0, 4, (60, 3, 2))
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    s = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    T[s < 0] = T[s < 0][:, ::-1]
    uv = T.reshape(-1, 2)
    Fuv = np.arange(len(uv)).reshape(-1, 3)
    got = {tuple(p) for p in overlapping_pairs(uv, Fuv).tolist()}
    want = {(i, j) for i in range(60) for j in range(i + 1, 60) if _clip_area(T[i], T[j]) > 1e-12}
    assert got == want and len(want) > 20


def test_folded_zero_area_face():
    """A zero-area face whose UV triangle turns the other way than the map folds over its neighbours (the metrics
    leave it out); a UV segment or a thin triangle the right way round does not."""
    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]])
    F = np.array([[0, 1, 3], [1, 2, 3], [0, 2, 1]])  # the last face: collinear corners
    uv = V[:, :2].copy()
    assert folded_zero_area(V, F, uv) == 0  # exactly a segment
    uv[1, 1] = 1e-3
    assert folded_zero_area(V, F, uv) == 0  # thin, counter-clockwise like the map
    assert folded_zero_area(V, F, uv * [-1, 1]) == 0  # the mirrored map: all its faces turn the other way
    uv[1, 1] = -1e-3
    assert folded_zero_area(V, F, uv) == folded_zero_area(V, F, uv * [-1, 1]) == 1
