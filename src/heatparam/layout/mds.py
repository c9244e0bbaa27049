"""Classical multidimensional scaling (paper Eq. 11-14) and landmark MDS for large meshes.

Classical MDS: C = −½ J G² J (Eq. 12) is never formed; a Lanczos solver (``scipy.sparse.linalg.eigsh``)
finds its two largest eigenpairs through products with G², and Φ = [√λ1 V1, √λ2 V2] (Eq. 14).
Landmark MDS (de Silva & Tenenbaum 2004) runs classical MDS on k landmarks and places every vertex by
distance-based triangulation from its k landmark distances: O(n·k) memory and time.
SMACOF (``smacof``) then minimizes the raw stress of Eq. 1 itself by the Guttman transform, all-pairs or over
the n×k point-landmark pairs (``Options.stress``).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from heatparam.errors import HeatparamError
from heatparam.memory import require


def classical_mds(D: np.ndarray, dim: int = 2, seed: int = 0, overwrite: bool = False) -> np.ndarray:
    """Classical MDS of a symmetric distance matrix D (n,n), Eq. 11-14.

    Parameters
    ----------
    D : (n,n) symmetric geodesic distances. With ``overwrite`` it is squared in place (saves n² memory).
    dim : embedding dimension. seed : start vector of the Lanczos iteration (determinism).

    Returns
    -------
    (n,dim) coordinates, centred (Σφ_i = 0, the constraint of Eq. 1).
    """
    n = len(D)
    if not overwrite:
        require(8.0 * n * n, f"squared distance matrix {n} x {n}", "use geodesics='landmarks'")
        D = D.copy()
    np.square(D, out=D)
    G2 = D

    def matvec(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x).reshape(n, -1)
        y = G2 @ (x - x.mean(axis=0))
        return -0.5 * (y - y.mean(axis=0))  # C x = −½ J G² J x (Eq. 12)

    C = spla.LinearOperator((n, n), matvec=matvec, matmat=matvec, dtype=np.float64)
    v0 = np.random.default_rng(seed).standard_normal(n)
    lam, vec = spla.eigsh(C, k=dim, which="LA", v0=v0)
    return _coordinates(lam, vec)

def _coordinates(lam: np.ndarray, vec: np.ndarray) -> np.ndarray:
    order = np.argsort(lam)[::-1]
    lam, vec = lam[order], vec[:, order]
    if lam[-1] <= 0:
        raise HeatparamError(
            "MDS found fewer than two positive eigenvalues: the distances do not describe a surface "
            "(is the mesh degenerate or tiny?)"
        )
    X = vec * np.sqrt(lam)
    # Deterministic signs: the entry of largest magnitude of each axis is positive.
    idx = np.argmax(np.abs(X), axis=0)
    X *= np.sign(X[idx, np.arange(X.shape[1])])
    return X - X.mean(axis=0)

def landmark_mds(DL: np.ndarray, landmarks: np.ndarray | None = None, dim: int = 2,
                 Dkk: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Landmark MDS (de Silva & Tenenbaum 2004): embed n points from their distances to k landmarks.

    Parameters
    ----------
    DL : (n,k) geodesic distances from each landmark (column) to every point (row).
    landmarks : (k,) row of DL that is each landmark (when the landmarks are among the points), or
    Dkk : (k,k) distances among the landmarks (when they are not, e.g. landmarks on a fill surface M*).

    Returns
    -------
    (n,dim) point coordinates and (k,dim) landmark coordinates, in one frame centred on the points. On the
    landmarks this is classical MDS (Eq. 11-14) of the k×k block.
    """
    if Dkk is None:
        Dkk = DL[np.asarray(landmarks), :]
    k = len(Dkk)
    if k < dim + 1:
        raise HeatparamError(f"landmark MDS needs at least {dim + 1} landmarks, got {k}")
    Dk2 = (0.5 * (Dkk + Dkk.T)) ** 2
    mu = Dk2.mean(axis=0)
    J = np.eye(k) - 1.0 / k
    lam, vec = np.linalg.eigh(-0.5 * J @ Dk2 @ J)
    lam, vec = lam[::-1][:dim], vec[:, ::-1][:, :dim]
    if lam[-1] <= 0:
        raise HeatparamError("landmark MDS found fewer than two positive eigenvalues: degenerate landmarks")
    pinv = vec / np.sqrt(lam)  # L# of de Silva & Tenenbaum, (k,dim)
    X = np.empty((DL.shape[0], dim))
    step = max(1, int(2**25 // (8 * k)))  # rows per chunk: bounded scratch for the squared distances
    for s in range(0, len(X), step):
        X[s : s + step] = -0.5 * (DL[s : s + step].astype(np.float64) ** 2 - mu) @ pinv
    XL = vec * np.sqrt(lam)
    sign = np.sign(X[np.argmax(np.abs(X), axis=0), np.arange(dim)])
    centre = X.mean(axis=0)
    return (X - centre) * sign, (XL - centre) * sign

def smacof(X0: np.ndarray, D: np.ndarray, landmarks: np.ndarray | None = None, iters: int = 100,
           tol: float = 1e-5, weights: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Stress majorization (SMACOF, de Leeuw 1977; Borg & Groenen ch. 8) of the raw stress of Eq. 1.

    Minimizes σ(X) = Σ_(i,j) w_ij (|x_i − x_j| − d_ij)² over the pairs of the pattern, from the start X0, by the
    Guttman transform X ← V⁺ B(Z) Z with Z the current layout, V = Σ w_ij (e_i − e_j)(e_i − e_j)ᵀ the weighted
    Laplacian of the pattern and B(Z) = Σ r_ij (e_i − e_j)(e_i − e_j)ᵀ, r_ij = w_ij d_ij / |z_i − z_j| (0 where
    z_i = z_j). Each transform minimizes a quadratic majorizer of σ that touches it at Z, so σ never increases.
    V⁺ returns the centred solution (Σ x_i = 0, the constraint of Eq. 1).

    Patterns: all-pairs (``landmarks`` None; :class:`_AllPairs`): D (n,n) symmetric (as ``heat.all_pairs``
    returns it), every pair. landmarks (:class:`_Bipartite`): D (n,k), column j the distances from point
    ``landmarks[j]`` (k distinct row ids) to every point; only those n·k pairs enter σ, in O(n·k) memory and time
    per iteration.

    Parameters
    ----------
    X0 : (n,dim) start layout (e.g. the MDS layout). D : (n,n) or (n,k) distances (see Patterns).
    landmarks : (k,) int, row of each column of D; None for all-pairs. iters : cap on Guttman transforms.
    tol : stop when a transform lowers σ by less than this fraction of it.
    weights : w_ij ≥ 0, D's shape; None = 1 for every finite d_ij. Deterministic (no randomness).

    Returns
    -------
    X : (n,dim) float64, centred. info : dict with ``pattern``, ``pairs`` (number of d_ij used), ``iterations``
    (Guttman transforms), ``converged``, ``stress_start`` / ``stress_end`` (relative RMS,
    √(Σ w (|x_i − x_j| − d_ij)² / Σ w d_ij²), as ``metrics.stress``), ``history`` (relative RMS after each
    transform, start first) and ``seconds``.
    """
    t0 = time.perf_counter()
    X = np.array(X0, dtype=np.float64)
    pattern = _pattern(X, np.asarray(D), landmarks, weights)
    X, hist, it, converged = _majorize(pattern, X, iters, tol)
    rel = [float(np.sqrt(h / pattern.den)) for h in hist]
    info = {"pattern": pattern.name, "pairs": pattern.pairs, "iterations": it, "converged": converged,
            "stress_start": rel[0], "stress_end": rel[-1], "history": rel,
            "seconds": round(time.perf_counter() - t0, 4)}
    return X, info


def _pattern(X: np.ndarray, D: np.ndarray, landmarks: np.ndarray | None, weights: np.ndarray | None):
    """The checked pattern of :func:`smacof`'s arguments: :class:`_AllPairs` or :class:`_Bipartite`."""
    if X.ndim != 2:
        raise ValueError(f"X0 must be (n,dim), got shape {X.shape}")
    n = X.shape[0]
    if weights is not None:
        weights = np.asarray(weights, dtype=np.float64)
        if weights.shape != D.shape or (weights < 0).any():
            raise ValueError("weights must be non-negative with D's shape")
    if landmarks is None:
        if D.shape != (n, n):
            raise ValueError(f"all-pairs SMACOF needs D of shape ({n}, {n}), got {D.shape}")
        return _AllPairs(D, weights)
    lm = np.asarray(landmarks, dtype=np.int64).ravel()
    if D.shape != (n, len(lm)):
        raise ValueError(f"landmark SMACOF needs D of shape ({n}, {len(lm)}), got {D.shape}")
    if len(lm) < 2 or lm.min() < 0 or lm.max() >= n or len(np.unique(lm)) != len(lm):
        raise ValueError("landmarks must be at least 2 distinct row indices of D")
    return _Bipartite(D, lm, weights)


def _majorize(pattern, X: np.ndarray, iters: int, tol: float) -> tuple[np.ndarray, list[float], int, bool]:
    """Guttman transforms of X until σ drops by less than ``tol`` of itself, reaches 0 or ``iters`` transforms:
    (X, σ before each transform and at the end, transforms, converged)."""
    hist: list[float] = []
    it = 0
    while True:
        num, BZ = pattern.evaluate(X)
        hist.append(num)
        if len(hist) > 1 and hist[-2] - num <= tol * hist[-2]:
            return X, hist, it, True
        if it == iters or num == 0.0:
            return X, hist, it, num == 0.0
        X = pattern.solve(BZ, X)
        it += 1


_CHUNK = 2**21  # entries of an (rows, k) or (rows, n) scratch block: bounded extra memory per step

def _dist(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """|a_i − b_j| (len(A), len(B)) without a (·,·,dim) temporary."""
    out = np.zeros((len(A), len(B)))
    for c in range(A.shape[1]):
        out += np.square(A[:, c, None] - B[None, :, c])
    return np.sqrt(out, out=out)

def _cholesky(M: np.ndarray, failure: str):
    """Dense Cholesky factor of the SPD matrix M (overwritten); HeatparamError("SMACOF: " + failure) if it is not."""
    try:
        return sla.cho_factor(M, overwrite_a=True)
    except np.linalg.LinAlgError:
        raise HeatparamError(f"SMACOF: {failure}") from None


def _ratio(W: np.ndarray | None, Dc: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """r = w d / |z_i − z_j| (0 where the distance is 0 or d is not finite)."""
    return np.divide(Dc if W is None else W * Dc, dist, out=np.zeros_like(dist), where=dist > 0)

class _AllPairs:
    """Every pair of D (n,n). With unit weights V = n·I − 11ᵀ and V⁺ B Z = B Z / n (B Z is centred): no solve.
    With weights (n,n) symmetric, or non-finite entries of D (weight 0), V is factorized once (dense Cholesky of
    V + 11ᵀ/n; O(n³))."""

    name = "all-pairs"

    def __init__(self, D: np.ndarray, W: np.ndarray | None):
        n = len(D)
        finite = bool(np.isfinite(D).all())
        if not finite:
            W = np.where(np.isfinite(D), 1.0 if W is None else W, 0.0)
        self.D = np.where(np.isfinite(D), D, 0.0) if not finite else D
        self.W = W
        self.n = n
        self.step = max(1, _CHUNK // max(n, 1))
        self.den = 0.0
        for s in range(0, n, self.step):
            Dc = self.D[s : s + self.step]
            self.den += float(np.square(Dc).sum() if W is None else (W[s : s + self.step] * Dc * Dc).sum())
        self.pairs = n * (n - 1) if W is None else int(np.count_nonzero(W) - np.count_nonzero(np.diag(W)))
        if not self.den > 0:
            raise HeatparamError("SMACOF: all distances are zero or non-finite")
        self.factor = None
        if W is not None:
            require(8.0 * n * n, f"SMACOF weighted Laplacian {n} x {n}", "use unit weights or landmarks")
            Vm = -0.5 * (W + W.T)
            np.fill_diagonal(Vm, 0.0)
            np.fill_diagonal(Vm, -Vm.sum(axis=1))
            Vm += 1.0 / n
            self.factor = _cholesky(Vm, "the weighted pairs do not connect all points")

    def evaluate(self, X: np.ndarray) -> tuple[float, np.ndarray]:
        num = 0.0
        BZ = np.empty_like(X)
        for s in range(0, self.n, self.step):
            e = min(self.n, s + self.step)
            dist = _dist(X[s:e], X)
            Dc = self.D[s:e]
            Wc = None if self.W is None else self.W[s:e]
            r = _ratio(Wc, Dc, dist)
            BZ[s:e] = X[s:e] * r.sum(axis=1)[:, None] - r @ X
            dist -= Dc  # now the residual |z_i − z_j| − d_ij
            num += float(np.vdot(dist, dist) if Wc is None else np.vdot(dist, Wc * dist))
        return num, BZ

    def solve(self, BZ: np.ndarray, X: np.ndarray) -> np.ndarray:
        if self.factor is None:
            Y = BZ / self.n  # V = n·I − 11ᵀ, V⁺ = J/n
        else:
            Y = sla.cho_solve(self.factor, BZ)
        return Y - Y.mean(axis=0)

class _Bipartite:
    """The n·k point-landmark pairs of D (n,k) (a pair of two landmarks twice, once per direction; the pair of a
    landmark with itself not at all), never an n×n array.

    The pattern is bipartite: a non-landmark point touches only landmarks, so V's block on the non-landmark points
    P is the diagonal of their degrees Δ_P and V = [[Δ_P, −W_P], [−W_Pᵀ, V_L]] (W_P (|P|,k) their weights). V x = y
    is solved by the Schur complement on the landmarks, S = V_L − W_Pᵀ Δ_P⁻¹ W_P (k×k, singular along 1: S + 11ᵀ/k
    is Cholesky-factorized once): x_L = S⁺ (y_L + W_Pᵀ Δ_P⁻¹ y_P), x_P = Δ_P⁻¹ (y_P + W_P x_L), then x is centred.
    This is exactly V⁺ y (y = B Z sums to zero); a sparse Cholesky of V with the landmarks ordered last performs
    the same elimination. A point with no finite distance (degree 0) keeps its start position."""

    name = "landmarks"

    def __init__(self, D: np.ndarray, lm: np.ndarray, W: np.ndarray | None):
        n, k = D.shape
        self.n, self.k, self.lm = n, k, lm
        self.step = max(1, _CHUNK // k)
        # Effective weights (n,k): 0 for non-finite distances and for each landmark's pair with itself.
        Weff = np.where(np.isfinite(D), 1.0 if W is None else W, 0.0)
        Weff[lm, np.arange(k)] = 0.0
        self.W = Weff
        self.D = np.where(Weff > 0, D, 0.0)
        self.den = float(np.einsum("ij,ij,ij->", Weff, self.D, self.D))
        self.pairs = int(np.count_nonzero(Weff))
        if not self.den > 0:
            raise HeatparamError("SMACOF: all landmark distances are zero or non-finite")
        # V = Σ w (e_i − e_l)(e_i − e_l)ᵀ: degrees, the landmark block, the Schur complement on the landmarks.
        deg = Weff.sum(axis=1)
        deg[lm] += Weff.sum(axis=0)
        is_lm = np.zeros(n, dtype=bool)
        is_lm[lm] = True
        self.P = np.flatnonzero(~is_lm)
        self.isolated = self.P[deg[self.P] == 0]
        self.inv_deg_P = np.divide(1.0, deg[self.P], out=np.zeros(len(self.P)), where=deg[self.P] > 0)
        WL = Weff[lm]
        S = -(WL + WL.T)
        S[np.diag_indices(k)] = deg[lm]
        for s in range(0, len(self.P), self.step):
            Pc = self.P[s : s + self.step]
            Wc = Weff[Pc]
            S -= (Wc * self.inv_deg_P[s : s + self.step, None]).T @ Wc
        S += 1.0 / k
        self.factor = _cholesky(S, "the landmark pairs do not connect all landmarks")

    def evaluate(self, X: np.ndarray) -> tuple[float, np.ndarray]:
        XL = X[self.lm]
        num = 0.0
        BZ = np.empty_like(X)
        BL = np.zeros_like(XL)
        for s in range(0, self.n, self.step):
            e = min(self.n, s + self.step)
            dist = _dist(X[s:e], XL)
            Wc, Dc = self.W[s:e], self.D[s:e]
            r = _ratio(Wc, Dc, dist)
            # Pair (i, l_j) adds r_ij (z_i − z_lj) to row i and r_ij (z_lj − z_i) to row l_j.
            BZ[s:e] = X[s:e] * r.sum(axis=1)[:, None] - r @ XL
            BL += XL * r.sum(axis=0)[:, None] - r.T @ X[s:e]
            dist -= Dc  # now the residual
            num += float(np.vdot(dist, Wc * dist))
        BZ[self.lm] += BL
        return num, BZ

    def solve(self, Y: np.ndarray, X: np.ndarray) -> np.ndarray:
        P, inv = self.P, self.inv_deg_P
        rhs = Y[self.lm].copy()
        out = np.empty_like(Y)
        for s in range(0, len(P), self.step):
            Pc = P[s : s + self.step]
            rhs += self.W[Pc].T @ (Y[Pc] * inv[s : s + self.step, None])
        xL = sla.cho_solve(self.factor, rhs)
        out[self.lm] = xL
        for s in range(0, len(P), self.step):
            Pc = P[s : s + self.step]
            out[Pc] = (Y[Pc] + self.W[Pc] @ xL) * inv[s : s + self.step, None]
        out[self.isolated] = X[self.isolated]
        return out - out.mean(axis=0)
