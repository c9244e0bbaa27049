"""Quality metrics of a mesh parameterization (the library's yardstick).

Plain, vectorized functions over numpy arrays:

- ``V`` (n, 3) float64 vertex positions, ``F`` (m, 3) int64 triangles;
- ``uv`` (n_uv, 2) float64 texture coordinates, optionally with per-corner indices ``Fuv`` (m, 3) into
  ``uv`` (OBJ files with seams). ``Fuv=None`` means ``Fuv = F`` (then ``n_uv == n``).

Conventions
-----------
* Per face, the Jacobian ``J`` is that of the affine map from the 3D triangle, written in an orthonormal
  frame of its own plane (``x`` along ``v1 - v0``, ``y = n x x`` with ``n`` the face normal, so the 3D
  triangle is counter-clockwise in it), to the UV triangle. A counter-clockwise UV triangle has
  ``det J > 0`` and a positive signed UV area.
* :func:`distortion` removes the global scale first: singular values are multiplied by
  ``uv_scale = sqrt(sum area_3d / sum |area_uv|)`` so total areas match (a true-scale map has
  ``uv_scale ~ 1``). Per face: ``iso = max(s1, 1/s2)``, ``conformal = s1/s2``,
  ``area = max(s1*s2, 1/(s1*s2))``; all equal 1 for an isometry.
* Flipped faces (signed UV area <= 0 after fixing a global mirror) have *infinite* distortion:
  ``*_max`` is ``inf`` whenever a face is flipped; ``*_mean`` is the area-weighted mean over the
  non-flipped faces only (reported together with ``flips`` and ``flipped_area_fraction``); ``*_p95`` is
  the area-weighted 95th percentile over all faces with flipped faces counted as ``inf``, so it is
  ``inf`` exactly when flipped faces cover more than 5% of the surface.
* Degenerate 3D faces (zero area, relative tolerance 1e-14 of the squared longest edge) carry no
  distortion: they are left out of every statistic and of the scale, and counted in
  ``degenerate_faces``. No statistic is NaN.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from heatparam.errors import MeshError
from heatparam.mesh.planar import polygon_area, signed_areas
from heatparam.mesh.topology import (
    boundary_edges,
    boundary_loops,
    pairs_in_groups,
    unique_ints,
    unique_inverse,
    zero_area,
)

__all__ = [
    "PerFaceDistortion",
    "angle_sums",
    "border_wraps",
    "boundary_crossings",
    "corner_angles",
    "crossing_pairs",
    "diameter",
    "distortion",
    "face_jacobian_singular_values",
    "layout_error",
    "layout_rmse",
    "per_face_distortion",
    "rigid_align",
    "stress",
    "summary",
    "true_scale_iso",
    "weld_uv",
    "wrapped",
]

_P = 0.95  # percentile reported as *_p95
#: :func:`_weighted_quantile` sorts only the values above the one of rank 1 - this × (1 - q) (the top 20% for a
#: p95), unless their weight falls short of 1 - q (weights vary up to ~4x across a scan); ...
QUANTILE_TAIL = 4.0
#: ... in arrays of at least this many values (below, one sort is as fast)
QUANTILE_TAIL_MIN = 4096
_CELL_MAX = 32  # a grid cell with more edges than this is refined (boundary_crossings)
_MAX_DEPTH = 4  # refinement levels of the crossing grid
_REFINE = 4.0  # cell size divisor per refinement level
_MAX_ENTRIES = 20_000_000  # (edge, cell) entries allowed per refinement level
# a border vertex whose corner angles sum to within this of 2π (rad) has its border touching itself (summation
# rounding is ~1e-14, any real gap far larger)
WRAP_TOL = 1e-9


# ----------------------------------------------------------------------------------------------------------
# input checks
# ----------------------------------------------------------------------------------------------------------
def _points(X: Any, dim: int, name: str) -> np.ndarray:
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != dim:
        raise MeshError(f"{name} must have shape (n, {dim}), got {X.shape}")
    return X


def _check_finite(X: np.ndarray, F: np.ndarray, name: str) -> None:
    """Raise unless every row of X referenced by F is finite (unreferenced rows may hold anything)."""
    used = np.zeros(len(X), dtype=bool)
    used[F.ravel()] = True
    if not np.isfinite(X[used]).all():
        raise MeshError(f"{name} contains NaN or infinite coordinates")


def _faces(F: Any, n: int, name: str) -> np.ndarray:
    F = np.asarray(F)
    if F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(f"{name} must have shape (m, 3), got {F.shape}")
    if F.size and not np.issubdtype(F.dtype, np.integer):
        raise MeshError(f"{name} must hold integer indices, got dtype {F.dtype}")
    F = F.astype(np.int64, copy=False)
    if F.size and (F.min() < 0 or F.max() >= n):
        raise MeshError(f"{name} indexes outside 0..{n - 1}")
    return F


def _uv_faces(F: np.ndarray, uv: Any, Fuv: Any | None) -> tuple[np.ndarray, np.ndarray]:
    uv = _points(uv, 2, "uv")
    if Fuv is None:
        if F.size and F.max() >= len(uv):
            raise MeshError(
                f"uv has {len(uv)} rows but F indexes vertex {F.max()}; pass Fuv for per-corner UVs"
            )
        Fuv = F
    else:
        Fuv = _faces(Fuv, len(uv), "Fuv")
        if Fuv.shape != F.shape:
            raise MeshError(f"Fuv must have the shape of F {F.shape}, got {Fuv.shape}")
    _check_finite(uv, Fuv, "uv")
    return uv, Fuv


# ----------------------------------------------------------------------------------------------------------
# per-face Jacobians and distortion
# ----------------------------------------------------------------------------------------------------------
def face_jacobian_singular_values(
    V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Singular values of the per-face Jacobian of the 3D -> UV map.

    Parameters
    ----------
    V, F, uv : (n, 3) float64 vertices, (m, 3) int64 triangles, (n_uv, 2) float64 texture coordinates.
    Fuv : (m, 3) int64 or None
        Per-corner indices into ``uv``; None means ``F``.

    Returns
    -------
    sigma1, sigma2 : (m,) float64
        ``sigma1 >= sigma2 >= 0`` (closed form for 2x2). Degenerate 3D faces (zero area) get
        ``sigma1 = inf, sigma2 = 0``.
    signed_area_uv : (m,) float64
        Signed UV area, positive for a counter-clockwise UV triangle (same orientation as the 3D
        triangle in its local frame).
    area_3d : (m,) float64
        3D triangle areas.
    """
    V = _points(V, 3, "V")
    F = _faces(F, len(V), "F")
    _check_finite(V, F, "V")
    uv, Fuv = _uv_faces(F, uv, Fuv)

    p0 = V[F[:, 0]]
    e1 = V[F[:, 1]] - p0
    e2 = V[F[:, 2]] - p0
    e3 = e2 - e1
    x1, y1, z1 = e1.T
    x2, y2, z2 = e2.T
    nn = np.sqrt((y1 * z2 - z1 * y2) ** 2 + (z1 * x2 - x1 * z2) ** 2 + (x1 * y2 - y1 * x2) ** 2)  # 2 * area
    L2 = x1 * x1 + y1 * y1 + z1 * z1
    dot = x1 * x2 + y1 * y2 + z1 * z2
    longest2 = np.maximum(np.maximum(L2, x2 * x2 + y2 * y2 + z2 * z2), np.einsum("ij,ij->i", e3, e3))
    degen = zero_area(nn, longest2, V, F)  # also catches longest2 == 0

    q0 = uv[Fuv[:, 0]]
    d1 = uv[Fuv[:, 1]] - q0
    d2 = uv[Fuv[:, 2]] - q0
    signed_uv = 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])

    # local 3D frame: p1 = (L, 0), p2 = (dot/L, nn/L);  J = [d1 d2] @ inv([p1 p2])
    L = np.sqrt(np.where(degen, 1.0, L2))
    Lnn = L * np.where(degen, 1.0, nn)
    a = d1[:, 0] / L
    c = d1[:, 1] / L
    b = (d2[:, 0] * L2 - d1[:, 0] * dot) / Lnn
    d = (d2[:, 1] * L2 - d1[:, 1] * dot) / Lnn

    # closed-form 2x2 SVD: J = conformal part (norm Q) + anti-conformal part (norm R); s1 = Q+R, s2 = |Q-R|
    Q = np.hypot(0.5 * (a + d), 0.5 * (c - b))
    R = np.hypot(0.5 * (a - d), 0.5 * (c + b))
    sigma1 = Q + R
    sigma2 = np.abs(Q - R)
    sigma1[degen] = np.inf
    sigma2[degen] = 0.0
    return sigma1, sigma2, signed_uv, 0.5 * nn


def true_scale_iso(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per face: max(sigma1, 1/sigma2) of the map as it is (no global rescaling; inf on flipped, collapsed and
    degenerate faces), the 3D area and the signed UV area (:func:`face_jacobian_singular_values`); (m,) each."""
    s1, s2, sa, a3 = face_jacobian_singular_values(V, F, uv, Fuv)
    with np.errstate(divide="ignore", invalid="ignore"):
        iso = np.where((sa > 0) & (s2 > 0), np.maximum(s1, 1.0 / s2), np.inf)
    return iso, a3, sa


class PerFaceDistortion(NamedTuple):
    """Per-face distortion after global scale normalization (all (m,); inf on flipped/degenerate faces)."""

    iso: np.ndarray
    conformal: np.ndarray
    area: np.ndarray
    flipped: np.ndarray


class _Analysis(NamedTuple):
    per_face: PerFaceDistortion
    weight: np.ndarray  # (m,) 3D areas
    valid: np.ndarray  # (m,) non-degenerate
    scale: float
    mirrored: bool
    area_3d: float
    area_uv: float


def _analyze(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None) -> _Analysis:
    s1, s2, sa, a3 = face_jacobian_singular_values(V, F, uv, Fuv)
    valid = np.isfinite(s1)
    if not valid.any():
        raise MeshError("every 3D face is degenerate (zero area): no distortion can be measured")
    area_3d = float(a3[valid].sum())
    area_uv = float(np.abs(sa[valid]).sum())
    if not area_uv > 0.0:
        raise MeshError("the UV layout has zero total area")
    scale = float(np.sqrt(area_3d / area_uv))
    neg = float(a3[valid & (sa < 0)].sum())
    pos = float(a3[valid & (sa > 0)].sum())
    mirrored = neg > pos
    flipped = valid & ((-sa if mirrored else sa) <= 0)
    good = valid & ~flipped

    m = len(s1)
    iso, conf, area = (np.full(m, np.inf) for _ in range(3))
    t1 = s1[good] * scale
    t2 = s2[good] * scale
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        iso[good] = np.maximum(t1, 1.0 / t2)
        conf[good] = t1 / t2
        det = t1 * t2
        area[good] = np.maximum(det, 1.0 / det)
    per_face = PerFaceDistortion(iso, conf, area, flipped)
    return _Analysis(per_face, a3, valid, scale, mirrored, area_3d, area_uv)


def per_face_distortion(
    V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None
) -> PerFaceDistortion:
    """Per-face distortion measures, for plotting.

    The UV is first scaled globally so total areas match. Parameters: as :func:`distortion`.

    Returns
    -------
    PerFaceDistortion
        Named tuple ``(iso, conformal, area, flipped)``: three (m,) float64 arrays
        (``max(s1, 1/s2)``, ``s1/s2``, ``max(s1 s2, 1/(s1 s2))``) and an (m,) bool array. Flipped faces
        (after fixing a global mirror) and degenerate 3D faces have ``inf`` in all three measures;
        degenerate faces have ``flipped == False``. Mask with ``np.isfinite`` before plotting.
    """
    return _analyze(V, F, uv, Fuv).per_face


def _weighted_quantile(x: np.ndarray, w: np.ndarray, q: float) -> float:
    """Smallest value whose cumulative weight fraction reaches ``q`` (inf values sort last).

    Only the values from a pivot up are sorted when the weight below the pivot is short of ``q`` (the answer is
    then among them): the pivot is the value of rank ``1 - QUANTILE_TAIL × (1 - q)`` (``np.partition``, linear).
    Sorted by numpy's quicksort, which without ties is the stable sort's unique order; with ties (flipped faces'
    inf, exact isometries) by the stable sort, so that the weights add up in the same order. A p95 of 378k faces:
    11 ms against 40-50 ms for a full sort."""
    base, k = 0.0, int(len(x) * (1.0 - QUANTILE_TAIL * (1.0 - q)))
    if len(x) >= QUANTILE_TAIL_MIN and 0 < k < len(x):
        pivot = np.partition(x, k)[k]
        low = x < pivot
        below = float(w[low].sum())
        if below < q * float(w.sum()):
            x, w, base = x[~low], w[~low], below
    order = np.argsort(x)
    xs = x[order]
    if len(x) > 1 and (xs[1:] == xs[:-1]).any():
        order = np.argsort(x, kind="stable")
    cw = base + np.cumsum(w[order])
    i = int(np.searchsorted(cw, q * cw[-1], side="left"))
    return float(x[order[min(i, len(x) - 1)]])


def distortion(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None) -> dict[str, Any]:
    """Scale-normalized distortion statistics of a parameterization.

    Parameters
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    uv : (n_uv, 2) float64
    Fuv : (m, 3) int64 or None

    Returns
    -------
    dict
        Python scalars only:

        - ``iso_mean, iso_p95, iso_max`` (and ``conformal_*``, ``area_*``): the mean is area-weighted over
          the non-flipped faces; p95 is the area-weighted 95th percentile over all non-degenerate faces
          with flipped faces as ``inf``; max is ``inf`` if any face is flipped. A mean over no face is inf.
        - ``flips``: non-degenerate faces with signed UV area <= 0 after orientation is fixed;
          ``flipped_area_fraction``: their share of the 3D area.
        - ``mirrored``: True when faces with negative UV area hold the majority of the 3D area; the whole
          map is then treated as mirrored (orientation reversed before counting flips).
        - ``uv_scale``: factor ``sqrt(total_area_3d / total_area_uv)`` applied to the UV before measuring.
        - ``total_area_3d, total_area_uv`` (sum of ``|signed UV area|``), ``faces``, ``degenerate_faces``.
    """
    an = _analyze(V, F, uv, Fuv)
    pf, w, valid = an.per_face, an.weight, an.valid
    good = valid & ~pf.flipped
    wg = w[good]
    wsum = float(wg.sum())
    out: dict[str, Any] = {}
    for name, x in (("iso", pf.iso), ("conformal", pf.conformal), ("area", pf.area)):
        out[f"{name}_mean"] = float(np.dot(wg, x[good]) / wsum) if wsum > 0 else float("inf")
        out[f"{name}_p95"] = _weighted_quantile(x[valid], w[valid], _P)
        out[f"{name}_max"] = float(x[valid].max())
    flips = int(pf.flipped.sum())
    out.update(
        flips=flips,
        flipped_area_fraction=float(w[pf.flipped].sum() / an.area_3d) if an.area_3d > 0 else 0.0,
        mirrored=bool(an.mirrored),
        uv_scale=an.scale,
        total_area_3d=an.area_3d,
        total_area_uv=an.area_uv,
        faces=len(w),
        degenerate_faces=int((~valid).sum()),
    )
    return out


def weld_uv(F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge per-corner UVs that belong to the same 3D vertex and have identical coordinates.

    OBJ exporters often duplicate texture coordinates per corner; after welding, only true seams (UV
    discontinuities) remain as UV boundary.

    Parameters
    ----------
    F : (m, 3) int64
    uv : (n_uv, 2) float64
    Fuv : (m, 3) int64

    Returns
    -------
    uv_w : (n_w, 2) float64, sorted by (vertex, u, v)
    Fuv_w : (m, 3) int64

    Coordinates are compared as they are (finite ones: :func:`summary` checks them first; corners that share a row
    holding NaN count as one).
    """
    F = np.asarray(F, dtype=np.int64)
    uv = np.asarray(uv, dtype=np.float64)
    Fuv = np.asarray(Fuv, dtype=np.int64)
    if F.size == 0:
        return np.zeros((0, 2)), Fuv.copy()
    # corners of one vertex and one uv row agree: the distinct (vertex, row) pairs are sorted by coordinates (a
    # 286k-face atlas: 145k pairs of 859k corners)
    _, first, pair = unique_inverse(F.ravel() * len(uv) + Fuv.ravel())
    vid, xy = F.ravel()[first], uv[Fuv.ravel()[first]]
    order = np.lexsort((xy[:, 1], xy[:, 0], vid))
    v_s, xy_s = vid[order], xy[order]
    new = np.ones(len(order), dtype=bool)
    new[1:] = (v_s[1:] != v_s[:-1]) | (xy_s[1:, 0] != xy_s[:-1, 0]) | (xy_s[1:, 1] != xy_s[:-1, 1])
    gid = np.empty(len(order), dtype=np.int64)
    gid[order] = np.cumsum(new) - 1
    return xy_s[new].copy(), gid[pair].reshape(F.shape)


# ----------------------------------------------------------------------------------------------------------
# boundary self-intersections
# ----------------------------------------------------------------------------------------------------------
def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _edge_cells(A: np.ndarray, B: np.ndarray, h: float, origin: np.ndarray) -> np.ndarray:
    """(k, 3) rows (edge, cx, cy): every grid cell each segment A[i]-B[i] passes through (deduplicated).

    Cells come from the two endpoints plus the two cells on either side of every grid-line crossing.
    """
    a = (A - origin) / h
    b = (B - origin) / h
    ca = np.floor(a).astype(np.int64)
    cb = np.floor(b).astype(np.int64)
    ne = len(A)
    eid = np.arange(ne, dtype=np.int64)
    parts = [np.column_stack([eid, ca]), np.column_stack([eid, cb])]
    for ax in (0, 1):
        other = 1 - ax
        lo = np.minimum(ca[:, ax], cb[:, ax])
        nx = np.abs(cb[:, ax] - ca[:, ax])
        tot = int(nx.sum())
        if tot == 0:
            continue
        e = np.repeat(eid, nx)
        k = lo[e] + 1 + (np.arange(tot) - np.repeat(np.cumsum(nx) - nx, nx))  # grid line index
        t = (k - a[e, ax]) / (b[e, ax] - a[e, ax])
        co = np.floor(a[e, other] + t * (b[e, other] - a[e, other])).astype(np.int64)
        c_lo = np.minimum(ca[e, other], cb[e, other])
        c_hi = np.maximum(ca[e, other], cb[e, other])
        co = np.clip(co, c_lo, c_hi)
        for kk in (k - 1, k):
            cell = np.empty((tot, 3), np.int64)
            cell[:, 0] = e
            cell[:, 1 + ax] = kk
            cell[:, 1 + other] = co
            parts.append(cell)
    rows = np.concatenate(parts)
    # the rows' bounds without a pass over them: edge ids 0..ne-1, every cell within its endpoints' cells
    lo = np.r_[0, np.minimum(ca.min(axis=0), cb.min(axis=0))]
    span = np.r_[ne, np.maximum(ca.max(axis=0), cb.max(axis=0))] - lo + 1
    if float(span[1]) * float(span[2]) * float(span[0]) < 2.0**62:  # one int64 key (cx, cy, edge): one sort
        key = unique_ints(((rows[:, 1] - lo[1]) * span[2] + rows[:, 2] - lo[2]) * span[0] + rows[:, 0] - lo[0])
        cell, e = np.divmod(key, span[0])
        cx, cy = np.divmod(cell, span[2])
        return np.column_stack([e + lo[0], cx + lo[1], cy + lo[2]])
    order = np.lexsort((rows[:, 0], rows[:, 2], rows[:, 1]))
    rows = rows[order]
    keep = np.ones(len(rows), dtype=bool)
    keep[1:] = (rows[1:] != rows[:-1]).any(axis=1)
    return rows[keep]


def _candidate_pairs(A: np.ndarray, B: np.ndarray, ids: np.ndarray, h: float, depth: int, out: list) -> None:
    """Append to ``out`` (k, 2) arrays of global edge ids whose segments share a grid cell of size ``h``."""
    Al, Bl = A[ids], B[ids]
    origin = np.minimum(Al.min(axis=0), Bl.min(axis=0))
    rows = _edge_cells(Al, Bl, h, origin)
    new = np.ones(len(rows), dtype=bool)
    new[1:] = (rows[1:, 1] != rows[:-1, 1]) | (rows[1:, 2] != rows[:-1, 2])
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(rows)))
    edges = ids[rows[:, 0]]
    dense = counts > _CELL_MAX
    if dense.any() and depth < _MAX_DEPTH:
        sub = unique_ints(rows[np.repeat(dense, counts), 0])
        h_sub = h / _REFINE
        span = np.abs(Bl[sub] - Al[sub]).sum() / h_sub + 2 * len(sub)
        if span <= _MAX_ENTRIES:
            out.append(pairs_in_groups(edges, starts[~dense], counts[~dense]))
            _candidate_pairs(A, B, ids[sub], h_sub, depth + 1, out)
            return
    out.append(pairs_in_groups(edges, starts, counts))


def segment_crossings(P: np.ndarray, E: np.ndarray) -> int:
    """Pairs of segments ``P[E[i]]`` that properly cross or overlap collinearly (shared indices skipped)."""
    return len(crossing_pairs(P, E))


def crossing_pairs(P: np.ndarray, E: np.ndarray) -> np.ndarray:
    """(k,2) int64 rows (i, j), i < j: the segments ``P[E[i]]``, ``P[E[j]]`` cross properly or overlap collinearly
    (pairs sharing an index skipped; :func:`segment_crossings` counts them)."""
    P = np.asarray(P, dtype=np.float64)
    E = np.asarray(E, dtype=np.int64)
    ne = len(E)
    none = np.zeros((0, 2), np.int64)
    if ne < 2:
        return none
    A, B = P[E[:, 0]], P[E[:, 1]]
    length = np.linalg.norm(B - A, axis=1)
    extent = float(np.max(np.maximum(A, B).max(axis=0) - np.minimum(A, B).min(axis=0)))
    if extent == 0.0:
        return none
    # cell ~ median edge length, but large enough that sum(len)/h stays O(#edges) and cells per axis bounded
    h = max(float(np.median(length)), float(length.mean()) / 4.0, extent / 4.0e6)
    chunks: list[np.ndarray] = []
    _candidate_pairs(A, B, np.arange(ne, dtype=np.int64), h, 0, chunks)
    cand = np.concatenate(chunks) if chunks else np.zeros((0, 2), np.int64)
    if len(cand) == 0:
        return none
    i = np.minimum(cand[:, 0], cand[:, 1])
    j = np.maximum(cand[:, 0], cand[:, 1])
    key = unique_ints(i[i != j] * ne + j[i != j])
    i, j = key // ne, key % ne
    ei, ej = E[i], E[j]
    share = (ei[:, :1] == ej).any(axis=1) | (ei[:, 1:] == ej).any(axis=1)
    i, j = i[~share], j[~share]
    p, q, r, s = A[i], B[i], A[j], B[j]
    o1, o2 = np.sign(_orient(p, q, r)), np.sign(_orient(p, q, s))
    o3, o4 = np.sign(_orient(r, s, p)), np.sign(_orient(r, s, q))
    hit = (o1 * o2 < 0) & (o3 * o4 < 0)
    col = (o1 == 0) & (o2 == 0) & (o3 == 0) & (o4 == 0)
    if col.any():
        p, q, r, s = p[col], q[col], r[col], s[col]
        d = np.abs(q - p) + np.abs(s - r)
        ax = (d[:, 1] > d[:, 0]).astype(np.int64)  # project on the dominant axis of the pair
        rng = np.arange(len(ax))
        pa, qa, ra, sa = p[rng, ax], q[rng, ax], r[rng, ax], s[rng, ax]
        lo = np.maximum(np.minimum(pa, qa), np.minimum(ra, sa))
        hi = np.minimum(np.maximum(pa, qa), np.maximum(ra, sa))
        hit[np.flatnonzero(col)[lo < hi]] = True
    return np.column_stack([i[hit], j[hit]])


def boundary_crossings(uv: np.ndarray, F: np.ndarray) -> int:
    """Global overlap check: number of intersecting pairs of UV boundary edges.

    All boundary edges (edges in exactly one face of ``F``: outer loop, holes, seams) are tested pairwise
    through a uniform grid (cell ~ median edge length, refined where crowded) with vectorized orientation
    predicates. Counted: pairs that cross properly (each segment's endpoints strictly on opposite sides of
    the other) and collinear pairs whose overlap has positive length. Pairs sharing a vertex index are
    skipped, and mere touching (an endpoint exactly on the other segment) is not counted; a boundary vertex
    where the boundary passes itself (its corner angles sum to more than 2π, :func:`border_wraps`: the two
    faces at the ends of its fan overlap, which no pair of edges sees, as they share the vertex) counts as one.
    A layout whose boundaries do not cross can still overlap only if one chart lies entirely inside another,
    which this does not detect.

    Parameters
    ----------
    uv : (n_uv, 2) float64
    F : (m, 3) int64
        Triangles indexing ``uv`` (pass ``Fuv`` for per-corner UVs, welded with :func:`weld_uv` if the
        corners are duplicated).

    Returns
    -------
    int
    """
    uv = _points(uv, 2, "uv")
    F = _faces(F, len(uv), "F")
    _check_finite(uv, F, "uv")
    E = boundary_edges(F)
    return segment_crossings(uv, E) + border_wraps(uv, F, unique_ints(E))


def corner_angles(T: np.ndarray) -> np.ndarray:
    """(m,3) the signed angle of each corner of the UV triangles ``T`` (m,3,2), in (-π, π]: positive on a
    counter-clockwise triangle."""
    e1 = np.roll(T, -1, axis=1) - T
    e2 = np.roll(T, 1, axis=1) - T
    return np.arctan2(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0], np.einsum("mjc,mjc->mj", e1, e2))


def border_wraps(uv: np.ndarray, F: np.ndarray, border: np.ndarray) -> int:
    """Number of the ``border`` rows (k,) of ``uv`` whose corner angles in ``F`` (m,3) sum to more than 2π (by
    more than :data:`WRAP_TOL`): there the border passes itself, the faces at the two ends of the vertex's fan
    overlapping. Touching (a sum of 2π: the two border edges on one ray) is not counted, as edges that only touch
    are not (:func:`wrapped` is the chart checks' stricter test)."""
    if not len(border):
        return 0
    return int(np.count_nonzero(angle_sums(uv, F)[border] > 2.0 * np.pi + WRAP_TOL))


def angle_sums(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n_uv,) per row of ``uv`` the sum of the signed corner angles of the faces ``F`` (m,3) there
    (:func:`corner_angles`): 2π inside a flip-free layout."""
    return np.bincount(F.ravel(), weights=corner_angles(uv[F]).ravel(), minlength=len(uv))


def wrapped(angle_sum: np.ndarray) -> np.ndarray:
    """bool per border vertex of a chart, of its corner angles' sum in the layout: 2π or more (less
    :data:`WRAP_TOL`), the border touching or passing itself there. The atlas refuses both where it chooses charts:
    a touch is one rounding away from an overlap (packing's translation made one so on a CAD part)."""
    return angle_sum >= 2.0 * np.pi - WRAP_TOL


def inverted_loops(uv: np.ndarray, F: np.ndarray) -> int:
    """Global overlap check of layouts with holes: boundary loops that wind the wrong way.

    A layout with no flipped face and no boundary crossing can still cover part of the plane twice when it has
    holes: a hole's loop turned inside out (traversed counter-clockwise, as the outer border is, when the faces are
    counter-clockwise) has faces on its inside, so the region it encloses is covered twice (halftunnel upsampled
    to 201k: its spectral conformal layout, 2 flipped faces untangled, turned a hole so). With every face of a
    connected piece oriented alike and the loops simple and disjoint, the piece is one-to-one exactly when one of
    its loops (the outer border) turns with its faces and every other against them: the covering number inside
    the loops is the sum of their winding numbers. Counted: for every connected piece of F, the loops whose signed
    area has the sign of the piece's total signed UV area, less one.

    Parameters
    ----------
    uv : (n_uv, 2) float64
    F : (m, 3) int64
        Triangles indexing ``uv`` (as :func:`boundary_crossings`: pass welded ``Fuv`` for per-corner UVs).

    Returns
    -------
    int
        0 for a layout whose pieces each have one outer border and holes that wind as holes; meaningful when no
        face is flipped and no boundary crosses (then 0 means the layout is one-to-one).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    uv = _points(uv, 2, "uv")
    F = _faces(F, len(uv), "F")
    loops = [lp for lp in boundary_loops(F) if len(lp) >= 3]
    if len(loops) <= 1:
        return 0
    n = len(uv)
    adj = coo_matrix((np.ones(2 * len(F)), (F[:, [0, 1]].ravel(), F[:, [1, 2]].ravel())), shape=(n, n))
    _, comp = connected_components(adj, directed=False)
    sign = np.sign(np.bincount(comp[F[:, 0]], weights=signed_areas(uv, F), minlength=comp.max() + 1))
    agree = np.zeros(len(sign), dtype=np.int64)
    for lp in loops:
        c = comp[lp[0]]
        agree[c] += polygon_area(uv[lp]) * sign[c] > 0
    return int(np.maximum(agree - 1, 0).sum())


# ----------------------------------------------------------------------------------------------------------
# stress and summary
# ----------------------------------------------------------------------------------------------------------
def stress(uv: np.ndarray, D: np.ndarray, sources: np.ndarray) -> float:
    """Relative RMS stress of UV distances against geodesic distances (no UV rescaling).

    ``sqrt(sum_ij (|uv_i - uv_{s_j}| - D_ij)^2 / sum_ij D_ij^2)`` over all vertices ``i`` and sources
    ``j``; non-finite ``D`` entries (unreachable vertices) are skipped.

    Parameters
    ----------
    uv : (n, 2) float64
    D : (n, k) float64
        Geodesic distances from each of the k sources to every vertex.
    sources : (k,) int64
        Vertex index of each source.

    Returns
    -------
    float
    """
    uv = _points(uv, 2, "uv")
    if not np.isfinite(uv).all():
        raise MeshError("uv contains NaN or infinite coordinates")
    D = np.asarray(D, dtype=np.float64)
    sources = np.asarray(sources, dtype=np.int64).ravel()
    n, k = len(uv), len(sources)
    if D.shape != (n, k):
        raise ValueError(f"D must have shape (n, k) = ({n}, {k}), got {D.shape}")
    if k and (sources.min() < 0 or sources.max() >= n):
        raise ValueError("sources index outside the vertex range")
    num = den = 0.0
    block = max(1, 4_000_000 // max(n, 1))
    for j0 in range(0, k, block):
        S = uv[sources[j0 : j0 + block]]
        dist = np.hypot(uv[:, 0, None] - S[None, :, 0], uv[:, 1, None] - S[None, :, 1])
        Db = D[:, j0 : j0 + block]
        ok = np.isfinite(Db)
        num += float(np.square(dist - Db, where=ok, out=np.zeros_like(Db)).sum())
        den += float(np.square(Db, where=ok, out=np.zeros_like(Db)).sum())
    if not den > 0.0:
        raise ValueError("stress is undefined: all geodesic distances are zero or non-finite")
    return float(np.sqrt(num / den))


def summary(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None) -> dict[str, Any]:
    """Distortion statistics plus global injectivity checks, as JSON-serializable Python scalars.

    Parameters: as :func:`distortion`.

    Returns
    -------
    dict
        Everything :func:`distortion` returns (``flips`` included), plus ``boundary_crossings`` (on the UV
        boundary; with ``Fuv`` the corners are welded first by :func:`weld_uv`), ``inverted_loops``
        (:func:`inverted_loops`: holes turned inside out) and ``bijective`` (``flips == 0``, no boundary crossing
        and no inverted loop; a globally mirrored map can be bijective).
        Infinite values (``*_max`` with flips) are Python ``inf``: ``json.dumps`` writes them as ``Infinity``.
    """
    out = distortion(V, F, uv, Fuv)
    F = np.asarray(F, dtype=np.int64)
    if Fuv is None:
        uv_b, F_b = uv, F
    else:
        uv_b, F_b = weld_uv(F, uv, Fuv)
    crossings = boundary_crossings(uv_b, F_b)
    out["boundary_crossings"] = int(crossings)
    out["inverted_loops"] = inverted_loops(uv_b, F_b)
    out["bijective"] = bool(out["flips"] == 0 and crossings == 0 and out["inverted_loops"] == 0)
    return out


# ----------------------------------------------------------------------------------------------------------
# layout error against a known flat layout
# ----------------------------------------------------------------------------------------------------------


def diameter(X: np.ndarray) -> float:
    """Largest pairwise distance of the points X (n,d), via the convex hull (no n^2 memory)."""
    X = np.asarray(X, dtype=np.float64)
    if len(X) < 2:
        return 0.0
    c = X - X.mean(axis=0)
    _, sv, Vt = np.linalg.svd(c, full_matrices=False)
    rank = int(np.sum(sv > 1e-9 * max(sv[0], 1e-300)))
    if rank == 0:
        return 0.0
    Y = c @ Vt[:rank].T  # coordinates in the affine span (planar points in 3D -> 2D)
    if rank == 1:
        return float(Y.max() - Y.min())
    from scipy.spatial import ConvexHull, QhullError

    try:
        P = Y[ConvexHull(Y).vertices]
    except QhullError:  # nearly degenerate: fall back to the extremes along the principal axis
        return float(Y[:, 0].max() - Y[:, 0].min())
    best = 0.0
    for i in range(0, len(P), 512):
        d = np.linalg.norm(P[i : i + 512, None, :] - P[None, :, :], axis=2)
        best = max(best, float(d.max()))
    return best


def rigid_align(uv: np.ndarray, uv_true: np.ndarray) -> np.ndarray:
    """Best rigid motion of uv onto uv_true (least squares; rotation, reflection, translation, NO scaling).

    Parameters
    ----------
    uv, uv_true : (n,d) corresponding points.

    Returns
    -------
    (n,d) float64 aligned copy of uv.
    """
    A = np.asarray(uv, dtype=np.float64)
    B = np.asarray(uv_true, dtype=np.float64)
    if A.shape != B.shape:
        raise ValueError(f"shape mismatch {A.shape} vs {B.shape}")
    ma, mb = A.mean(axis=0), B.mean(axis=0)
    U, _, Vt = np.linalg.svd((A - ma).T @ (B - mb))
    return (A - ma) @ (U @ Vt) + mb


def layout_error(uv: np.ndarray, uv_true: np.ndarray) -> float:
    """Max vertex distance after :func:`rigid_align`, divided by the diameter of uv_true (scale-sensitive)."""
    return float(np.linalg.norm(rigid_align(uv, uv_true) - uv_true, axis=1).max() / diameter(uv_true))


def layout_rmse(uv: np.ndarray, uv_true: np.ndarray) -> float:
    """Root-mean-square vertex distance after :func:`rigid_align`, divided by the diameter of uv_true."""
    d2 = np.sum((rigid_align(uv, uv_true) - uv_true) ** 2, axis=1)
    return float(np.sqrt(d2.mean()) / diameter(uv_true))
