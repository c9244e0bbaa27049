"""Planar geometry shared by the stages: signed areas, orientation, constrained Delaunay triangulation."""

from __future__ import annotations

import numpy as np


def signed_areas(P: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Signed areas (t,) of the triangles T (t,3) over points P (n,2); positive = counter-clockwise."""
    e1, e2 = P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def covered_area(P: np.ndarray, T: np.ndarray) -> float:
    """The area the triangles T (t,3) over P (n,2) cover, each counted positive (a layout's UV area)."""
    return float(np.abs(signed_areas(P, T)).sum())


def polygon_area(loop: np.ndarray) -> float:
    """Signed area of the closed polygon ``loop`` (k,2) (shoelace); positive = counter-clockwise."""
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def make_ccw(P: np.ndarray, T: np.ndarray) -> np.ndarray:
    """T (t,3) with every clockwise triangle's last two corners swapped (a copy)."""
    T = np.array(T, dtype=np.int64)
    cw = signed_areas(P, T) < 0
    T[cw] = T[cw][:, [0, 2, 1]]
    return T


def triangulate(P: np.ndarray, E: np.ndarray, *, max_area: float = 0.0, min_angle: float = 0.0,
                steiner: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Constrained Delaunay triangulation of the points P (n,2) with the segments E (e,2) (gpytoolbox's Triangle).

    The region is the inside of the segment loops by the even-odd rule (nested loops: holes). ``max_area`` /
    ``min_angle`` (radians) > 0 refine with Steiner points inside; ``steiner=False`` keeps the segments unsplit.
    Returns (points (n',2) float64, the input points first when none were moved, triangles (t,3) int64).

    Raises
    ------
    ValueError when Triangle fails (crossing segments, duplicate points).
    """
    import gpytoolbox as gpy

    try:
        P2, T = gpy.triangulate_polygon(P, E, a=max_area, q=min_angle, steiner=steiner)
    except (ValueError, RuntimeError) as exc:
        raise ValueError(f"constrained triangulation failed (segments touch or cross): {exc}") from exc
    return np.asarray(P2, dtype=np.float64), np.asarray(T, dtype=np.int64)


def shelf_pack(sizes: np.ndarray, width: float, gap: float) -> tuple[np.ndarray, float, float]:
    """Lower-left corners of boxes (w,h) on shelves of the given width, tallest first: (k,2), used w, used h."""
    order = np.lexsort((-sizes[:, 0], -sizes[:, 1]))
    pos = np.zeros((len(sizes), 2))
    x = y = shelf_h = 0.0
    used_w = 0.0
    for i in order:
        w, h = sizes[i]
        if x > 0 and x + w > width:
            y += shelf_h + gap
            x = shelf_h = 0.0
        pos[i] = (x, y)
        x += w + gap
        used_w = max(used_w, x - gap)
        shelf_h = max(shelf_h, h)
    return pos, used_w, y + shelf_h
