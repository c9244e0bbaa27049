"""Classical multidimensional scaling (paper Eq. 11-14) and landmark MDS for large meshes.

Classical MDS: C = −½ J G² J (Eq. 12) is never formed; a Lanczos solver (``scipy.sparse.linalg.eigsh``)
finds its two largest eigenpairs through products with G², and Φ = [√λ1 V1, √λ2 V2] (Eq. 14).
Landmark MDS (de Silva & Tenenbaum 2004) runs classical MDS on k landmarks and places every vertex by
distance-based triangulation from its k landmark distances: O(n·k) memory and time.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from heatparam.errors import HeatparamError
from heatparam.memory import require
from heatparam.mesh import face_areas


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
        require(8.0 * n * n, f"squared distance matrix {n} x {n}", "use --geodesics landmarks")
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


def needs_mirror(uv: np.ndarray, F: np.ndarray) -> bool:
    """Whether most of the layout's signed area is clockwise (MDS fixes coordinates only up to a reflection)."""
    a = uv[F[:, 1]] - uv[F[:, 0]]
    b = uv[F[:, 2]] - uv[F[:, 0]]
    return bool((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum() < 0)


def orient_layout(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Mirror the layout if most of its signed area is clockwise, so the faces keep the mesh's orientation."""
    if needs_mirror(uv, F):
        uv = uv.copy()
        uv[:, 1] *= -1
    return uv


def conformal_layout(V: np.ndarray, F: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """A quick reference layout: free-boundary LSCM (``igl.lscm``; two far vertices of the outer loop pinned),
    mirrored to keep the mesh's orientation, scaled to the 3D area and centred. (n,2) float64.

    Not MDS: the fill uses it to decide where M* extends, the refinement as a fallback start when the MDS layout
    folds. LSCM is exact up to scale on developable surfaces.
    """
    import igl

    a = int(outer[0])
    b = int(outer[np.argmax(np.linalg.norm(V[outer] - V[a], axis=1))])
    uv, _ = igl.lscm(V, F, np.array([a, b], dtype=np.int64), np.array([[0.0, 0.0], [1.0, 0.0]]))
    uv = np.asarray(uv, dtype=np.float64)
    if not np.isfinite(uv).all():
        raise HeatparamError("the conformal (LSCM) layout failed: is the mesh degenerate?")
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    signed = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    if signed < 0:
        uv[:, 1] *= -1
    uv *= np.sqrt(face_areas(V, F).sum() / max(abs(signed), 1e-300))
    return uv - uv.mean(axis=0)
