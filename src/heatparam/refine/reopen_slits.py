"""A start for a mesh cut open along seams: its conformal layout with the slits that cross reopened.

The conformal layout of the cut mesh (``layout.conformal``: free boundary) is smooth and low in energy, but where
a seam leaves a small hole the copies of its first edge can cross: the slit's mouth closes past zero width (beetle:
4 crossing pairs at two small holes). Then it is no start, and the polish would begin at Tutte's embedding (beetle:
energy 37.6 against 1.21). The crossings are local: the copies of every seam vertex on a crossing boundary edge are
moved to their mean (the slit closed there, as in the surface before the cut) and pushed a little into their own
sides (along the cut boundary's inward normal, the step shrunk wherever a face would lose half its area); where that
still leaves a crossing, the seam vertices near them join (``REOPEN_WIDEN``). The seams stage offers the result to
the refinement as the start candidate ``"conformal_reopened"`` (docs/history.md §14).
"""

from __future__ import annotations

import numpy as np

from heatparam import metrics
from heatparam.mesh.planar import signed_areas
from heatparam.mesh.topology import boundary_edges

#: Each seam-vertex copy moves this fraction of its shortest incident edge (in the layout) into its own side ...
SLIT_STEP = 0.25

#: ... halved, for the vertices of any face that would keep less than this fraction of its signed area, ...
SLIT_MIN_AREA_FRACTION = 0.5

#: ... at most this many times.
SLIT_HALVINGS = 30


def _inward_normals(uv: np.ndarray, bnd: np.ndarray) -> np.ndarray:
    """Per vertex (n,2): the sum of the unit left normals of the boundary half-edges ``bnd`` (k,2) into and out of it
    (the inside of a counter-clockwise face lies left of its edges), zero off the boundary."""
    d = uv[bnd[:, 1]] - uv[bnd[:, 0]]
    length = np.linalg.norm(d, axis=1)
    d = d / np.where(length > 0, length, 1.0)[:, None]
    left = np.column_stack([-d[:, 1], d[:, 0]])
    out = np.zeros((len(uv), 2))
    np.add.at(out, bnd[:, 0], left)
    np.add.at(out, bnd[:, 1], left)
    return out


def push_apart(uv: np.ndarray, F: np.ndarray, bnd: np.ndarray, moved: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """Push the vertex copies ``moved`` (k,) (of seam vertices, or of a vertex the repair split, lying on one point)
    of the layout ``uv`` (n,2), whose faces are all positive, ``SLIT_STEP`` × their shortest edge along the inward
    normal of the boundary ``bnd`` (k,2) (``mesh.topology.boundary_edges``) at them, halving the step of the
    vertices of any face left with less than ``SLIT_MIN_AREA_FRACTION`` of its area; (layout or None, report)."""
    n = len(uv)
    normal = _inward_normals(uv, bnd)[moved]
    norm = np.linalg.norm(normal, axis=1)
    if (norm <= 1e-12).any():  # a copy whose boundary turns back on itself: no inward direction
        return None, {"reason": "a seam copy has no inward direction"}
    normal /= norm[:, None]
    is_moved = np.zeros(n, dtype=bool)
    is_moved[moved] = True
    Ft = F[is_moved[F].any(axis=1)]  # the faces that move
    edges = np.concatenate([Ft[:, [0, 1]], Ft[:, [1, 2]], Ft[:, [2, 0]]])
    elen = np.linalg.norm(uv[edges[:, 0]] - uv[edges[:, 1]], axis=1)
    shortest = np.full(n, np.inf)
    np.minimum.at(shortest, edges[:, 0], elen)
    np.minimum.at(shortest, edges[:, 1], elen)
    step = SLIT_STEP * shortest[moved]
    area0 = signed_areas(uv, Ft)
    pos = np.full(n, -1)
    pos[moved] = np.arange(len(moved))
    halvings = 0
    while True:
        x = uv.copy()
        x[moved] += step[:, None] * normal
        bad = signed_areas(x, Ft) < SLIT_MIN_AREA_FRACTION * area0
        if not bad.any():
            break
        if halvings == SLIT_HALVINGS:
            return None, {"reason": f"faces beside the seams still shrink after {SLIT_HALVINGS} halvings"}
        vs = pos[Ft[bad]]
        step[np.unique(vs[vs >= 0])] *= 0.5
        halvings += 1
    crossings = len(metrics.crossing_pairs(x, bnd))
    if crossings:
        return None, {"reason": f"the opened slits cross a boundary ({crossings} pairs)"}
    return x, {"moved": int(len(moved)), "halvings": halvings}


#: :func:`reopen_crossing_slits` closes the seam vertices on crossing edges, then, until the reopened layout is
#: bijective, also the seam vertices within 1, 2, 4, ... up to this many seam edges of them (a slit's two sides
#: can lie swapped along a stretch, crossing only at its ends: beetle upsampled to 311k)
REOPEN_WIDEN = 64


def reopen_crossing_slits(uv: np.ndarray, F: np.ndarray, source: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """The conformal layout of a cut mesh with its crossing slits closed and opened again (module docstring).

    Parameters
    ----------
    uv : (n_s,2) float64, a layout of the cut mesh with no flipped face (its conformal layout), counter-clockwise.
    F : (m,3) int64, the cut mesh's faces.
    source : (n_s,) int64, the uncut vertex of each cut vertex (``mesh.seams.cut_open``).

    Returns
    -------
    (layout (n_s,2) or None, report): a bijective layout (no flipped face, no boundary crossing) that differs from
    ``uv`` only at the copies of the seam vertices the report's ``closed`` counts; None with the report's
    ``reason`` when ``uv`` has no crossing, a crossing without a seam copy on it, or none was found.
    """
    uv = np.asarray(uv, dtype=np.float64)
    flipped = int((signed_areas(uv, F) <= 0).sum())
    if flipped:
        return None, {"reason": f"the layout has {flipped} flipped faces"}
    bnd = boundary_edges(F)
    pairs = metrics.crossing_pairs(uv, bnd)
    if len(pairs) == 0:
        return None, {"reason": "no boundary crossing"}
    copies_of = np.bincount(source)
    copies = copies_of[source] > 1
    ends = np.unique(bnd[pairs.ravel()])
    closed = np.unique(source[ends[copies[ends]]])
    if len(closed) == 0:
        return None, {"reason": f"{len(pairs)} crossing boundary edge pairs without a seam vertex"}
    seam_edges = source[bnd[copies[bnd].all(axis=1)]]  # boundary edges along the seams, as uncut vertex pairs
    report: dict = {"crossings": int(len(pairs))}
    widen, reached = 0, 0
    while widen <= REOPEN_WIDEN:
        for _ in range(widen - reached):  # the seam vertices next to the closed ones join
            near = seam_edges[np.isin(seam_edges, closed).any(axis=1)].ravel()
            closed = np.union1d(closed, near)
        reached, widen = widen, max(1, 2 * widen)
        moved = np.flatnonzero(np.isin(source, closed))
        y = uv.copy()
        mean = np.zeros((len(copies_of), 2))
        np.add.at(mean, source[moved], uv[moved])
        y[moved] = (mean / np.maximum(copies_of, 1)[:, None])[source[moved]]
        report.update(closed=int(len(closed)), widened=reached)
        is_moved = np.zeros(len(uv), dtype=bool)
        is_moved[moved] = True
        if (signed_areas(y, F[is_moved[F].any(axis=1)]) <= 0).any():
            report["reason"] = "closing the slits flips a face"
            continue
        x, rep = push_apart(y, F, bnd, moved)
        report.update(rep)
        if x is not None:
            report.pop("reason", None)
            return x, report
    return None, report


__all__ = ["push_apart", "reopen_crossing_slits"]
