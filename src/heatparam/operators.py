"""FEM operators on a triangle mesh (paper Eq. 5-6): cotangent Laplacian L, mass B, gradient, divergence.

Sign convention: the paper writes L_ij = (cot α_ij + cot β_ij)/2 with a negative diagonal and then uses
(Δt·L + B) in Eq. 4, which is only positive definite for the *positive* semidefinite Laplacian. We use the
positive semidefinite stiffness matrix L = Gᵀ A G (off-diagonal −(cot α + cot β)/2, rows summing to 0), so
that Eq. 4 reads (Δt·L + B) u = B u₀ and Eq. 10 reads L φ = Gᵀ A X.

All operators are *intrinsic*: built from edge lengths only. Zero-area (degenerate) input faces are handled by
intrinsic mollification (Sharp & Crane 2020, "A Laplacian for nonmanifold triangle meshes", §4.5): a tiny
length ε is added to every edge so that each triangle satisfies the strict triangle inequality by δ.
"""

from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np
import scipy.sparse as sp

from heatparam.options import MASS_KINDS


def edge_lengths(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Edge lengths (m,3): column c is the length of the edge opposite corner c (libigl convention)."""
    return igl.edge_lengths(V, F)


def mollify(lengths: np.ndarray, delta: float) -> tuple[np.ndarray, float]:
    """Intrinsic mollification: add ε to all edge lengths so every triangle inequality holds by ≥ δ.

    Parameters
    ----------
    lengths : (m,3) edge lengths. delta : required slack (length units).

    Returns
    -------
    (m,3) mollified lengths, and ε (0.0 when no face needed it, so the lengths are unchanged).
    """
    slack = lengths.sum(axis=1, keepdims=True) - 2.0 * lengths  # (l_j + l_k - l_i) per corner
    eps = float(max(0.0, delta - slack.min()))
    return (lengths + eps if eps > 0 else lengths), eps


#: The mollification slack of :func:`mollified_lengths`, relative to the mean edge length (``build_operators``'s
#: default ``delta`` too)
MOLLIFY_REL = 1e-4


def mollified_lengths(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Edge lengths (m,3) of (V, F), mollified (:func:`mollify`) by ``MOLLIFY_REL`` × their mean: the intrinsic
    triangles the polish and the conformal layout take for zero-area faces."""
    raw = edge_lengths(V, F)
    return mollify(raw, MOLLIFY_REL * float(raw.mean()))[0]


def intrinsic_areas(lengths: np.ndarray) -> np.ndarray:
    """Triangle areas (m,) from edge lengths by Heron's formula (stable form)."""
    a, b, c = np.sort(lengths, axis=1)[:, ::-1].T  # a ≥ b ≥ c
    p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * np.sqrt(np.maximum(p, 0.0))


def cotan_laplacian(lengths: np.ndarray, F: np.ndarray) -> sp.csc_matrix:
    """Positive semidefinite cotangent Laplacian L (n,n), Eq. 5 with the sign flipped (see module doc)."""
    return (-igl.cotmatrix_intrinsic(lengths, F)).tocsc()


def mass_matrix(lengths: np.ndarray, F: np.ndarray, kind: str = "lumped") -> sp.csc_matrix:
    """Mass matrix B (n,n), summing to the surface area.

    ``consistent`` is Eq. 6 exactly (B_ij = (|t1|+|t2|)/12, B_ii = Σ_k B_ik); ``lumped`` puts a third of each
    incident triangle's area on the diagonal (the barycentric lumping used by the heat method of Crane et al.).
    """
    if kind == "consistent":
        return igl.massmatrix_intrinsic(lengths, F, igl.MASSMATRIX_TYPE_FULL).tocsc()
    if kind == "lumped":
        return igl.massmatrix_intrinsic(lengths, F, igl.MASSMATRIX_TYPE_BARYCENTRIC).tocsc()
    raise ValueError(f"mass matrix kind must be one of {MASS_KINDS}, got {kind!r}")


def local_triangles(lengths: np.ndarray) -> np.ndarray:
    """Each triangle laid in its own 2D frame from edge lengths: corner 0 at the origin, corner 1 on +x.

    Returns (m,3,2) corner positions, counter-clockwise.
    """
    l0, l1, l2 = lengths.T  # opposite corners 0,1,2: l2 = |p1-p0|, l1 = |p2-p0|, l0 = |p2-p1|
    x = (l2**2 + l1**2 - l0**2) / (2.0 * l2)
    y = np.sqrt(np.maximum(l1**2 - x**2, 0.0))
    P = np.zeros((len(lengths), 3, 2))
    P[:, 1, 0] = l2
    P[:, 2, 0] = x
    P[:, 2, 1] = y
    return P


def gradient_operator(lengths: np.ndarray, F: np.ndarray, n: int) -> sp.csr_matrix:
    """Per-face gradient G (2m, n) in each face's local frame: rows [0,m) are x, rows [m,2m) are y.

    ∇φ_i = J·(p_k − p_j)/(2|t|) for the counter-clockwise corners (i, j, k), J the 90° rotation.
    """
    m = len(F)
    P = local_triangles(lengths)
    area2 = (2.0 * intrinsic_areas(lengths))[:, None]
    e = np.roll(P, -2, axis=1) - np.roll(P, -1, axis=1)  # e[:, i] = p_k - p_j for (i, j, k) cyclic
    gx = -e[:, :, 1] / area2
    gy = e[:, :, 0] / area2
    # CSR directly, three entries per row with the column indices sorted (what COO → CSR conversion gives)
    s = np.argsort(F, axis=1, kind="stable")
    cols = np.take_along_axis(F, s, axis=1).ravel()
    vals = np.concatenate([np.take_along_axis(gx, s, axis=1).ravel(), np.take_along_axis(gy, s, axis=1).ravel()])
    indptr = np.arange(0, 6 * m + 1, 3, dtype=np.int64)
    return sp.csr_matrix((vals, np.concatenate([cols, cols]), indptr), shape=(2 * m, n))


def divergence_operator(G: sp.csr_matrix, areas: np.ndarray) -> sp.csr_matrix:
    """Divergence (n, 2m) of per-face vector fields, the negative adjoint of G: div = −Gᵀ·diag(A, A).

    With this sign, −div∘grad = Gᵀ A G = L (the discrete Green identity); Eq. 10 is L φ = −div X.
    """
    return (-(G.T @ sp.diags(np.concatenate([areas, areas])))).tocsr()


def _edge_keys(F: np.ndarray, n: int) -> np.ndarray:
    """(m,3) key of the edge opposite each corner of F (vertex ids < n)."""
    a, b = np.roll(F, -1, axis=1), np.roll(F, -2, axis=1)
    return np.minimum(a, b) * n + np.maximum(a, b)


def _restore_lengths(F0: np.ndarray, l0: np.ndarray, F1: np.ndarray, l1: np.ndarray,
                     keep: np.ndarray | None = None) -> np.ndarray:
    """Lengths for triangulation F1: the exact length l0 for every edge that F0 also has, else l1 (flipped); edges
    whose keys (:func:`_edge_keys`) are in the sorted array ``keep`` take l1 too."""
    n = int(max(F0.max(), F1.max())) + 1
    k0, k1 = _edge_keys(F0, n).ravel(), _edge_keys(F1, n).ravel()
    order = np.argsort(k0)
    pos = np.clip(np.searchsorted(k0[order], k1), 0, len(k0) - 1)
    hit = k0[order][pos] == k1
    if keep is not None and len(keep):
        hit &= keep[np.clip(np.searchsorted(keep, k1), 0, len(keep) - 1)] != k1
    out = l1.ravel().copy()
    out[hit] = l0.ravel()[order][pos[hit]]
    return out.reshape(l1.shape)


def _consistent_lengths(F0: np.ndarray, l0: np.ndarray, F1: np.ndarray, l1: np.ndarray) -> np.ndarray:
    """:func:`_restore_lengths`, made valid where mixing broke a triangle: the exact lengths l0 and the flipped
    triangulation's own l1 differ by the 2^-24 snapping, which a needle triangle's margin can be smaller than (a
    scan-like cylinder with holes and noise of 0.3 × the edge, 182k vertices: 3 intrinsic triangles of zero area,
    NaN cotangents, the heat factorization failed). Such triangles' edges take l1 (valid: the intrinsic Delaunay
    triangulation's own lengths), a few rounds, then every edge."""
    n = int(max(F0.max(), F1.max())) + 1
    keep = np.zeros(0, dtype=np.int64)
    for _ in range(4):
        lengths = _restore_lengths(F0, l0, F1, l1, keep)
        bad = ~(intrinsic_areas(lengths) > 0)
        if not bad.any():
            return lengths
        keep = np.union1d(keep, _edge_keys(F1[bad], n).ravel())
    return l1


@dataclass
class Operators:
    """FEM operators of one mesh, built once (precompute) and shared by the heat and Poisson solves."""

    L: sp.csc_matrix  # (n,n) PSD cotangent Laplacian
    B: sp.csc_matrix  # (n,n) mass matrix
    G: sp.csr_matrix  # (2m,n) per-face gradient in local frames
    D: sp.csr_matrix  # (n,2m) divergence
    areas: np.ndarray  # (m,) intrinsic face areas (after mollification)
    lengths: np.ndarray  # (m,3) edge lengths (after mollification) of the faces F below
    F: np.ndarray  # (m,3) the triangulation the operators live on (intrinsic Delaunay by default)
    mollify_eps: float  # length added to every edge (0.0: none needed)
    mass: str

    @property
    def mean_edge(self) -> float:
        return float(self.lengths.mean())

    @property
    def max_edge(self) -> float:
        return float(self.lengths.max())


def build_operators(V: np.ndarray, F: np.ndarray, mass: str = "lumped", delaunay: bool = True,
                    delta: float = MOLLIFY_REL) -> Operators:
    """Precompute L, B, G, div for (V (n,3), F (m,3)).

    delaunay : build the operators on the intrinsic Delaunay triangulation of the same surface (Bobenko &
        Springborn 2007; ``igl.intrinsic_delaunay_triangulation``): same vertices, same metric, edges flipped
        intrinsically until every cotangent weight is non-negative. On irregular meshes this is what makes the
        heat method accurate (camelhead.off, t = h²: mean geodesic error 2.2% → 1.2%); on good meshes it
        changes nothing.
    delta : mollification slack, relative to the mean edge length.
    """
    raw = edge_lengths(V, F)
    h = float(raw.mean())
    # Discrete decisions (which faces to mollify, which edges to flip) are taken on lengths in units of the
    # mean edge, snapped to 2^-24: a mesh scaled by s then gets the very same triangulation (exact Delaunay
    # ties on regular grids would otherwise be broken by rounding), so the map is exactly scale-invariant.
    unit = np.round(raw / h * 2.0**24) / 2.0**24
    unit, eps_unit = mollify(unit, delta)
    eps = eps_unit * h
    exact = raw + eps if eps > 0 else raw
    if delaunay:
        unit, F_idt = igl.intrinsic_delaunay_triangulation(unit, F)[:2]
        lengths = _consistent_lengths(F, exact, F_idt, unit * h)
        F = F_idt
    else:
        lengths = exact
    L = cotan_laplacian(lengths, F)
    B = mass_matrix(lengths, F, mass)
    G = gradient_operator(lengths, F, len(V))
    areas = intrinsic_areas(lengths)
    return Operators(L, B, G, divergence_operator(G, areas), areas, lengths, F, eps, mass)
