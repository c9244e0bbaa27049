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

from heatparam.mesh.topology import degenerate_faces, pairs_in_groups

__all__ = ["count_overlaps", "folded_zero_area", "overlapping_pairs", "uv_degenerate_faces"]

_EPS = np.finfo(np.float64).eps
_ERRBOUND = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk's ccwerrboundA


def _orient(ax, ay, bx, by, cx, cy) -> np.ndarray:
    """Sign (-1, 0, 1) of the orientation of (a, b, c), exact (arrays of equal shape)."""
    left = (bx - ax) * (cy - ay)
    right = (by - ay) * (cx - ax)
    det = left - right
    bound = _ERRBOUND * (np.abs(left) + np.abs(right))
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


def folded_zero_area(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None) -> int:
    """Zero-area 3D faces whose UV triangle is a triangle of the orientation opposite to the map's (that of the
    larger signed UV area): a fold over its neighbours that the metrics, which leave zero-area faces out, do not
    count as a flip. Exact orientation test; a UV segment or point is no fold."""
    Fuv = F if Fuv is None else Fuv
    zero = np.flatnonzero(degenerate_faces(V, F))
    if not len(zero):
        return 0
    P = uv[Fuv]
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    way = np.sign((e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())
    Z = P[zero]
    s = _orient(Z[:, 0, 0], Z[:, 0, 1], Z[:, 1, 0], Z[:, 1, 1], Z[:, 2, 0], Z[:, 2, 1])
    return int((s == -way).sum()) if way else 0


def _candidates(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(p,2) pairs i < j whose closed bounding boxes intersect (uniform grid broad phase), each once, in no
    particular order."""
    m = len(lo)
    if m < 2:
        return np.zeros((0, 2), dtype=np.int64)
    ext = hi - lo
    cell = max(float(np.median(ext.max(axis=1))) * 2.0, 1e-300)
    origin = lo.min(axis=0)
    c0 = np.floor((lo - origin) / cell).astype(np.int64)
    c1 = np.floor((hi - origin) / cell).astype(np.int64)
    span = (c1 - c0 + 1)
    count = span[:, 0] * span[:, 1]
    tri = np.repeat(np.arange(m), count)
    offs = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    sx = np.repeat(span[:, 0], count)
    cx = np.repeat(c0[:, 0], count) + offs % sx
    cy = np.repeat(c0[:, 1], count) + offs // sx
    ny = int(cy.max()) + 1
    key = cx * ny + cy
    order = np.lexsort((tri, key))
    key, tri = key[order], tri[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    sizes = np.diff(np.r_[starts, len(key)])
    st, sz = starts[sizes > 1], sizes[sizes > 1]
    if not len(st):
        return np.zeros((0, 2), dtype=np.int64)
    # every pair of positions p < q within each cell's run of the sorted list, all cells at once
    first, second = pairs_in_groups(np.arange(len(tri)), st, sz).T
    a, b, cell = tri[first], tri[second], key[first]
    # each pair once: in the cell of its boxes' common lower-left corner (both boxes cover that cell), where the
    # boxes intersect at all
    (cx0, cy0), (lx, ly), (hx, hy) = (np.ascontiguousarray(x.T) for x in (c0, lo, hi))  # columns: gathers 2x faster
    keep = np.maximum(cx0[a], cx0[b]) * ny + np.maximum(cy0[a], cy0[b]) == cell
    a, b = a[keep], b[keep]
    keep = (lx[a] <= hx[b]) & (lx[b] <= hx[a]) & (ly[a] <= hy[b]) & (ly[b] <= hy[a])
    return np.column_stack([a[keep], b[keep]])


def overlapping_pairs(uv: np.ndarray, Fuv: np.ndarray, chunk: int = 1_000_000) -> np.ndarray:
    """Triangle pairs of the atlas whose open interiors intersect.

    Parameters
    ----------
    uv : (k,2) float64 UV positions. Fuv : (m,3) int64 rows of ``uv`` per face corner.

    Returns
    -------
    (p,2) int64 face pairs (i < j). Zero-area UV triangles have no interior and are never part of a pair
    (count them with :func:`uv_degenerate_faces`).
    """
    uv = np.asarray(uv, dtype=np.float64)
    Fuv = np.asarray(Fuv, dtype=np.int64)
    P = uv[Fuv]  # (m,3,2)
    ori = _orient(P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1], P[:, 2, 0], P[:, 2, 1])
    live = np.flatnonzero(ori != 0)
    Pl = P[live]
    # make every live triangle counter-clockwise
    cw = ori[live] < 0
    Pl[cw] = Pl[cw][:, ::-1]
    cand = _candidates(Pl.min(axis=1), Pl.max(axis=1))
    out = []
    for s in range(0, len(cand), chunk):
        c = cand[s:s + chunk]
        A, B = Pl[c[:, 0]], Pl[c[:, 1]]
        separated = np.zeros(len(c), dtype=bool)
        for X, Y in ((A, B), (B, A)):
            for e in range(3):
                p, q = X[:, e], X[:, (e + 1) % 3]
                outside = np.ones(len(c), dtype=bool)
                for v in range(3):
                    todo = np.flatnonzero(~separated & outside)
                    if not len(todo):
                        break
                    r = Y[todo, v]
                    s_ = _orient(p[todo, 0], p[todo, 1], q[todo, 0], q[todo, 1], r[:, 0], r[:, 1])
                    outside[todo[s_ > 0]] = False
                separated |= outside
        hit = c[~separated]
        out.append(live[hit])
    if not out:
        return np.zeros((0, 2), dtype=np.int64)
    res = np.sort(np.concatenate(out), axis=1)
    return res[np.lexsort((res[:, 1], res[:, 0]))] if len(res) else np.zeros((0, 2), dtype=np.int64)


def count_overlaps(uv: np.ndarray, Fuv: np.ndarray) -> int:
    """Number of triangle pairs of the atlas whose interiors intersect (:func:`overlapping_pairs`)."""
    return int(len(overlapping_pairs(uv, Fuv)))
