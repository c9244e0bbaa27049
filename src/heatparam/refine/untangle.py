"""Untangling: flip-free positions for some vertices of a layout with flipped triangles, the others held fixed.

Garanzha, Kaporin, Kudryavtseva, Protais, Ray, Sokolov, *Foldover-free maps in 50 lines of code* (ACM TOG 40(4),
2021). Each triangle's Jacobian J (2×2, from its rest triangle in 3D to the layout) with D = det J enters through

    χ(D, ε) = (D + √(ε² + D²)) / 2        (> 0 for every D, → D for D > 0 as ε → 0)
    E_ε = Σ_f A_f [ (1 − λ) tr(JᵀJ) / χ(D, ε) + λ (D² + 1) / χ(D, ε) ]

(a shape term and an area term, both finite for flipped triangles while ε > 0). E_ε is minimized by L-BFGS
(scipy) over the free vertices for a decreasing sequence of ε; once no triangle is flipped a last minimization
with ε ≈ 0 (a barrier: χ ≈ D) improves the worst triangles without flipping them. λ = 1/2 (the paper's λ is a
free parameter): with a small λ the repaired triangles come out thin (a 50k-vertex halftunnel's coarse-to-fine
start: symmetric Dirichlet energy 36 after λ = 10⁻³, 1.36 after λ = 1/2).

Used by :meth:`heatparam.refine.multilevel.CoarseLevel.repaired` where the mean value repair of a prolongation fails
(flips beside a locked, non-convex boundary: mean value interpolation is flip-free only inside convex regions).
"""

from __future__ import annotations

import numpy as np

from heatparam.refine.energy import det, jacobians, scatter

#: Weight of the area term against the shape term.
UNTANGLE_LAMBDA = 0.5

#: ε is divided by this while flips remain ...
EPS_DECAY = 10.0

#: ... at most this many times (one L-BFGS minimization each).
UNTANGLE_ROUNDS = 12

#: L-BFGS iterations per minimization.
UNTANGLE_MAX_ITERS = 300

#: ε of the last minimization, once the layout is flip-free (a barrier; J is measured against the 3D triangles, so
#: D is about 1).
BARRIER_EPS = 1e-6


def untangle(x: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, free: np.ndarray
             ) -> tuple[np.ndarray | None, int]:
    """Move the ``free`` vertices of the layout ``x`` until no triangle of F is flipped (module docstring).

    Parameters
    ----------
    x : (n,2) float64 layout, some triangles flipped (det J ≤ 0).
    F : (m,3) int64 triangles; g : (m,3,2) hat gradients of their rest (3D) triangles; area : (m,) their areas.
    free : (n,) bool, the vertices that may move; every other vertex keeps its position exactly.

    Returns
    -------
    (layout (n,2) with every triangle positive, or None when flips remain; the number of minimizations run).
    """
    y = np.array(x, dtype=np.float64, copy=True)
    fi = np.flatnonzero(free)
    faces = np.flatnonzero(free[F].any(axis=1))
    if not len(fi) or not len(faces):
        return None, 0
    held = np.ones(len(F), dtype=bool)
    held[faces] = False
    if (det(jacobians(y, F[held], g[held])) <= 0).any():  # a flipped triangle without a free corner stays so
        return None, 0
    Fr, gr = F[faces], g[faces]
    w = area[faces] / float(area[faces].mean())
    problem = (y, fi, Fr, gr, w)
    dmin = float(det(jacobians(y, Fr, gr)).min())
    eps = max(1e-3, 2.0 * abs(min(dmin, 0.0)))
    for r in range(1, UNTANGLE_ROUNDS + 1):
        _minimize(eps, *problem)
        if not _flipped(y, Fr, gr):
            good = y.copy()
            _minimize(BARRIER_EPS, *problem)
            if _flipped(y, Fr, gr) or not np.isfinite(y).all():  # keep the flip-free layout of the last round
                y[:] = good
            return y, r + 1
        eps /= EPS_DECAY
    return None, UNTANGLE_ROUNDS


def _flipped(y: np.ndarray, Fr: np.ndarray, gr: np.ndarray) -> bool:
    return bool((det(jacobians(y, Fr, gr)) <= 0).any())


def _minimize(eps: float, y: np.ndarray, fi: np.ndarray, Fr: np.ndarray, gr: np.ndarray, w: np.ndarray) -> None:
    """One L-BFGS minimization of E_ε over the free vertices ``fi`` of y (in place) on the faces Fr (hat
    gradients gr, weights w: areas over their mean)."""
    from scipy.optimize import minimize  # here: only a failed repair untangles (the import is 0.06 s)

    res = minimize(_energy, y[fi].ravel(), args=(eps, y, fi, Fr, gr, w), jac=True, method="L-BFGS-B",
                   options={"maxiter": UNTANGLE_MAX_ITERS})
    y[fi] = res.x.reshape(-1, 2)


def _energy(z: np.ndarray, eps: float, y: np.ndarray, fi: np.ndarray, Fr: np.ndarray, gr: np.ndarray,
            w: np.ndarray) -> tuple[float, np.ndarray]:
    """E_ε (module docstring) with the free vertices at z (written into y) and its gradient with respect to z."""
    lam = UNTANGLE_LAMBDA
    with np.errstate(divide="ignore", invalid="ignore"):  # χ = 0 (D + s cancels for D ≪ -ε): E = inf, L-BFGS
        y[fi] = z.reshape(-1, 2)                          # backs off from such a point
        J = jacobians(y, Fr, gr)
        D = det(J)
        s = np.sqrt(eps * eps + D * D)
        chi = 0.5 * (D + s)
        dchi = 0.5 * (1.0 + D / s)
        T = (J * J).sum(axis=(1, 2))
        E = float(np.dot(w, ((1.0 - lam) * T + lam * (D * D + 1.0)) / chi))
        # dE/dJ: the shape term's 2J/χ plus (dE/dD) cof(J), cof(J) = dD/dJ
        dD = (-((1.0 - lam) * T + lam * (D * D + 1.0)) / chi ** 2 * dchi + lam * 2.0 * D / chi)
        cof = np.empty_like(J)
        cof[:, 0, 0], cof[:, 0, 1], cof[:, 1, 0], cof[:, 1, 1] = J[:, 1, 1], -J[:, 1, 0], -J[:, 0, 1], J[:, 0, 0]
        dJ = w[:, None, None] * ((1.0 - lam) * 2.0 * J / chi[:, None, None] + dD[:, None, None] * cof)
        return E, scatter(dJ, Fr, gr, len(y))[fi].ravel()


__all__ = ["untangle"]
