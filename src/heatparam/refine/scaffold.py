"""Global bijectivity by a scaffold (Jiang et al. 2017): the rest of a box around the layout, triangulated.

At every iteration of the polish the outside of the outer loop and the inside of every hole are triangulated
(constrained Delaunay, :func:`build_scaffold`; a fine level keeps the last triangulation while it holds,
:func:`scaffold_holds`) and join the energy with a small weight; no step lets a surface
triangle's det J cross zero, nor one of the scaffold it is in, so boundaries slide freely but never cross.

How far a step may go (:func:`feasible_step`): a scaffold triangle flipping is not a crossing — a thin triangle
between three nearly collinear boundary vertices flips as soon as that stretch of boundary turns from convex to
concave — so the step goes to 0.9 of the first scaffold's flip, and where that is short of the Newton step the
scaffold is re-triangulated there and the step goes on along the same direction, up to ``SCAFFOLD_CHAIN``
scaffolds, while no boundary vertex comes closer to a boundary edge than ``GAP_FRACTION`` of its distance at the
start of the step (:func:`boundary_gaps`; what keeps a chain from running the sides of a slit into each other to
round-off). Every point of the step lies in a stretch where one valid scaffold has no flipped triangle, so the
layout stays bijective.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from heatparam.mesh.planar import triangulate
from heatparam.refine.energy import hat_gradients, jacobians, max_step

SCAFFOLD_WEIGHT = 1e-2  # largest energy weight of one scaffold triangle, relative to the mean surface face's

SCAFFOLD_ADAPT = 2.0  # after an uncut Newton step the scaffold weight is divided by this, after a cut one multiplied

SCAFFOLD_WEIGHT_MIN = 1e-4  # ... within [SCAFFOLD_WEIGHT_MIN, 1] × SCAFFOLD_WEIGHT

SCAFFOLD_MARGIN = 0.5  # the box extends this fraction of the layout's extent beyond it on every side

#: At most this many scaffolds per step (:func:`feasible_step`); beetle's cut mesh from Tutte: 44 Newton
#: iterations with one scaffold per step, 24 with up to 8, the same minimum (docs/refine.md, "How far a step may go")
SCAFFOLD_CHAIN = 8

#: A chained step brings no boundary vertex closer to a boundary edge than this fraction of its distance at the
#: step's start (beetle's cut mesh: 0.01 → 24 iterations, 0.1 → 26, 0.3 → 31, the same minimum; a floor of 1e-3
#: of an edge instead stopped the polish at a worse one: the minimum has slits narrower than that)
GAP_FRACTION = 0.01

#: Boundary edges searched per vertex by :func:`boundary_gaps` (nearest midpoints)
GAP_NEIGHBOURS = 8

#: A re-triangulated stretch that comes too close is halved at most this many times, else the step ends before it
GAP_HALVINGS = 4

def loop_ranges(loops: list[np.ndarray]) -> list[np.ndarray]:
    """Where each loop sits in ``np.concatenate(loops)``: one index range per loop."""
    ends = np.cumsum([len(lp) for lp in loops])
    return [np.arange(e - len(lp), e) for e, lp in zip(ends, loops, strict=True)]

def loop_edges(ranges: list[np.ndarray]) -> np.ndarray:
    """Closed-polygon edges (e,2) of the index ranges of :func:`loop_ranges` (each range's last index joins its
    first), in one pass (an atlas's scaffold has a loop per chart)."""
    k = np.concatenate(ranges)
    nxt = np.empty_like(k)
    nxt[:-1] = k[1:]
    last = np.cumsum([len(r) for r in ranges]) - 1
    nxt[last] = [r[0] for r in ranges]
    return np.column_stack([k, nxt])

#: The polish keeps the last iteration's scaffold while each of its triangles keeps at least this fraction of the
#: signed area it had when triangulated (:func:`scaffold_holds`): the Hessian's sparsity pattern then stays the same
#: and PARDISO refactorizes without a new analysis. 0: always re-triangulate. 0.1 keeps more scaffolds than 0.5
#: (half the fine factorizations in place on beetle↑311k's cut map, the energy the same to 10 digits; BENCHMARKS.md
#: §24b); positivity alone did no better.
SCAFFOLD_KEEP = 0.1


class Scaffold(NamedTuple):
    F: np.ndarray  # (s,3) triangles over [surface vertices 0..n-1, then the box corners n..n+3]
    box: np.ndarray  # (4,2) box corners, fixed while this scaffold is used
    area: np.ndarray | None = None  # (s,) the triangles' signed areas in the layout they were triangulated in

def build_scaffold(uv: np.ndarray, loops: list[np.ndarray]) -> Scaffold:
    """Triangulate (constrained Delaunay, no Steiner points) the box around ``uv`` (n,2) minus the surface.

    The region is everything between a square box and the surface's outer loop, plus the inside of every hole:
    the loops nest (box ⊃ outer loop ⊃ holes), so CDT's even-odd nesting rule gives exactly that region.
    With every surface and scaffold triangle positively oriented, the layout is globally injective (the union is
    a triangulated square with a fixed boundary), so boundaries cannot cross or overlap.
    Requires the boundary loops of ``uv`` to be simple and disjoint (a bijective layout).
    """
    ids = np.concatenate(loops)
    P = uv[ids]
    lo, hi = P.min(axis=0), P.max(axis=0)
    c, r = 0.5 * (lo + hi), (0.5 + SCAFFOLD_MARGIN) * float((hi - lo).max())
    box = c + r * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    E = np.vstack([loop_edges(loop_ranges(loops)), len(ids) + np.array([[0, 1], [1, 2], [2, 3], [3, 0]])])
    try:
        P2, T = triangulate(np.vstack([P, box]), E)
    except ValueError as exc:
        raise ValueError(f"cannot triangulate the scaffold (boundary loops touch or cross): {exc}") from None
    if len(P2) != len(ids) + 4:
        raise ValueError("the scaffold triangulation added vertices (boundary loops touch or cross)")
    glob = np.concatenate([ids, len(uv) + np.arange(4)])
    sc = Scaffold(glob[T], box)
    return sc._replace(area=signed_areas(uv, sc))


def signed_areas(uv: np.ndarray, sc: Scaffold) -> np.ndarray:
    """Signed areas (s,) of the scaffold's triangles over the layout ``uv`` (n,2) and its box."""
    P = np.vstack([uv, sc.box])[sc.F]
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def scaffold_holds(uv: np.ndarray, sc: Scaffold) -> bool:
    """Whether the scaffold ``sc``, triangulated around an earlier layout, still serves the layout ``uv`` (n,2):
    every triangle positive (then surface and scaffold still tile the box: boundaries neither touch nor cross) and
    keeping ``SCAFFOLD_KEEP`` of its area at triangulation (no sliver a re-triangulation would have replaced)."""
    return SCAFFOLD_KEEP > 0 and sc.area is not None and bool(
        (signed_areas(uv, sc) >= SCAFFOLD_KEEP * sc.area).all())

def scaffold_matrix(F: np.ndarray, blocks: np.ndarray, n: int) -> sp.csc_matrix:
    """Sum the scaffold's 6×6 blocks into a (2n,2n) matrix; rows/columns of the fixed box corners are dropped."""
    ids = np.concatenate([F, F + n], axis=1)  # unknown index of (coordinate a, corner i) = a*n + v
    ids[:, :3][F >= n] = -1
    ids[:, 3:][F >= n] = -1
    r = np.repeat(ids, 6, axis=1).ravel()
    c = np.tile(ids, (1, 6)).ravel()
    ok = (r >= 0) & (c >= 0)
    return sp.csc_matrix((blocks.ravel()[ok], (r[ok], c[ok])), shape=(2 * n, 2 * n))


def boundary_gaps(uv: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Per boundary vertex (``np.concatenate(loops)`` order): its distance (b,) to the nearest boundary edge that
    does not end at it, among the ``GAP_NEIGHBOURS`` edges whose midpoints are nearest."""
    ids = np.concatenate(loops)
    E = ids[loop_edges(loop_ranges(loops))]
    A, B = uv[E[:, 0]], uv[E[:, 1]]
    P = uv[ids]
    _, j = cKDTree(0.5 * (A + B)).query(P, k=min(GAP_NEIGHBOURS, len(E)))
    j = j.reshape(len(ids), -1)
    px, py = P[:, :1], P[:, 1:]  # (b,1): against the (b,k) candidate edges, coordinate by coordinate
    ax, ay, bx, by = A[j, 0], A[j, 1], B[j, 0], B[j, 1]
    ex, ey = bx - ax, by - ay
    s = np.clip(((px - ax) * ex + (py - ay) * ey) / np.maximum(ex * ex + ey * ey, 1e-300), 0.0, 1.0)
    dist = np.hypot(px - ax - s * ex, py - ay - s * ey)
    dist[(E[j, 0] == ids[:, None]) | (E[j, 1] == ids[:, None])] = np.inf
    return dist.min(axis=1)


def feasible_step(uv: np.ndarray, d: np.ndarray, loops: list[np.ndarray], sc: Scaffold, target: float) -> float:
    """How far along the direction ``d`` (n,2) the layout ``uv`` (n,2) stays bijective (module docstring).

    Starts with the scaffold ``sc`` of ``uv``: 0.9 × the largest step before one of its triangles flips (the
    polish's classic fraction to the boundary), then a new scaffold there, and so on (at most
    ``SCAFFOLD_CHAIN``) until ``target`` is reached. A re-triangulated stretch that brings a boundary vertex closer
    to the boundary than ``GAP_FRACTION`` of its gap at ``uv`` (:func:`boundary_gaps`) is halved until it does not
    (at most ``GAP_HALVINGS`` times, else dropped) and ends the chain. Returns t such that every point of [0, t] is
    bijective (surface flips are the caller's: ``energy.max_step``).
    """
    floor = None
    zero = np.zeros((4, 2))
    t = 0.0
    for k in range(SCAFFOLD_CHAIN):
        x = uv + t * d
        if k:
            try:
                sc = build_scaffold(x, loops)
            except ValueError:  # touching to round-off: stop where the last scaffold held
                return t
        xs = np.vstack([x, sc.box])
        gs = hat_gradients(xs[sc.F])
        dt = min(0.9 * max_step(jacobians(xs, sc.F, gs), jacobians(np.vstack([d, zero]), sc.F, gs)), target - t)
        full = dt
        if k:  # the first scaffold's 0.9 rule alone is the classic fraction to the boundary
            if floor is None:
                floor = GAP_FRACTION * boundary_gaps(uv, loops)
            for _ in range(GAP_HALVINGS):
                if (boundary_gaps(x + dt * d, loops) >= floor).all():
                    break
                dt *= 0.5
            else:
                return t
            if dt < full:
                return t + dt
        t += dt
        if t >= target:
            return t
    return t
