"""Global bijectivity by a scaffold (Jiang et al. 2017): the rest of a box around the layout, triangulated.

At every iteration of the polish the outside of the outer loop and the inside of every hole are triangulated
(constrained Delaunay, :func:`build_scaffold`) and join the energy with a small weight; the line search never lets
a surface or scaffold triangle's det J cross zero, so boundaries slide freely but never cross.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from heatparam.mesh.planar import triangulate

SCAFFOLD_WEIGHT = 1e-2  # largest energy weight of one scaffold triangle, relative to the mean surface face's

SCAFFOLD_ADAPT = 2.0  # after an uncut Newton step the scaffold weight is divided by this, after a cut one multiplied

SCAFFOLD_WEIGHT_MIN = 1e-4  # ... within [SCAFFOLD_WEIGHT_MIN, 1] × SCAFFOLD_WEIGHT

SCAFFOLD_MARGIN = 0.5  # the box extends this fraction of the layout's extent beyond it on every side

def loop_ranges(loops: list[np.ndarray]) -> list[np.ndarray]:
    """Where each loop sits in ``np.concatenate(loops)``: one index range per loop."""
    ends = np.cumsum([len(lp) for lp in loops])
    return [np.arange(e - len(lp), e) for e, lp in zip(ends, loops, strict=True)]

def loop_edges(ranges: list[np.ndarray]) -> np.ndarray:
    """Closed-polygon edges (e,2) of the index ranges of :func:`loop_ranges`."""
    return np.vstack([np.column_stack([k, np.roll(k, -1)]) for k in ranges])

class Scaffold(NamedTuple):
    F: np.ndarray  # (s,3) triangles over [surface vertices 0..n-1, then the box corners n..n+3]
    box: np.ndarray  # (4,2) box corners, fixed while this scaffold is used

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
    return Scaffold(glob[T], box)

def scaffold_matrix(F: np.ndarray, blocks: np.ndarray, n: int) -> sp.csc_matrix:
    """Sum the scaffold's 6×6 blocks into a (2n,2n) matrix; rows/columns of the fixed box corners are dropped."""
    ids = np.concatenate([F, F + n], axis=1)  # unknown index of (coordinate a, corner i) = a*n + v
    ids[:, :3][F >= n] = -1
    ids[:, 3:][F >= n] = -1
    r = np.repeat(ids, 6, axis=1).ravel()
    c = np.tile(ids, (1, 6)).ravel()
    ok = (r >= 0) & (c >= 0)
    return sp.csc_matrix((blocks.ravel()[ok], (r[ok], c[ok])), shape=(2 * n, 2 * n))
