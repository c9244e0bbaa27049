"""Untangling: flip-free positions for some vertices of a layout with flipped triangles, the others held fixed.

Garanzha, Kaporin, Kudryavtseva, Protais, Ray, Sokolov, *Foldover-free maps in 50 lines of code* (ACM TOG 40(4),
2021). Each triangle's Jacobian J (2×2, from its rest triangle in 3D to the layout) with D = det J enters through

    χ(D, ε) = (D + √(ε² + D²)) / 2        (> 0 for every D, → D for D > 0 as ε → 0)
    E_ε = Σ_f A_f [ (1 − λ) tr(JᵀJ) / χ(D, ε) + λ (D² + 1) / χ(D, ε) ]

(a shape term and an area term, both finite for flipped triangles while ε > 0). E_ε is minimized over the free
vertices for a decreasing sequence of ε; once no triangle is flipped a last minimization with ε ≈ 0 (a barrier:
χ ≈ D) improves the worst triangles without flipping them. λ = 1/2 (the paper's λ is a free parameter): with a small
λ the repaired triangles come out thin (a 50k-vertex halftunnel's coarse-to-fine start: symmetric Dirichlet energy
36 after λ = 10⁻³, 1.36 after λ = 1/2).

Each minimization is a projected Newton iteration (each face's 4×4 Hessian in J clamped to its positive
eigenvalues, pulled back to its corners) on the faces at a free vertex only, with a backtracking line search: the
paper's L-BFGS needed 150-230 iterations per ε on a 57k-unknown repair region of a 150k-face scan, Newton 4-6, to the
same layout (29 → 5 s; docs/refine.md §5.4).

Used by :meth:`heatparam.refine.multilevel.CoarseLevel.repaired` where the mean value repair of a prolongation fails
(flips beside a locked, non-convex boundary: mean value interpolation is flip-free only inside convex regions).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from heatparam.refine.energy import det, jacobians
from heatparam.solvers import Factor, large_system_backend

#: Weight of the area term against the shape term.
UNTANGLE_LAMBDA = 0.5

#: ε is divided by this while flips remain ...
EPS_DECAY = 10.0

#: ... at most this many times (one minimization each).
UNTANGLE_ROUNDS = 12

#: A minimization ends when a Newton step lowers E_ε by less than this fraction of it ...
NEWTON_RTOL = 1e-6

#: ... or after this many steps.
NEWTON_MAX_ITERS = 50

#: ε of the last minimization, once the layout is flip-free (a barrier; J is measured against the 3D triangles, so
#: D is about 1).
BARRIER_EPS = 1e-6


def untangle(x: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, free: np.ndarray, floor: float = 0.0
             ) -> tuple[np.ndarray | None, int]:
    """Move the ``free`` vertices of the layout ``x`` until no triangle of F is flipped (module docstring).

    Parameters
    ----------
    x : (n,2) float64 layout, some triangles flipped (det J ≤ 0).
    F : (m,3) int64 triangles; g : (m,3,2) hat gradients of their rest (3D) triangles; area : (m,) their areas.
    free : (n,) bool, the vertices that may move; every other vertex keeps its position exactly.
    floor : a triangle whose det J is at most this counts as flipped (``BARRIER_EPS``: degenerate to round-off,
        below where the last minimization's barrier acts).

    Returns
    -------
    (layout (n,2) with every triangle positive, or None when flips remain; the number of minimizations run).
    """
    faces = np.flatnonzero(free[F].any(axis=1))
    if not free.any() or not len(faces):
        return None, 0
    held = np.ones(len(F), dtype=bool)
    held[faces] = False
    if (det(jacobians(x, F[held], g[held])) <= floor).any():  # a flipped triangle without a free corner stays so
        return None, 0
    region = _Region(x, F[faces], g[faces], area[faces], free)
    eps = max(1e-3, 2.0 * abs(min(float(region.dets().min()), 0.0)))
    for r in range(1, UNTANGLE_ROUNDS + 1):
        region.minimize(eps)
        if not region.flipped(floor):
            good = region.y.copy()
            region.minimize(BARRIER_EPS)
            if region.flipped(floor) or not np.isfinite(region.y).all():  # keep the flip-free layout of the last round
                region.y[:] = good
            y = np.array(x, dtype=np.float64, copy=True)
            y[region.verts] = region.y
            return y, r + 1
        eps /= EPS_DECAY
    return None, UNTANGLE_ROUNDS


#: ∇²(det J) in vec(J) = (J₀₀, J₀₁, J₁₀, J₁₁): constant, det J being quadratic
_DET_HESSIAN = np.array([[0, 0, 0, 1], [0, 0, -1, 0], [0, -1, 0, 0], [1, 0, 0, 0]], dtype=np.float64)


class _Region:
    """E_ε on the faces at a free vertex, over their vertices only: the positions ``y`` (k,2) of those vertices
    (``verts`` (k,) their ids), the free ones' unknowns ordered (u of every free vertex, then v), and the
    Hessian's sparsity pattern, built once."""

    def __init__(self, x: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, free: np.ndarray):
        self.verts, local = np.unique(F, return_inverse=True)
        self.F, self.g = local.reshape(-1, 3), g
        self.w = area / float(area.mean())
        self.y = np.array(x[self.verts], dtype=np.float64)
        self.fi = np.flatnonzero(free[self.verts])
        k = self.k = len(self.fi)
        col = np.full(len(self.verts), -1, dtype=np.int64)
        col[self.fi] = np.arange(k)
        cF = col[self.F]
        unknown = np.concatenate([cF, np.where(cF >= 0, cF + k, -1)], axis=1)  # (m,6): u₀ u₁ u₂ v₀ v₁ v₂
        R, C = np.repeat(unknown, 6, axis=1).ravel(), np.tile(unknown, (1, 6)).ravel()
        self.keep = (R >= 0) & (C >= 0)
        # CSC pattern: keys column-major, each face entry's place among them
        key, self.slot = np.unique(C[self.keep] * (2 * k) + R[self.keep], return_inverse=True)
        self.indices = (key % (2 * k)).astype(np.int32)
        self.indptr = np.searchsorted(key // (2 * k), np.arange(2 * k + 1)).astype(np.int32)
        self.fac: Factor | None = None

    def dets(self) -> np.ndarray:
        return det(jacobians(self.y, self.F, self.g))

    def flipped(self, floor: float = 0.0) -> bool:
        return bool((self.dets() <= floor).any())

    def energy(self, y: np.ndarray, eps: float) -> float:
        J = jacobians(y, self.F, self.g)
        return float(np.dot(self.w, _terms(J, eps)[0]))

    def minimize(self, eps: float) -> None:
        """Projected Newton on E_ε from ``y`` (in place), to ``NEWTON_RTOL``."""
        k, y = self.k, self.y
        for _ in range(NEWTON_MAX_ITERS):
            E, grad, H = self._system(eps)
            H = H + sp.identity(2 * k, format="csc") * (1e-9 * float(H.diagonal().mean()))
            # PARDISO where installed: its refactorizations keep the analysis of this fixed pattern (as the polish)
            self.fac = (Factor(H, large_system_backend(2 * k, min_unknowns=0)) if self.fac is None
                        else self.fac.refactor(H))
            d = -self.fac.solve(grad)
            slope = float(grad @ d)
            if not slope < 0:
                return
            t, z = 1.0, y.copy()
            while True:  # backtracking (Armijo): E_ε is finite everywhere while ε > 0
                z[self.fi] = y[self.fi] + t * np.stack([d[:k], d[k:]], axis=1)
                E1 = self.energy(z, eps)
                if E1 <= E + 1e-4 * t * slope or t < 1e-12:
                    break
                t *= 0.5
            if not E1 < E:
                return
            y[:] = z
            if E - E1 < NEWTON_RTOL * E:
                return

    def _system(self, eps: float) -> tuple[float, np.ndarray, sp.csc_matrix]:
        """E_ε, its gradient in the unknowns (2k,) and its PSD-projected Hessian (2k,2k)."""
        J = jacobians(self.y, self.F, self.g)
        m, w, g = len(J), self.w, self.g
        psi, dpsi, hpsi = _terms(J, eps, derivatives=True)
        lam, Q = np.linalg.eigh(hpsi)
        hpsi = np.matmul(Q * (np.maximum(lam, 0.0) * w[:, None])[:, None, :], Q.transpose(0, 2, 1))
        # J = Σ_i y_i ⊗ g_i: dJ[a,c]/dy[i,a] = g[i,c], so with B (m,4,6) the corner block is Bᵀ H B
        B = np.zeros((m, 4, 6))
        B[:, 0:2, 0:3] = g.transpose(0, 2, 1)
        B[:, 2:4, 3:6] = g.transpose(0, 2, 1)
        blocks = np.matmul(B.transpose(0, 2, 1), np.matmul(hpsi, B)).reshape(m, 36)
        dy = np.matmul(B.transpose(0, 2, 1), (w[:, None] * dpsi)[:, :, None])[:, :, 0]  # (m,6)
        n, idx = len(self.y), self.F.ravel()
        gu = np.bincount(idx, weights=dy[:, :3].ravel(), minlength=n)
        gv = np.bincount(idx, weights=dy[:, 3:].ravel(), minlength=n)
        data = np.bincount(self.slot, weights=blocks.ravel()[self.keep], minlength=len(self.indices))
        H = sp.csc_matrix((data, self.indices, self.indptr), shape=(2 * self.k, 2 * self.k))
        return float(np.dot(w, psi)), np.concatenate([gu[self.fi], gv[self.fi]]), H


def _terms(J: np.ndarray, eps: float, derivatives: bool = False):
    """Each face's term of E_ε before its weight, ψ (m,), and with ``derivatives`` its gradient (m,4) and Hessian
    (m,4,4) in vec(J) = (J₀₀, J₀₁, J₁₀, J₁₁): ψ = N / χ with N = (1 − λ)|J|² + λ(D² + 1)."""
    lam = UNTANGLE_LAMBDA
    D = det(J)
    s = np.sqrt(eps * eps + D * D)
    # χ = (D + s)/2 = ε² / (2(s − D)): the second form where D < 0, where the first cancels
    chi = np.where(D >= 0, 0.5 * (D + s), 0.5 * eps * eps / np.where(D >= 0, 1.0, s - D))
    N = (1.0 - lam) * (J * J).sum(axis=(1, 2)) + lam * (D * D + 1.0)
    psi = N / chi
    if not derivatives:
        return (psi,)
    m = len(J)
    vJ = J.reshape(m, 4)
    dD = np.stack([J[:, 1, 1], -J[:, 1, 0], -J[:, 0, 1], J[:, 0, 0]], axis=1)
    dN = 2.0 * (1.0 - lam) * vJ + 2.0 * lam * D[:, None] * dD
    chi_d = 0.5 * (1.0 + D / s)  # dχ/dD
    dchi = chi_d[:, None] * dD
    c = chi[:, None]
    grad = dN / c - N[:, None] * dchi / c**2
    d2N = 2.0 * (1.0 - lam) * np.eye(4) + 2.0 * lam * (_outer(dD, dD) + D[:, None, None] * _DET_HESSIAN)
    d2chi = (0.5 * eps * eps / s**3)[:, None, None] * _outer(dD, dD) + chi_d[:, None, None] * _DET_HESSIAN
    c = chi[:, None, None]
    Nc = N[:, None, None]
    hess = (d2N / c - (_outer(dN, dchi) + _outer(dchi, dN)) / c**2 - Nc * d2chi / c**2
            + 2.0 * Nc * _outer(dchi, dchi) / c**3)
    return psi, grad, hess


def _outer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise outer products (m,4,4) of a, b (m,4)."""
    return a[:, :, None] * b[:, None, :]


__all__ = ["untangle"]
