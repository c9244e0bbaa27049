"""Exact overlap count of a 2D triangle soup (a UV atlas): which triangle pairs' interiors intersect.

Independent of how the map was made: a uniform-grid broad phase over the triangles' UV bounding boxes, then an
exact separating-axis test per candidate pair. Two triangles' open interiors are disjoint exactly when one of the
six edge lines has the other triangle wholly on its closed outer side; orientations are computed in floating
point and recomputed exactly (``fractions.Fraction`` of the float coordinates) wherever the float result is within
its rounding error bound of zero. Shared corners and shared edges (same coordinates) are therefore not overlaps,
and neither is a chart that only touches another one; a chart lying wholly inside another one is.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from heatparam.compiled import compiled, warmup
from heatparam.mesh.topology import degenerate_faces

__all__ = ["ORIENT_ERRBOUND", "count_overlaps", "float_orientation", "folded_zero_area", "overlapping_pairs",
           "uv_degenerate_faces"]

_EPS = np.finfo(np.float64).eps
#: Shewchuk's ccwerrboundA: a floating-point orientation farther from zero than this times the sum of its two
#: products' magnitudes has the exact orientation's sign
ORIENT_ERRBOUND = (3.0 + 16.0 * _EPS) * _EPS


def float_orientation(ax, ay, bx, by, cx, cy) -> tuple[np.ndarray, np.ndarray]:
    """The orientation determinant of (a, b, c) in floating point and its rounding error bound (arrays of equal
    shape): where |det| exceeds the bound, its sign is the exact orientation's."""
    left = (bx - ax) * (cy - ay)
    right = (by - ay) * (cx - ax)
    return left - right, ORIENT_ERRBOUND * (np.abs(left) + np.abs(right))


def _orient(ax, ay, bx, by, cx, cy) -> np.ndarray:
    """Sign (-1, 0, 1) of the orientation of (a, b, c), exact (arrays of equal shape)."""
    det, bound = float_orientation(ax, ay, bx, by, cx, cy)
    sign = np.sign(det)
    # exact zeros without arithmetic: c equals a or b (shared corners, shared edges)
    same = ((cx == ax) & (cy == ay)) | ((cx == bx) & (cy == by)) | ((ax == bx) & (ay == by))
    sign = np.where(same, 0.0, sign)
    unsure = np.flatnonzero((np.abs(det) <= bound) & ~same & (bound > 0))
    if len(unsure):
        flat = [np.ravel(x) for x in (ax, ay, bx, by, cx, cy)]
        out = np.ravel(sign).copy()
        for i in unsure:
            a_x, a_y, b_x, b_y, c_x, c_y = (Fraction(float(x[i])) for x in flat)
            d = (b_x - a_x) * (c_y - a_y) - (b_y - a_y) * (c_x - a_x)
            out[i] = (d > 0) - (d < 0)
        sign = out.reshape(np.shape(det))
    return sign


def uv_degenerate_faces(uv: np.ndarray, Fuv: np.ndarray) -> np.ndarray:
    """(m,) bool: faces whose UV triangle has zero area (exact orientation test)."""
    P = uv[Fuv]
    s = _orient(P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1], P[:, 2, 0], P[:, 2, 1])
    return s == 0


def folded_zero_area(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None,
                     zero_area: np.ndarray | None = None) -> int:
    """Zero-area 3D faces whose UV triangle is a triangle of the orientation opposite to the map's (that of the
    larger signed UV area): a fold over its neighbours that the metrics, which leave zero-area faces out, do not
    count as a flip. Exact orientation test; a UV segment or point is no fold. ``zero_area`` (m,) bool: the
    zero-area faces (``degenerate_faces(V, F)``) when known."""
    Fuv = F if Fuv is None else Fuv
    zero = np.flatnonzero(degenerate_faces(V, F) if zero_area is None else zero_area)
    if not len(zero):
        return 0
    P = uv[Fuv]
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    way = np.sign((e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())
    Z = P[zero]
    s = _orient(Z[:, 0, 0], Z[:, 0, 1], Z[:, 1, 0], Z[:, 1, 1], Z[:, 2, 0], Z[:, 2, 1])
    return int((s == -way).sum()) if way else 0


@compiled()
def _box_pairs(lo, hi, cell):  # pragma: no cover - compiled
    """(p,2) pairs i < j of the boxes [lo, hi] (m,2) that intersect (closed), each once: a uniform grid of ``cell``,
    each pair found in the cell of its boxes' common lower-left corner (both boxes cover that cell)."""
    m = lo.shape[0]
    ox, oy = lo[:, 0].min(), lo[:, 1].min()
    c0 = np.empty((m, 2), dtype=np.int64)
    c1 = np.empty((m, 2), dtype=np.int64)
    total = 0
    for i in range(m):
        c0[i, 0], c0[i, 1] = np.floor((lo[i, 0] - ox) / cell), np.floor((lo[i, 1] - oy) / cell)
        c1[i, 0], c1[i, 1] = np.floor((hi[i, 0] - ox) / cell), np.floor((hi[i, 1] - oy) / cell)
        total += (c1[i, 0] - c0[i, 0] + 1) * (c1[i, 1] - c0[i, 1] + 1)
    ny = c1[:, 1].max() + 1
    key = np.empty(total, dtype=np.int64)
    box = np.empty(total, dtype=np.int64)
    t = 0
    for i in range(m):
        for cx in range(c0[i, 0], c1[i, 0] + 1):
            for cy in range(c0[i, 1], c1[i, 1] + 1):
                key[t], box[t] = cx * ny + cy, i
                t += 1
    order = np.argsort(key)
    out = np.empty((max(total, 16), 2), dtype=np.int64)
    n, s = 0, 0
    while s < total:
        e = s
        while e < total and key[order[e]] == key[order[s]]:
            e += 1
        for p in range(s, e):
            for q in range(p + 1, e):
                a, b = min(box[order[p]], box[order[q]]), max(box[order[p]], box[order[q]])
                if max(c0[a, 0], c0[b, 0]) * ny + max(c0[a, 1], c0[b, 1]) != key[order[s]]:
                    continue
                if lo[a, 0] <= hi[b, 0] and lo[b, 0] <= hi[a, 0] and lo[a, 1] <= hi[b, 1] and lo[b, 1] <= hi[a, 1]:
                    if n == len(out):
                        out = np.concatenate((out, np.empty_like(out)))
                    out[n, 0], out[n, 1] = a, b
                    n += 1
        s = e
    return out[:n]


@compiled()
def _orient_sign(ax, ay, bx, by, cx, cy):  # pragma: no cover - compiled
    """The sign of the orientation of (a, b, c) as :func:`_orient` finds it without exact arithmetic; 2 where the
    float result is within its rounding error bound of zero (exact arithmetic must decide)."""
    if (cx == ax and cy == ay) or (cx == bx and cy == by) or (ax == bx and ay == by):
        return 0
    left = (bx - ax) * (cy - ay)
    right = (by - ay) * (cx - ax)
    det = left - right
    bound = ORIENT_ERRBOUND * (abs(left) + abs(right))
    if bound > 0 and abs(det) <= bound:
        return 2
    return 1 if det > 0 else -1 if det < 0 else 0


@compiled(_orient_sign)
def _pair_verdicts(T, pairs):  # pragma: no cover - compiled
    """Per pair of counter-clockwise triangles T (t,3,2): 0 when an edge line of one has the other wholly on its
    closed outer side (disjoint interiors), 1 when none has (they overlap), 2 when only exact arithmetic decides."""
    out = np.empty(len(pairs), dtype=np.int8)
    for i in range(len(pairs)):
        verdict = 1
        for side in range(2):
            x, y = (pairs[i, 0], pairs[i, 1]) if side == 0 else (pairs[i, 1], pairs[i, 0])
            for e in range(3):
                f = (e + 1) % 3
                worst = -1
                for v in range(3):
                    worst = max(worst, _orient_sign(T[x, e, 0], T[x, e, 1], T[x, f, 0], T[x, f, 1], T[y, v, 0],
                                                    T[y, v, 1]))
                if worst <= 0:
                    verdict = 0
                elif worst == 2 and verdict == 1:
                    verdict = 2
        out[i] = verdict
    return out


def _separated(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(p,) bool, exact: triangle pairs (A[i], B[i]) (p,3,2), counter-clockwise, whose open interiors are disjoint."""
    separated = np.zeros(len(A), dtype=bool)
    for X, Y in ((A, B), (B, A)):
        for e in range(3):
            p, q = X[:, e], X[:, (e + 1) % 3]
            outside = np.ones(len(A), dtype=bool)
            for v in range(3):
                todo = np.flatnonzero(~separated & outside)
                if not len(todo):
                    break
                r = Y[todo, v]
                s_ = _orient(p[todo, 0], p[todo, 1], q[todo, 0], q[todo, 1], r[:, 0], r[:, 1])
                outside[todo[s_ > 0]] = False
            separated |= outside
    return separated


def overlapping_pairs(uv: np.ndarray, Fuv: np.ndarray) -> np.ndarray:
    """Triangle pairs of the atlas whose open interiors intersect.

    Parameters
    ----------
    uv : (k,2) float64 UV positions. Fuv : (m,3) int64 rows of ``uv`` per face corner.

    Returns
    -------
    (p,2) int64 face pairs (i < j), sorted. Zero-area UV triangles have no interior and are never part of a pair
    (count them with :func:`uv_degenerate_faces`).
    """
    uv = np.asarray(uv, dtype=np.float64)
    Fuv = np.asarray(Fuv, dtype=np.int64)
    P = uv[Fuv]  # (m,3,2)
    ori = _orient(P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1], P[:, 2, 0], P[:, 2, 1])
    live = np.flatnonzero(ori != 0)
    if len(live) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    Pl = P[live]
    cw = ori[live] < 0  # every live triangle made counter-clockwise
    Pl[cw] = Pl[cw][:, ::-1]
    lo, hi = Pl.min(axis=1), Pl.max(axis=1)
    cell = max(float(np.median((hi - lo).max(axis=1))) * 2.0, 1e-300)
    cand = _box_pairs(lo, hi, cell)
    verdict = _pair_verdicts(np.ascontiguousarray(Pl), cand)
    close = np.flatnonzero(verdict == 2)
    verdict[close] = ~_separated(Pl[cand[close, 0]], Pl[cand[close, 1]])
    res = np.sort(live[cand[verdict == 1]], axis=1)
    return res[np.lexsort((res[:, 1], res[:, 0]))]


def count_overlaps(uv: np.ndarray, Fuv: np.ndarray) -> int:
    """Number of triangle pairs of the atlas whose interiors intersect (:func:`overlapping_pairs`)."""
    return int(len(overlapping_pairs(uv, Fuv)))


@warmup
def _warm() -> None:
    """The compiled loops run once on two overlapping triangles (:func:`heatparam.compiled.warm_all`)."""
    overlapping_pairs(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.1, 0.1]]), np.array([[0, 1, 2], [3, 1, 2]]))
