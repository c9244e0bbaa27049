"""The seams of an atlas: interior mesh edges whose two sides use different UV rows."""

from __future__ import annotations

import numpy as np

from heatparam.atlas.repair import half_edge_opposites
from heatparam.mesh.topology import unique_inverse

__all__ = ["chart_seam_lengths", "cut_half_edges", "seam_length"]


def seam_length(V: np.ndarray, F: np.ndarray, Fuv: np.ndarray, opp: np.ndarray | None = None,
                cut: np.ndarray | None = None) -> float:
    """Length of the interior mesh edges whose two sides have different UV rows (each edge once). opp (3m,): F's
    ``repair.half_edge_opposites`` and cut (3m,): :func:`cut_half_edges`, when the caller has them."""
    opp = half_edge_opposites(F) if opp is None else opp
    cut = cut_half_edges(F, Fuv, opp) if cut is None else cut
    h = np.flatnonzero(cut & (opp > np.arange(len(opp))))
    fa, ja = h // 3, h % 3
    a, b = F[fa, ja], F[fa, (ja + 1) % 3]
    # edges of 3+ faces (or of inconsistent orientation) are cut by the repair: count them too
    a_all, b_all = F.ravel(), F[:, [1, 2, 0]].ravel()
    n = len(V)
    key = np.minimum(a_all, b_all) * n + np.maximum(a_all, b_all)
    _, first, inv = unique_inverse(key)
    # the edges of 2+ half-edges none of which is welded (manifold, oriented)
    multi = first[(np.bincount(inv) >= 2) & (np.bincount(inv, weights=opp >= 0) == 0)]
    L = float(np.linalg.norm(V[b] - V[a], axis=1).sum())
    L += float(np.linalg.norm(V[b_all[multi]] - V[a_all[multi]], axis=1).sum())
    return L


def cut_half_edges(F: np.ndarray, Fuv: np.ndarray, opp: np.ndarray) -> np.ndarray:
    """(3m,) bool: half-edge ``3 f + j`` has an opposite (``repair.half_edge_opposites``) and the two sides of their
    edge use different UV rows (a seam of the atlas)."""
    h = np.flatnonzero(opp >= 0)
    o = opp[h]
    fa, ja, fb, jb = h // 3, h % 3, o // 3, o % 3
    cut = np.zeros(len(opp), dtype=bool)
    cut[h] = ~((Fuv[fa, ja] == Fuv[fb, (jb + 1) % 3]) & (Fuv[fa, (ja + 1) % 3] == Fuv[fb, jb]))
    return cut


def chart_seam_lengths(V: np.ndarray, F: np.ndarray, cut: np.ndarray, chart: np.ndarray, k: int) -> np.ndarray:
    """(k,) per chart (``chart`` (m,) of each face): the length of its cut half-edges (:func:`cut_half_edges`)."""
    h = np.arange(3 * len(F))
    fa, ja = h // 3, h % 3
    L = np.linalg.norm(V[F[fa, (ja + 1) % 3]] - V[F[fa, ja]], axis=1) * cut
    return np.bincount(chart[fa], weights=L, minlength=k)
