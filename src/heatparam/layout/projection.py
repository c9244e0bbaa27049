"""The orthogonal projection onto the surface's mean plane: a start layout for height-field-like parts.

A single scan view, a range image, a face mask, a shallow cap or a sheet with gentle bends is a height field over
the plane of its area-weighted mean normal, so its projection there is a bijective layout: every hole stays a hole,
the ragged border stays where it is, and the distortion is only the slope's. The conformal layout of such a part
often crosses itself along a ragged border, leaving Tutte's embedding as the only bijective start: on range images
of the large-part family (``bench/large_family.py``, tuning seeds) energy 179-723 against the projection's ~1.02,
and ~50 Newton iterations to polish it. Where the part is not a height field (a cylinder rolled past a
half turn, a closed-ish cap) the projection folds and the start check (``refine.start``) rejects it like any other.
"""

from __future__ import annotations

import numpy as np

from heatparam.mesh.planar import signed_areas
from heatparam.mesh.topology import face_areas

#: Why :func:`projection_layout` gave no layout, as the reports say it
NO_MEAN_PLANE = "the faces' normals sum to zero: no mean plane"


def projection_layout(V: np.ndarray, F: np.ndarray) -> np.ndarray | None:
    """V (n,3), F (m,3) projected orthogonally onto the plane through the centroid normal to Σ_f A_f n_f (the faces'
    area-weighted normals), in a right-handed frame of that plane (so faces facing the normal are counter-clockwise),
    scaled to the surface's 3D area like the conformal layout. (n,2) float64, or None when the normals sum to zero
    (no mean plane)."""
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]).sum(axis=0)
    norm = float(np.linalg.norm(N))
    if not norm > 0.0 or not np.isfinite(norm):
        return None
    n = N / norm
    a = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])  # any axis not parallel to n
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    P = V - V.mean(axis=0)
    uv = np.column_stack([P @ a, P @ b])
    area2d = float(np.abs(signed_areas(uv, F)).sum())
    if not area2d > 0.0:
        return None
    return uv * np.sqrt(float(face_areas(V, F).sum()) / area2d)
