"""Packing charts without overlap: each chart turned to its minimum-area bounding rectangle, then shelf packing.

``scale``: true scale (model units), charts kept at their size, a gap of ``gap`` model units between boxes.
``texture``: every chart scaled by one common factor, as large as fits in [0,1]² with a gutter of
``padding / resolution`` between boxes (``padding`` pixels of a ``resolution``² texture) and half of it at the
border.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from heatparam.mesh.planar import shelf_pack

__all__ = ["min_area_rotation", "pack_charts"]


def min_area_rotation(P: np.ndarray) -> np.ndarray:
    """(2,2) rotation that puts the points' minimum-area bounding rectangle axis-aligned (rotating calipers)."""
    try:
        H = P[ConvexHull(P).vertices]
    except (QhullError, ValueError):
        return np.eye(2)
    E = np.roll(H, -1, axis=0) - H
    ang = np.arctan2(E[:, 1], E[:, 0])
    t = np.unique(np.mod(ang, np.pi / 2))
    c, s = np.cos(t), np.sin(t)
    R = np.stack([np.column_stack([c, s]), np.column_stack([-s, c])], axis=1)  # (T,2,2): one rotation per angle
    Q = H @ R.transpose(0, 2, 1)  # (T,h,2): the hull in each frame, all at once
    ext = Q.max(axis=1) - Q.min(axis=1)
    best, R_best = np.inf, np.eye(2)
    for i, area in enumerate((ext[:, 0] * ext[:, 1]).tolist()):  # the first of the smallest, as one by one
        if area < best - 1e-12 * abs(best if np.isfinite(best) else 1):
            best, R_best = area, R[i] if ext[i, 0] >= ext[i, 1] else np.array([[0, 1], [-1, 0]]) @ R[i]
    return R_best


def pack_charts(uvs: list[np.ndarray], Fs: list[np.ndarray], mode: str = "scale", padding: float = 4.0,
                resolution: int = 1024, gap: float | None = None) -> tuple[list[np.ndarray], dict]:
    """Place charts without overlap.

    Parameters
    ----------
    uvs : list of (n_i,2) float64 chart layouts (each bijective on its own). Fs : list of (m_i,3) int64 their
        triangles (for the packing efficiency).
    mode : ``scale`` or ``texture`` (module docstring).
    padding, resolution : the texture gutter in pixels and the texture size (``texture``).
    gap : ``scale`` mode gap in model units (default: 2% of the square root of the mean chart box area).

    Returns
    -------
    (placed layouts, info dict with ``scale`` (texture scale factor; 1 in scale mode), ``width``, ``height``,
    ``efficiency`` = summed chart UV area / area of the atlas rectangle ([0,1]² in texture mode)).
    """
    rot, sizes, areas = _upright(uvs, Fs)
    if mode == "scale":
        return _pack_scale(rot, sizes, areas, gap)
    if mode != "texture":
        raise ValueError(f"pack must be 'scale' or 'texture', got {mode!r}")
    return _pack_texture(rot, sizes, areas, float(padding) / float(resolution))


def _upright(uvs: list[np.ndarray], Fs: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Each chart turned to its minimum-area bounding rectangle, moved to the origin: (the layouts, (k,2) their
    boxes' sizes, (k,) their UV areas)."""
    rot = []
    sizes = np.zeros((len(uvs), 2))
    areas = np.zeros(len(uvs))
    for i, P in enumerate(uvs):
        R = min_area_rotation(P)
        Q = P @ R.T
        Q = Q - Q.min(axis=0)
        rot.append(Q)
        sizes[i] = Q.max(axis=0)
        T = Q[Fs[i]]
        e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
        areas[i] = 0.5 * float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())
    return rot, sizes, areas


def _pack_scale(rot: list[np.ndarray], sizes: np.ndarray, areas: np.ndarray, gap: float | None
                ) -> tuple[list[np.ndarray], dict]:
    """True scale: the shelf width (of a few tried) that gives the smallest rectangle."""
    g = gap if gap is not None else 0.02 * float(np.sqrt(np.mean(sizes[:, 0] * sizes[:, 1])) + 1e-300)
    total = float((sizes + g).prod(axis=1).sum())
    best = None
    for f in (0.8, 0.9, 1.0, 1.1, 1.25, 1.4, 1.6, 2.0):  # shelf widths: keep the smallest rectangle
        width = max(float(np.sqrt(total) * f), float(sizes[:, 0].max()))
        cand = shelf_pack(sizes, width, g)
        if best is None or cand[1] * cand[2] < best[1] * best[2]:
            best = cand
    pos, w, h = best
    out = [Q + pos[i] for i, Q in enumerate(rot)]
    return out, {"mode": "scale", "scale": 1.0, "width": w, "height": h, "gap": g,
                 "efficiency": float(areas.sum() / max(w * h, 1e-300))}


def _pack_texture(rot: list[np.ndarray], sizes: np.ndarray, areas: np.ndarray, g: float
                  ) -> tuple[list[np.ndarray], dict]:
    """One common scale, the largest that fits in [0,1]² with gutter ``g`` (bisection)."""
    hi = (1.0 - g) / max(float(sizes.max()), 1e-300)
    lo = 0.0
    if _texture_fit(sizes, hi, g)[0]:
        lo = hi
    else:
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if _texture_fit(sizes, mid, g)[0]:
                lo = mid
            else:
                hi = mid
    _, pos = _texture_fit(sizes, lo, g)
    out = [Q * lo + pos[i] + 0.5 * g for i, Q in enumerate(rot)]
    return out, {"mode": "texture", "scale": lo, "width": 1.0, "height": 1.0, "gutter": g,
                 "efficiency": float(areas.sum() * lo * lo)}


def _texture_fit(sizes: np.ndarray, s: float, g: float) -> tuple[bool, np.ndarray | None]:
    """Whether the charts scaled by ``s`` fit in [0,1]² with gutter ``g``, and the boxes' shelf positions."""
    inner = 1.0 - g
    if (sizes * s).max() > inner:
        return False, None
    pos, _, h = shelf_pack(sizes * s, inner, g)
    return h <= inner, pos
