"""A start for a mesh cut open along seams: the uncut map with its slits opened slightly.

The bijective map of the uncut surface already lays out the cut surface: give every copy of a seam vertex its
source's position. Every face keeps its positive area, but each seam's two sides coincide (a zero-width slit), so
the boundary touches itself and the scaffold cannot be triangulated. :func:`open_slits` moves each copy a small
distance into its own side (along the inward normal of the cut boundary at it), shrinking the step wherever an
incident face would lose more than half its area, and accepts the result only when it is bijective (no flipped
face, no boundary crossing).

Measured (2026-12-01, ``bench/bench_seams.py``), it is not the default start of the cut mesh: on beetle its energy
is 1.0106 against Tutte's 37.6, but the polish from it ends in a worse minimum (1.0039 vs 1.0007, iso mean 1.041
vs 1.019) after more Newton iterations (67 vs 44): each slit's sides stay where the uncut map put them, facing each
other, and the scaffold keeps them from passing; opening the slits wider (0.45 instead of 0.25 of the shortest
edge) reached the same minimum. A free-boundary Newton step without the scaffold crosses the slits at once (its
direction shears the two sides past each other). On halftunnel LSCM's start is lower (1.218 vs 1.300) and wins.
``pipeline.seams.seams_stage(uncut_start=True)`` offers it as the candidate ``"uncut"``.
"""

from __future__ import annotations

import numpy as np

from heatparam import metrics

#: Each seam-vertex copy moves this fraction of its shortest incident edge (in the layout) into its own side ...
SLIT_STEP = 0.25

#: ... halved, for the vertices of any face that would keep less than this fraction of its signed area, ...
SLIT_MIN_AREA_FRACTION = 0.5

#: ... at most this many times.
SLIT_HALVINGS = 30


def _signed_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _inward_normals(uv: np.ndarray, F: np.ndarray, n: int) -> np.ndarray:
    """Per vertex (n,2): the sum of the unit left normals of the boundary half-edges into and out of it (the
    inside of a counter-clockwise face lies left of its edges), zero off the boundary."""
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = he[:, 0] * n + he[:, 1]
    rev = he[:, 1] * n + he[:, 0]
    bnd = he[~np.isin(key, rev)]  # half-edges whose twin is missing: the boundary, oriented as its face
    d = uv[bnd[:, 1]] - uv[bnd[:, 0]]
    length = np.linalg.norm(d, axis=1)
    d = d / np.where(length > 0, length, 1.0)[:, None]
    left = np.column_stack([-d[:, 1], d[:, 0]])
    out = np.zeros((n, 2))
    np.add.at(out, bnd[:, 0], left)
    np.add.at(out, bnd[:, 1], left)
    return out


def open_slits(uv: np.ndarray, F: np.ndarray, source: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """Open the zero-width slits of a cut mesh laid out by its uncut map.

    Parameters
    ----------
    uv : (n_s,2) float64, the cut mesh's vertices at their uncut positions (``uv_uncut[source]``), faces
        counter-clockwise.
    F : (m,3) int64, the cut mesh's faces.
    source : (n_s,) int64, the uncut vertex of each cut vertex (``mesh.seams.cut_open``); vertices sharing a
        source are the copies of one seam vertex.

    Returns
    -------
    (layout (n_s,2) or None, report): the layout is bijective (no flipped face, no boundary crossing); None with
    the reason in the report when no such opening was found.
    """
    uv = np.asarray(uv, dtype=np.float64)
    n = len(uv)
    counts = np.bincount(source)
    moved = np.flatnonzero(counts[source] > 1)
    if len(moved) == 0:
        return None, {"reason": "no seams"}
    area0 = _signed_areas(uv, F)
    if (area0 <= 0).any():
        return None, {"reason": f"the uncut map has {int((area0 <= 0).sum())} flipped faces"}
    normal = _inward_normals(uv, F, n)[moved]
    norm = np.linalg.norm(normal, axis=1)
    if (norm <= 1e-12).any():  # a copy whose boundary turns back on itself: no inward direction
        return None, {"reason": "a seam copy has no inward direction"}
    normal /= norm[:, None]
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    elen = np.linalg.norm(uv[edges[:, 0]] - uv[edges[:, 1]], axis=1)
    shortest = np.full(n, np.inf)
    np.minimum.at(shortest, edges[:, 0], elen)
    np.minimum.at(shortest, edges[:, 1], elen)
    step = SLIT_STEP * shortest[moved]
    is_moved = np.zeros(n, dtype=bool)
    is_moved[moved] = True
    touched = is_moved[F].any(axis=1)
    pos = np.full(n, -1)
    pos[moved] = np.arange(len(moved))
    halvings = 0
    while True:
        x = uv.copy()
        x[moved] += step[:, None] * normal
        bad = touched & (_signed_areas(x, F) < SLIT_MIN_AREA_FRACTION * area0)
        if not bad.any():
            break
        if halvings == SLIT_HALVINGS:
            return None, {"reason": f"faces beside the seams still shrink after {SLIT_HALVINGS} halvings"}
        vs = pos[F[bad]]
        step[np.unique(vs[vs >= 0])] *= 0.5
        halvings += 1
    crossings = int(metrics.boundary_crossings(x, F))
    if crossings:
        return None, {"reason": f"the opened slits cross a boundary ({crossings} pairs)"}
    return x, {"moved": int(len(moved)), "halvings": halvings}


__all__ = ["open_slits"]

