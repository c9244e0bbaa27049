"""Flip-free polish of the MDS layout and overlap resolution (issue 5).

Classical MDS minimizes strain (Eq. 13), not the stress of Eq. 1, and folds on strongly curved disks. This
stage turns the raw MDS layout into a bijective, near-isometric map at true scale:

1. **Hole fans.** Every hole loop gets a virtual centre vertex joined to its boundary edges, so the mesh plus
   its fans is a topological disk. Fan triangles are scaffold elements (Jiang et al. 2017): they must stay
   positively oriented, which keeps every hole from overlapping itself or the surface, and their (small) energy
   is measured against their own shape at the start of each iteration.
2. **Start.** The MDS layout when it has no flipped triangle (fans included) and no boundary crossing;
   otherwise a free-boundary LSCM layout scaled to the 3D area if it is valid (no flip, fans included, no
   crossing), else a Tutte embedding of the disk (outer loop on a circle of the surface's perimeter, uniform
   weights), bijective by Tutte's theorem. (:func:`untangle`, Garanzha et al. 2021, is implemented but off: measured to
   fail on our cases, see ``UNTANGLE_MAX_FRACTION``.)
3. **Polish**: symmetric Dirichlet energy Σ A_f (|J|² + |J⁻¹|²), no rescaling (its minimum is the isometry
   itself), minimized by projected Newton (per-face 4×4 Hessian in J projected to PSD, one sparse Cholesky
   per iteration; the SLIM proxy of Rabinovich et al. 2017 is kept as ``method="slim"``), with a line search
   that never lets a triangle's det J cross zero (Smith & Schaefer 2015: first positive root of each face's
   quadratic) and rejects any step after which the outer boundary crosses itself. The start is bijective and
   every accepted step keeps it so (crossings are checked at the step's end point, not continuously).

``refine(V, F, uv, opts)`` → (uv, report). Plain arrays in and out; ``report`` is JSON-able.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.optimize as so
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from heatparam import metrics
from heatparam.operators import edge_lengths, intrinsic_areas, local_triangles, mollify
from heatparam.solvers import Factor

REFINE_MODES = ("none", "sd")
# Untangle only when at most this fraction of the faces is flipped. 0: never — our L-BFGS implementation of
# Garanzha et al. failed on every measured case (halftunnel 178 → 617 flips, cylinder_with_holes 3 → 959,
# camelhead 9379 → 7291, 1-29 s), so a flipped start goes to the LSCM / Tutte starts. See docs/refine.md.
UNTANGLE_MAX_FRACTION = 0.0
FAN_WEIGHT = 1e-2  # scaffold (fan) face energy weight, relative to the mean surface face area


# ----------------------------------------------------------------------------------------------------------
# geometry of the per-face Jacobians
# ----------------------------------------------------------------------------------------------------------
def hat_gradients(P: np.ndarray) -> np.ndarray:
    """Gradients (m,3,2) of the three hat functions of each rest triangle P (m,3,2) (counter-clockwise).

    The Jacobian of the map taking P to the UV triangle Q (m,3,2) is ``J[a,c] = Σ_i Q[i,a] g[i,c]``.
    """
    E = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)  # (m,2,2) columns = edges
    Einv = np.linalg.inv(E)  # rows = gradients of the hats of corners 1 and 2
    g = np.empty((len(P), 3, 2))
    g[:, 1] = Einv[:, 0]
    g[:, 2] = Einv[:, 1]
    g[:, 0] = -(g[:, 1] + g[:, 2])
    return g


def jacobians(uv: np.ndarray, F: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Per-face Jacobians (m,2,2) of the map to ``uv`` (n,2)."""
    return np.einsum("mia,mic->mac", uv[F], g)


def _det(J: np.ndarray) -> np.ndarray:
    return J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]


def _cof(J: np.ndarray) -> np.ndarray:
    """d det J / dJ."""
    C = np.empty_like(J)
    C[:, 0, 0] = J[:, 1, 1]
    C[:, 1, 1] = J[:, 0, 0]
    C[:, 0, 1] = -J[:, 1, 0]
    C[:, 1, 0] = -J[:, 0, 1]
    return C


def _scatter(dJ: np.ndarray, F: np.ndarray, g: np.ndarray, n: int) -> np.ndarray:
    """Chain rule: per-face dE/dJ (m,2,2) → dE/duv (n,2)."""
    dQ = np.einsum("mac,mic->mia", dJ, g)  # (m,3,2)
    out = np.empty((n, 2))
    idx = F.ravel()
    out[:, 0] = np.bincount(idx, weights=dQ[:, :, 0].ravel(), minlength=n)
    out[:, 1] = np.bincount(idx, weights=dQ[:, :, 1].ravel(), minlength=n)
    return out


def symmetric_dirichlet(J: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Σ w_f (|J|² + |J⁻¹|²) and per-face values (inf where det J ≤ 0)."""
    d = _det(J)
    f2 = np.einsum("mab,mab->m", J, J)
    with np.errstate(divide="ignore"):
        e = np.where(d > 0, f2 * (1.0 + 1.0 / np.where(d > 0, d, 1.0) ** 2), np.inf)
    return float(np.dot(w, e)) if np.all(d > 0) else float("inf"), e


def max_step(J: np.ndarray, D: np.ndarray) -> float:
    """Largest t ≤ ∞ such that det(J + sD) > 0 for all s in [0, t) (per-face quadratic, first positive root)."""
    c = _det(J)
    a = _det(D)
    b = J[:, 0, 0] * D[:, 1, 1] + D[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * D[:, 1, 0] - D[:, 0, 1] * J[:, 1, 0]
    t = np.full(len(c), np.inf)
    lin = np.abs(a) <= 1e-14 * (np.abs(b) + np.abs(c))
    with np.errstate(divide="ignore", invalid="ignore"):
        tl = -c / b
        t = np.where(lin & (tl > 0), tl, t)
        disc = b * b - 4 * a * c
        ok = ~lin & (disc >= 0)
        sq = np.sqrt(np.where(ok, disc, 0.0))
        # numerically stable roots
        q = -0.5 * (b + np.sign(b + (b == 0)) * sq)
        r1 = q / a
        r2 = c / q
        r1 = np.where(ok & (r1 > 0), r1, np.inf)
        r2 = np.where(ok & (r2 > 0), r2, np.inf)
        t = np.minimum(t, np.where(ok, np.minimum(r1, r2), np.inf))
    return float(t.min()) if len(t) else float("inf")


# ----------------------------------------------------------------------------------------------------------
# the disk: surface + hole fans
# ----------------------------------------------------------------------------------------------------------
class Disk(NamedTuple):
    F: np.ndarray  # (m + f, 3) surface faces then fan faces
    m: int  # number of surface faces
    n: int  # number of surface vertices (fan centres are n, n+1, ...)
    outer: np.ndarray  # outer boundary loop (vertex ids)
    holes: list  # hole loops
    fan_rest: np.ndarray  # (f,3,2) reference triangles of the fan faces (for untangling)


def build_disk(V: np.ndarray, F: np.ndarray) -> Disk:
    """Close every hole of the disk-like mesh (V, F) with a fan around a virtual centre vertex.

    The outer loop is the longest boundary loop in 3D.
    """
    n, m = len(V), len(F)
    loops = metrics.boundary_loops(F)
    lens = [float(np.linalg.norm(V[lp] - V[np.roll(lp, -1)], axis=1).sum()) for lp in loops]
    if not loops:
        raise ValueError("refine needs a mesh with a boundary")
    io = int(np.argmax(lens))
    outer = loops[io]
    holes = [lp for i, lp in enumerate(loops) if i != io]
    fans, rest = [], []
    for h, lp in enumerate(holes):
        a, b = lp, np.roll(lp, -1)  # half-edges a→b as oriented in their faces
        c = np.full(len(lp), n + h)
        fans.append(np.column_stack([b, a, c]))
        el = np.linalg.norm(V[a] - V[b], axis=1)
        rad = max(lens[[i for i in range(len(loops)) if i != io][h]] / (2 * np.pi), 1e-12)
        ht = np.sqrt(np.maximum(rad**2 - 0.25 * el**2, (0.1 * rad) ** 2))
        P = np.zeros((len(lp), 3, 2))
        P[:, 1, 0] = el
        P[:, 2, 0] = 0.5 * el
        P[:, 2, 1] = ht
        rest.append(P)
    Fa = np.vstack([F] + fans) if fans else F.copy()
    fan_rest = np.concatenate(rest) if rest else np.zeros((0, 3, 2))
    return Disk(Fa.astype(np.int64), m, n, outer, holes, fan_rest)


def _fan_centres(uv: np.ndarray, disk: Disk) -> np.ndarray:
    if not disk.holes:
        return uv
    return np.vstack([uv] + [uv[lp].mean(axis=0, keepdims=True) for lp in disk.holes])


def _outer_crossings(uv: np.ndarray, disk: Disk) -> int:
    return metrics.boundary_crossings(uv, disk.F)


# ----------------------------------------------------------------------------------------------------------
# untangling (Garanzha et al. 2021)
# ----------------------------------------------------------------------------------------------------------
def _chi(eps: float, d: np.ndarray) -> np.ndarray:
    s = np.sqrt(eps * eps + d * d)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(d > 0, 0.5 * eps * eps / np.maximum(s - d, 1e-300), 0.5 * (s + d))


def untangle(uv: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, max_outer: int = 10,
             theta: float = 1.0 / 128, inner_iters: int = 100, bar=None) -> tuple[np.ndarray, dict]:
    """Garanzha et al. 2021: minimize Σ A_f [(1−θ)|J|²/χ(det J, ε) + θ(1 + det²J)/χ(det J, ε)] with ε ↓ 0.

    Returns the layout (n,2) and a report (outer iterations, min det, seconds). Free boundary.
    """
    t0 = time.perf_counter()
    n = len(uv)
    w = area / area.sum()

    def energy(x: np.ndarray, eps: float):
        X = x.reshape(n, 2)
        J = jacobians(X, F, g)
        d = _det(J)
        f2 = np.einsum("mab,mab->m", J, J)
        s = np.sqrt(eps * eps + d * d)
        chi = _chi(eps, d)
        dchi = 0.5 + 0.5 * d / s
        f = f2 / chi
        gg = (1.0 + d * d) / chi
        E = float(np.dot(w, (1 - theta) * f + theta * gg))
        C = _cof(J)
        dJ = (1 - theta) * (2 * J - (f * dchi)[:, None, None] * C) / chi[:, None, None]
        dJ += theta * ((2 * d - gg * dchi) / chi)[:, None, None] * C
        dJ *= w[:, None, None]
        return E, _scatter(dJ, F, g, n).ravel()

    x = uv.ravel().copy()
    d = _det(jacobians(uv, F, g))
    eps = 1.0
    E_prev = energy(x, eps)[0]
    it = 0
    for it in range(1, max_outer + 1):
        res = so.minimize(energy, x, args=(eps,), jac=True, method="L-BFGS-B",
                          options={"maxiter": inner_iters, "gtol": 1e-9, "ftol": 1e-12})
        x = res.x
        E = energy(x, eps)[0]
        d = _det(jacobians(x.reshape(n, 2), F, g))
        dmin = float(d.min())
        sigma = max(1.0 - E / E_prev, 0.1)
        mu = (1.0 - sigma) * float(_chi(eps, np.array([dmin]))[0])
        eps = 2.0 * np.sqrt(mu * (mu - dmin)) if dmin < mu else 1e-10
        if bar is not None:
            bar.update(1)
        if dmin > 0 and abs(E_prev - E) / E < 1e-4:
            break
        E_prev = E
        if dmin > 0 and it >= 3 and eps < 1e-9:
            break
    info = {"outer_iterations": it, "min_det": float(d.min()), "flips": int((d <= 0).sum()),
            "seconds": round(time.perf_counter() - t0, 3)}
    return x.reshape(n, 2), info


# ----------------------------------------------------------------------------------------------------------
# Tutte fallback
# ----------------------------------------------------------------------------------------------------------
def tutte(V: np.ndarray, disk: Disk, backend: str = "auto") -> np.ndarray:
    """Uniform-weight Tutte embedding of the disk (surface + fans), outer loop on a circle of its 3D perimeter."""
    N = disk.n + len(disk.holes)
    F = disk.F
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.unique(np.sort(E, axis=1), axis=0)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(N, N))
    A = (A + A.T).tocsr()
    L = (sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A).tocsr()
    b = disk.outer
    seg = np.linalg.norm(V[b] - V[np.roll(b, -1)], axis=1)
    per = seg.sum()
    ang = 2 * np.pi * np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / per
    R = per / (2 * np.pi)
    bc = R * np.column_stack([np.cos(ang), np.sin(ang)])
    free = np.setdiff1d(np.arange(N), b)
    uv = np.zeros((N, 2))
    uv[b] = bc
    Lff = L[free][:, free].tocsc()
    rhs = -(L[free][:, b] @ bc)
    uv[free] = Factor(Lff, backend).solve(rhs)
    return uv


def conformal_start(V: np.ndarray, F: np.ndarray, disk: Disk) -> np.ndarray:
    """Free-boundary LSCM scaled to the 3D area and centred (``mds.conformal_layout``), (n,2)."""
    from heatparam.mds import conformal_layout

    return conformal_layout(V, F, disk.outer)


# ----------------------------------------------------------------------------------------------------------
# symmetric Dirichlet polish with the SLIM proxy
# ----------------------------------------------------------------------------------------------------------
class _Pattern:
    """Sparsity pattern of the 2N×2N proxy Hessian, built once; ``matrix(vals)`` sums per-face blocks into it."""

    def __init__(self, F: np.ndarray, N: int):
        m = len(F)
        # unknown index of (coordinate a, corner i): a*N + F[:, i]
        ids = np.stack([F, F + N], axis=1)  # (m,2,3)
        ids = ids.reshape(m, 6)
        rows = np.repeat(ids, 6, axis=1).ravel()
        cols = np.tile(ids, (1, 6)).ravel()
        key = cols.astype(np.int64) * (2 * N) + rows
        uniq, self.inv = np.unique(key, return_inverse=True)
        self.shape = (2 * N, 2 * N)
        c, r = np.divmod(uniq, 2 * N)
        self.indices = r.astype(np.int32)
        self.indptr = np.searchsorted(c, np.arange(2 * N + 1)).astype(np.int32)
        self.nnz = len(uniq)

    def matrix(self, vals: np.ndarray) -> sp.csc_matrix:
        data = np.bincount(self.inv, weights=vals.ravel(), minlength=self.nnz)
        return sp.csc_matrix((data, self.indices, self.indptr), shape=self.shape)


def _polar_weights(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """SLIM for symmetric Dirichlet: closest rotations R (m,2,2) and W² = U diag(w²) Uᵀ (m,2,2).

    Closed-form 2×2 SVD: J = Rot(φ) diag(σ1, σ2) Rot(θ), R = Rot(φ + θ), w² = (σ − σ⁻³)/(σ − 1).
    """
    a, b, c, d = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
    e, f, g, h = 0.5 * (a + d), 0.5 * (a - d), 0.5 * (c + b), 0.5 * (c - b)
    q, r = np.hypot(e, h), np.hypot(f, g)
    a1, a2 = np.arctan2(g, f), np.arctan2(h, e)
    phi = 0.5 * (a2 + a1)
    s = np.maximum(np.stack([q + r, q - r], axis=1), 1e-8)
    w2 = (s + 1.0) * (s * s + 1.0) / s**3  # (σ − σ⁻³)/(σ − 1), no singularity at σ = 1
    cp, sp_ = np.cos(phi), np.sin(phi)
    ca, sa = np.cos(a2), np.sin(a2)
    R = np.stack([np.stack([ca, -sa], 1), np.stack([sa, ca], 1)], 1)
    W2 = np.empty_like(J)
    W2[:, 0, 0] = cp * cp * w2[:, 0] + sp_ * sp_ * w2[:, 1]
    W2[:, 1, 1] = sp_ * sp_ * w2[:, 0] + cp * cp * w2[:, 1]
    W2[:, 0, 1] = W2[:, 1, 0] = cp * sp_ * (w2[:, 0] - w2[:, 1])
    return R, W2


def _sd_newton_blocks(J: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradient (m,2,2) and PSD-projected Hessian (m,4,4) of w_f·|J|²(1 + det⁻²J) w.r.t. row-major vec(J)."""
    m = len(J)
    j = J.reshape(m, 4)
    d = _det(J)
    f = np.einsum("mi,mi->m", j, j)
    c = np.stack([j[:, 3], -j[:, 2], -j[:, 1], j[:, 0]], axis=1)
    d2, d3, d4 = d**-2, d**-3, d**-4
    grad = 2 * j * (1 + d2)[:, None] - 2 * (f * d3)[:, None] * c
    K = np.zeros((4, 4))
    K[0, 3] = K[3, 0] = 1.0
    K[1, 2] = K[2, 1] = -1.0
    jc = j[:, :, None] * c[:, None, :]
    H = (2 * (1 + d2))[:, None, None] * np.eye(4) - (4 * d3)[:, None, None] * (jc + jc.transpose(0, 2, 1))
    H += (6 * f * d4)[:, None, None] * c[:, :, None] * c[:, None, :] - (2 * f * d3)[:, None, None] * K
    lam, Q = np.linalg.eigh(H)
    H = np.einsum("mij,mj,mkj->mik", Q, np.maximum(lam, 1e-8 * (1 + d2)[:, None]), Q)
    return (w[:, None] * grad).reshape(m, 2, 2), w[:, None, None] * H


#: Newton directions are solved to this relative residual by conjugate gradients preconditioned with the last
#: Cholesky factor; the Hessian is refactorized only when that takes more than PCG_MAX_ITERS iterations.
PCG_RTOL = 1e-3
PCG_MAX_ITERS = 12


def _newton_direction(H: sp.csc_matrix, rhs: np.ndarray, fac: Factor | None, backend: str
                      ) -> tuple[np.ndarray, Factor, int]:
    """Solve H dx = rhs, reusing a stale factorization as a preconditioner while it still works (lagged Newton).

    Factorizing the (2N,2N) Hessian dominates an iteration; consecutive Hessians differ little, so a few
    preconditioned CG steps with the previous factor usually reach PCG_RTOL for a fraction of the cost.
    Returns (dx, the factor used, 1 if it was refactorized else 0).
    """
    if fac is not None:
        prec = spla.LinearOperator(H.shape, matvec=fac.solve, dtype=np.float64)
        dx, info = spla.cg(H, rhs, x0=fac.solve(rhs), rtol=PCG_RTOL, maxiter=PCG_MAX_ITERS, M=prec)
        if info == 0:
            return dx, fac, 0
    fac = Factor(H, backend)
    return fac.solve(rhs), fac, 1


def polish(uv: np.ndarray, disk: Disk, g_surf: np.ndarray, area: np.ndarray, *, max_iters: int = 200,
           tol: float = 1e-6, backend: str = "auto", check_crossings: bool = True, method: str = "newton",
           bar=None) -> tuple[np.ndarray, dict]:
    """Minimize the symmetric Dirichlet energy of the surface faces from a flip-free ``uv`` (N,2), flip-free.

    Surface face f weighs its 3D area; fan faces are scaffold elements measured against their shape at the start
    of each iteration. Stops when the relative energy decrease of an iteration is below ``tol``.
    """
    t0 = time.perf_counter()
    F = disk.F
    N = len(uv)
    m = disk.m
    pat = _Pattern(F, N)
    wsum = area.sum()
    w_surf = area / wsum
    fan_w = FAN_WEIGHT * float(area.mean()) / wsum
    x = uv.copy()
    hist = []
    crossing_rejects = 0
    fac, refactorizations = None, 0
    it = 0
    converged = False
    while it < max_iters:
        it += 1
        if len(F) > m:
            Pf = x[F[m:]]
            g_fan = hat_gradients(Pf)
            g = np.concatenate([g_surf, g_fan])
            w = np.concatenate([w_surf, np.full(len(F) - m, fan_w)])
        else:
            g, w = g_surf, w_surf
        J = jacobians(x, F, g)
        E0, _ = symmetric_dirichlet(J, w)
        Es0 = symmetric_dirichlet(J[:m], w_surf)[0]
        hist.append(Es0)
        if method == "newton":
            # projected Newton: per-face Hessian in J, projected to PSD, chained through J = Σ_i uv_i ⊗ g_i
            gJ, HJ = _sd_newton_blocks(J, w)
            Bm = np.zeros((len(F), 4, 2, 3))  # d vec(J)[(a,c)] / d uv[(a',i)]
            for a in range(2):
                Bm[:, 2 * a : 2 * a + 2, a, :] = g.transpose(0, 2, 1)
            Bm = Bm.reshape(len(F), 4, 6)
            blocks = np.matmul(np.matmul(Bm.transpose(0, 2, 1), HJ), Bm)
            H = pat.matrix(blocks)
            gr = _scatter(gJ, F, g, N)
            rhs = -np.concatenate([gr[:, 0], gr[:, 1]])
            lam = 1e-9 * float(H.diagonal().mean())
            H = H + sp.identity(2 * N, format="csc") * lam
            dx, fac, fresh = _newton_direction(H, rhs, fac, backend)
            refactorizations += fresh
            d = np.column_stack([dx[:N], dx[N:]])
        else:
            R, W2 = _polar_weights(J)
            # SLIM blocks: H[(a,i),(b,j)] = w_f W2[a,b] (g_i·g_j); rhs[(a,i)] = w_f (W2 R g_iᵀ)[a]
            K = np.einsum("mic,mjc->mij", g, g)
            blocks = w[:, None, None, None, None] * W2[:, :, None, :, None] * K[:, None, :, None, :]
            H = pat.matrix(blocks.reshape(len(F), 36))
            rhsf = w[:, None, None] * np.einsum("mab,mbc,mic->mai", W2, R, g)  # (m,2,3)
            rhs = np.zeros(2 * N)
            rhs[:N] = np.bincount(F.ravel(), weights=rhsf[:, 0].ravel(), minlength=N)
            rhs[N:] = np.bincount(F.ravel(), weights=rhsf[:, 1].ravel(), minlength=N)
            lam = 1e-9 * float(H.diagonal().mean())
            xv = np.concatenate([x[:, 0], x[:, 1]])
            H = H + sp.identity(2 * N, format="csc") * lam
            xn = Factor(H, backend).solve(rhs + lam * xv)
            d = np.column_stack([xn[:N] - x[:, 0], xn[N:] - x[:, 1]])
        D = jacobians(d, F, g)
        t = min(1.0, 0.9 * max_step(J, D))
        accepted = False
        for _ in range(40):
            xt = x + t * d
            E1, _ = symmetric_dirichlet(J + t * D, w)
            if E1 < E0:
                if check_crossings and _outer_crossings(xt, disk) > 0:
                    crossing_rejects += 1
                else:
                    accepted = True
                    break
            t *= 0.5
        if not accepted:
            break
        x = xt
        if bar is not None:
            bar.update(1)
        Es1 = symmetric_dirichlet(jacobians(x[: disk.n], F[:m], g_surf), w_surf)[0]
        if (Es0 - Es1) / Es0 < tol:
            hist.append(Es1)
            converged = True
            break
    info = {"iterations": it, "converged": converged, "energy_start": float(hist[0] / 4 if hist else np.nan),
            "energy_end": float(hist[-1] / 4 if hist else np.nan), "crossing_rejected_steps": crossing_rejects,
            "factorizations": refactorizations,
            "seconds": round(time.perf_counter() - t0, 3)}
    return x, info


# ----------------------------------------------------------------------------------------------------------
# the stage
# ----------------------------------------------------------------------------------------------------------
def surface_gradients(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hat gradients (m,3,2) of each 3D triangle in its own frame, and the areas (m,) (mollified lengths)."""
    raw = edge_lengths(V, F)
    lengths, _ = mollify(raw, 1e-4 * float(raw.mean()))
    return hat_gradients(local_triangles(lengths)), intrinsic_areas(lengths)


def refine(V: np.ndarray, F: np.ndarray, uv: np.ndarray, opts=None, progress=None,
           conformal: Callable[[], np.ndarray] | None = None) -> tuple[np.ndarray, dict]:
    """Make the MDS layout ``uv`` (n,2) of (V (n,3), F (m,3)) flip-free and near-isometric (true scale).

    ``conformal``, if given, returns the LSCM layout of (V, F) for the fallback start (already computed by the
    fill decision, so it is not computed twice).

    Returns the refined layout (n,2) and a JSON-able report of what was done.
    """
    t0 = time.perf_counter()
    backend = getattr(opts, "solver", "auto")
    max_iters = int(getattr(opts, "refine_iters", 200))
    tol = float(getattr(opts, "refine_tol", 1e-6))
    n = len(V)
    disk = build_disk(V, F)
    g_surf, area = surface_gradients(V, F)
    report: dict = {"method": "sd", "holes_fanned": len(disk.holes)}

    x = _fan_centres(np.asarray(uv, dtype=np.float64), disk)
    g_all = np.concatenate([g_surf, hat_gradients(disk.fan_rest)]) if disk.holes else g_surf
    a_all = np.concatenate([area, intrinsic_areas(_tri_lengths(disk.fan_rest))]) if disk.holes else area
    d = _det(jacobians(x, disk.F, g_all))
    report["start"] = {"flips": int((d[: disk.m] <= 0).sum()), "fan_flips": int((d[disk.m:] <= 0).sum())}
    start = "mds"
    if (d <= 0).any() and (d <= 0).sum() <= UNTANGLE_MAX_FRACTION * len(d):
        bar = progress.bar(40, "untangle") if progress is not None else None
        try:
            x, uinfo = untangle(x, disk.F, g_all, a_all, bar=bar)
        finally:
            if bar is not None:
                bar.close()
        report["untangle"] = uinfo
        start = "mds+untangle"
    d = _det(jacobians(x, disk.F, g_all))
    cross = _outer_crossings(x, disk) if (d > 0).all() else -1
    report["start"]["crossings_before_polish"] = cross
    if not (d > 0).all() or cross != 0:
        xl = _fan_centres(conformal() if conformal is not None else conformal_start(V, F, disk), disk)
        dl = _det(jacobians(xl, disk.F, g_all))
        report["start"]["lscm_flips"] = int((dl <= 0).sum())
        if (dl > 0).all() and _outer_crossings(xl, disk) == 0:
            x, start = xl, "lscm"
        else:
            x, start = tutte(V, disk, backend), "tutte"
    report["start"]["layout"] = start
    bar = progress.bar(max_iters, "polish") if progress is not None else None
    try:
        x, pinfo = polish(x, disk, g_surf, area, max_iters=max_iters, tol=tol, backend=backend, bar=bar)
    finally:
        if bar is not None:
            bar.close()
    pinfo["method"] = "projected-newton"
    report["polish"] = pinfo
    uvn = x[:n]
    report["flips"] = int((_det(jacobians(uvn, F, g_surf)) <= 0).sum())
    report["boundary_crossings"] = int(metrics.boundary_crossings(uvn, F))
    report["bijective"] = report["flips"] == 0 and report["boundary_crossings"] == 0
    report["seconds"] = round(time.perf_counter() - t0, 3)
    return uvn, report


def _tri_lengths(P: np.ndarray) -> np.ndarray:
    return np.stack([np.linalg.norm(P[:, 2] - P[:, 1], axis=1), np.linalg.norm(P[:, 2] - P[:, 0], axis=1),
                     np.linalg.norm(P[:, 1] - P[:, 0], axis=1)], axis=1)
