"""Bijective, near-isometric polish of the MDS layout at true scale (issue 5; Eq. 1 beyond the paper).

Classical MDS minimizes strain (Eq. 13), not the stress of Eq. 1, and folds on strongly curved disks. This
stage turns the raw MDS layout into a bijective map at true scale:

1. **Start.** Of the MDS layout and the free-boundary LSCM layout scaled to the 3D area, the bijective one (no
   flipped triangle, no boundary crossing on any loop) with the lower energy (on developable parts LSCM is an
   isometry to round-off); if neither is bijective, a uniform Tutte embedding of the mesh with every hole closed
   by a fan (outer loop on a circle of the surface's perimeter), bijective by Tutte's theorem.
2. **Polish.** Symmetric Dirichlet energy Σ A_f (|J|² + |J⁻¹|²), no rescaling (its minimum is the isometry
   itself), minimized by projected Newton with the closed-form Hessian eigensystem of Smith et al. 2019
   (:func:`sd_eigensystem`; the PSD projection is a clamp of one eigenvalue) and one sparse Cholesky reused as a
   preconditioner while it works (:func:`_newton_direction`).
3. **Global bijectivity by a scaffold** (Jiang et al. 2017): at every iteration the rest of a box around the
   layout — the outside of the outer loop and the inside of every hole — is triangulated (constrained
   Delaunay, :func:`build_scaffold`) and its triangles join the energy with a small weight. The line search never
   lets a surface or scaffold triangle's det J cross zero (Smith & Schaefer 2015: first positive root of each
   face's quadratic), so boundaries can slide freely but never cross, and holes can take any shape.

``refine(V, F, uv, opts)`` → (uv, report). Plain arrays in and out; ``report`` is JSON-able.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import ThreadpoolController

from heatparam import metrics
from heatparam.errors import HeatparamError
from heatparam.mesh import unique_edges
from heatparam.operators import edge_lengths, intrinsic_areas, local_triangles, mollify
from heatparam.solvers import Factor, large_system_backend

REFINE_MODES = ("none", "sd")
#: Peak memory of the refinement per surface face, above the rest of the pipeline: the peak RSS of the default run
#: minus that of ``--refine none`` measured 2.4 / 1.9 / 2.35 KB per face on camelhead↑45k / 182k / 727k
#: (BENCHMARKS.md §4: PARDISO's factor of the Hessian, the 6×6 blocks and the pattern's index arrays)
POLISH_BYTES_PER_FACE = 2600


def polish_bytes(faces: int) -> float:
    """Memory the refinement of a mesh with ``faces`` triangles needs at its peak (estimate), bytes."""
    return float(POLISH_BYTES_PER_FACE) * faces


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
    return np.matmul(uv[F].transpose(0, 2, 1), g)


def _det(J: np.ndarray) -> np.ndarray:
    return J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]


def _scatter(dJ: np.ndarray, F: np.ndarray, g: np.ndarray, n: int) -> np.ndarray:
    """Chain rule: per-face dE/dJ (m,2,2) → dE/duv (n,2)."""
    dQ = np.matmul(g, dJ.transpose(0, 2, 1))  # (m,3,2)
    out = np.empty((n, 2))
    idx = F.ravel()
    out[:, 0] = np.bincount(idx, weights=dQ[:, :, 0].ravel(), minlength=n)
    out[:, 1] = np.bincount(idx, weights=dQ[:, :, 1].ravel(), minlength=n)
    return out


def symmetric_dirichlet(J: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Σ w_f (|J|² + |J⁻¹|²) and per-face values (inf where det J ≤ 0)."""
    d = _det(J)
    f2 = (J * J).sum(axis=(1, 2))
    with np.errstate(divide="ignore"):
        e = np.where(d > 0, f2 * (1.0 + 1.0 / np.where(d > 0, d, 1.0) ** 2), np.inf)
    return float(np.dot(w, e)) if np.all(d > 0) else float("inf"), e


def _energy(uv: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray) -> float:
    """Symmetric Dirichlet energy per area / 4 of a layout (1 = isometry)."""
    return symmetric_dirichlet(jacobians(uv, F, g), area / area.sum())[0] / 4


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
    """The mesh's boundary loops, and its faces with every hole closed by a fan (for the Tutte start)."""

    F: np.ndarray  # (m + f, 3) surface faces then fan faces
    m: int  # number of surface faces
    n: int  # number of surface vertices (fan centres are n, n+1, ...)
    outer: np.ndarray  # outer boundary loop (vertex ids)
    holes: list  # hole loops


def build_disk(V: np.ndarray, F: np.ndarray) -> Disk:
    """Close every hole of the disk-like mesh (V, F) with a fan around a virtual centre vertex.

    The outer loop is the longest boundary loop in 3D.
    """
    loops = metrics.boundary_loops(F)
    if not loops:
        raise ValueError("refine needs a mesh with a boundary")
    lens = [float(np.linalg.norm(V[lp] - V[np.roll(lp, -1)], axis=1).sum()) for lp in loops]
    io = int(np.argmax(lens))
    holes = [lp for i, lp in enumerate(loops) if i != io]
    fans = [np.column_stack([np.roll(lp, -1), lp, np.full(len(lp), len(V) + h)]) for h, lp in enumerate(holes)]
    return Disk(np.vstack([F, *fans]).astype(np.int64), len(F), len(V), loops[io], holes)


# ----------------------------------------------------------------------------------------------------------
# Tutte fallback
# ----------------------------------------------------------------------------------------------------------
def tutte(V: np.ndarray, disk: Disk, backend: str = "auto") -> np.ndarray:
    """Uniform-weight Tutte embedding of the disk (surface + fans), outer loop on a circle of its 3D perimeter."""
    N = disk.n + len(disk.holes)
    F = disk.F
    E = unique_edges(F)
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
# symmetric Dirichlet: analytic gradient and PSD-projected Hessian (Smith, De Goes & Kim 2019)
# ----------------------------------------------------------------------------------------------------------
def svd2(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed closed-form SVD of 2×2 matrices: J = U diag(σ) Vᵀ with U, V rotations, σ1 ≥ |σ2|.

    J (m,2,2) → U (m,2,2), σ (m,2), V (m,2,2); σ2 > 0 exactly where det J > 0.
    """
    a, b, c, d = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
    e, f, g, h = 0.5 * (a + d), 0.5 * (a - d), 0.5 * (c + b), 0.5 * (c - b)
    q, r = np.hypot(e, h), np.hypot(f, g)
    a1, a2 = np.arctan2(g, f), np.arctan2(h, e)
    return _rot(0.5 * (a2 + a1)), np.stack([q + r, q - r], axis=1), _rot(0.5 * (a1 - a2))


def _rot(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)


def sd_eigensystem(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gradient and Hessian eigenvalues of Ψ(J) = |J|² + |J⁻¹|² = Σ σᵢ² + σᵢ⁻² (det J > 0).

    Closed form (Smith et al. 2019, 2D case): with J = U diag(σ) Vᵀ (columns uᵢ, vᵢ), ∂Ψ/∂J = U diag(2σ − 2σ⁻³) Vᵀ
    and the Hessian's eigenpairs are (2 + 6σ₁⁻⁴, u₁v₁ᵀ), (2 + 6σ₂⁻⁴, u₂v₂ᵀ), twist
    (2 − 2(σ₁² − σ₁σ₂ + σ₂²)/(σ₁σ₂)³, (u₂v₁ᵀ − u₁v₂ᵀ)/√2) and flip (2 + 2(σ₁² + σ₁σ₂ + σ₂²)/(σ₁σ₂)³,
    (u₁v₂ᵀ + u₂v₁ᵀ)/√2). Only the twist eigenvalue can be negative, so the PSD projection is a clamp.

    Returns dΨ/dJ (m,2,2), eigenvalues λ (m,4) in that order, U (m,2,2) and V (m,2,2).
    """
    U, s, V = svd2(J)
    s1, s2 = s[:, 0], s[:, 1]
    p3 = (s1 * s2) ** 3
    lam = np.stack([2 + 6 / s1**4, 2 + 6 / s2**4, 2 - 2 * (s1 * s1 - s1 * s2 + s2 * s2) / p3,
                    2 + 2 * (s1 * s1 + s1 * s2 + s2 * s2) / p3], axis=1)
    dpsi = 2 * s - 2 / s**3
    grad = np.matmul(U * dpsi[:, None, :], V.transpose(0, 2, 1))
    return grad, lam, U, V


def sd_newton_blocks(J: np.ndarray, g: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-face gradient dE/dJ (m,2,2) and PSD-projected Hessian (m,6,6) in the corner unknowns of
    E = Σ w_f Ψ(J_f), J = Σ_i uv_i ⊗ g_i; the unknowns of a face are ordered (u₀,u₁,u₂,v₀,v₁,v₂).

    An eigenmatrix u vᵀ pulls back to the corners as u ⊗ (g v), so the block is Σ_k λ_k⁺ b_k b_kᵀ.
    """
    grad, lam, U, V = sd_eigensystem(J)
    m = len(J)
    gv = np.matmul(g, V)  # (m,3,2): column j = g·v_j per corner
    u1, u2 = U[:, :, 0, None], U[:, :, 1, None]  # (m,2,1)
    a11 = (u1 * gv[:, None, :, 0]).reshape(m, 6)  # u1 ⊗ g v1
    a22 = (u2 * gv[:, None, :, 1]).reshape(m, 6)
    a21 = (u2 * gv[:, None, :, 0]).reshape(m, 6)
    a12 = (u1 * gv[:, None, :, 1]).reshape(m, 6)
    r = 1.0 / np.sqrt(2.0)
    b = np.stack([a11, a22, r * (a21 - a12), r * (a12 + a21)], axis=1)  # (m,4,6)
    lw = w[:, None] * np.maximum(lam, 0.0)
    blocks = np.matmul(b.transpose(0, 2, 1) * lw[:, None, :], b)
    return w[:, None, None] * grad, blocks


# ----------------------------------------------------------------------------------------------------------
# the scaffold (Jiang et al. 2017): the rest of a box, triangulated around the current layout
# ----------------------------------------------------------------------------------------------------------
SCAFFOLD_WEIGHT = 1e-2  # largest energy weight of one scaffold triangle, relative to the mean surface face's
SCAFFOLD_ADAPT = 2.0  # after an uncut Newton step the scaffold weight is divided by this, after a cut one multiplied
SCAFFOLD_WEIGHT_MIN = 1e-4  # ... within [SCAFFOLD_WEIGHT_MIN, 1] × SCAFFOLD_WEIGHT
SCAFFOLD_MARGIN = 0.5  # the box extends this fraction of the layout's extent beyond it on every side
DECREMENT_TOL = 1e-3  # converged at once when the Newton decrement predicts less than this × tol relative decrease
STALL_ITERS = 5  # the polish gives up after this many barrier-limited iterations in a row that gain < tol


def _loop_ranges(loops: list[np.ndarray]) -> list[np.ndarray]:
    """Where each loop sits in ``np.concatenate(loops)``: one index range per loop."""
    ends = np.cumsum([len(lp) for lp in loops])
    return [np.arange(e - len(lp), e) for e, lp in zip(ends, loops, strict=True)]


def _loop_edges(ranges: list[np.ndarray]) -> np.ndarray:
    """Closed-polygon edges (e,2) of the index ranges of :func:`_loop_ranges`."""
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
    import gpytoolbox as gpy

    ids = np.concatenate(loops)
    P = uv[ids]
    lo, hi = P.min(axis=0), P.max(axis=0)
    c, r = 0.5 * (lo + hi), (0.5 + SCAFFOLD_MARGIN) * float((hi - lo).max())
    box = c + r * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    E = np.vstack([_loop_edges(_loop_ranges(loops)), len(ids) + np.array([[0, 1], [1, 2], [2, 3], [3, 0]])])
    try:
        P2, T = gpy.triangulate_polygon(np.vstack([P, box]), E, a=0.0, q=0.0, steiner=False)
    except (ValueError, RuntimeError) as exc:  # CDT: crossing constraints, duplicate points
        raise ValueError(f"cannot triangulate the scaffold (boundary loops touch or cross): {exc}") from exc
    if len(P2) != len(ids) + 4:
        raise ValueError("the scaffold triangulation added vertices (boundary loops touch or cross)")
    glob = np.concatenate([ids, len(uv) + np.arange(4)])
    return Scaffold(glob[T].astype(np.int64), box)


def _scaffold_matrix(F: np.ndarray, blocks: np.ndarray, n: int) -> sp.csc_matrix:
    """Sum the scaffold's 6×6 blocks into a (2n,2n) matrix; rows/columns of the fixed box corners are dropped."""
    ids = np.concatenate([F, F + n], axis=1)  # unknown index of (coordinate a, corner i) = a*n + v
    ids[:, :3][F >= n] = -1
    ids[:, 3:][F >= n] = -1
    r = np.repeat(ids, 6, axis=1).ravel()
    c = np.tile(ids, (1, 6)).ravel()
    ok = (r >= 0) & (c >= 0)
    return sp.csc_matrix((blocks.ravel()[ok], (r[ok], c[ok])), shape=(2 * n, 2 * n))


class _Pattern:
    """Sparsity pattern of the surface's (2n,2n) Hessian, built once; ``matrix(vals)`` sums per-face blocks.

    The Hessian is a 2×2 block matrix [[H_uu, H_uv], [H_vu, H_vv]] whose four blocks share the vertex-adjacency
    pattern A (n,n), so only the 9 vertex pairs of each face are located in A (one sort of 9m keys, not of the
    36m entries); column (b, v) of the full CSC matrix holds A's column v twice, rows u then n + u.
    """

    def __init__(self, F: np.ndarray, n: int):
        m = len(F)
        ci, cj = np.divmod(np.arange(9), 3)
        R, C = F[:, ci].ravel(), F[:, cj].ravel()  # (9m,) row and column vertex of corner pair (i, j)
        A = sp.csc_matrix((np.ones(9 * m), (R, C)), shape=(n, n))
        A.sum_duplicates()  # also sorts each column's rows
        ptr, rows = A.indptr.astype(np.int64), A.indices.astype(np.int64)
        deg = np.diff(ptr)
        nnz = len(rows)
        col = np.repeat(np.arange(n, dtype=np.int64), deg)
        local = np.searchsorted(col * n + rows, C.astype(np.int64) * n + R) - ptr[C]  # place of (R, C) in column C
        # full CSC layout: column b*n + v starts at b*2nnz + 2 ptr[v]; rows a*n + u sit at a*deg[v] + local
        half = np.empty(2 * nnz, dtype=np.int64)
        at = 2 * ptr[col] + (np.arange(nnz) - ptr[col])
        half[at] = rows
        half[at + deg[col]] = rows + n
        self.indices = np.concatenate([half, half]).astype(np.int32)
        self.indptr = np.concatenate([2 * ptr[:-1], 2 * nnz + 2 * ptr]).astype(np.int32)
        self.shape = (2 * n, 2 * n)
        self.nnz = 4 * nnz
        base = (2 * ptr[C] + local).reshape(m, 3, 3)  # (f, i, j): offset of pair (F[f,i], F[f,j]) in a half
        degC = deg[C].reshape(m, 3, 3)
        inv = np.empty((m, 2, 3, 2, 3), dtype=np.int64)  # block entry (a*3+i, b*3+j), as sd_newton_blocks
        for a in range(2):
            for b in range(2):
                inv[:, a, :, b, :] = b * 2 * nnz + base + a * degC
        self.inv = inv.reshape(m, 36)

    def matrix(self, vals: np.ndarray) -> sp.csc_matrix:
        data = np.bincount(self.inv.ravel(), weights=vals.ravel(), minlength=self.nnz)
        return sp.csc_matrix((data, self.indices, self.indptr), shape=self.shape)


#: The polish factorizes with PARDISO whenever it is installed (backend ``auto``): with its analysis reused and no
#: iterative refinement it measured 0.8 vs 1.65 s on camelhead (11k), 6.1-6.5 vs 9.2-9.8 s on beetle (20k), 2.8-3.0
#: vs 7.2 s on camelhead↑45k against CHOLMOD (cholespy) with lagged factors, and even on halftunnel (831 vertices)
POLISH_PARDISO_MIN_UNKNOWNS = 0
#: Newton directions are solved to this relative residual by conjugate gradients preconditioned with the last
#: Cholesky factor; the Hessian is refactorized only when that takes more than PCG_MAX_ITERS iterations.
PCG_RTOL = 1e-3
PCG_MAX_ITERS = 12
#: With PARDISO no stale factor is tried: its refactorizations reuse the symbolic analysis (``Factor.refactor``,
#: ~0.55 s at 363k unknowns), about 4 of its CG steps (a solve + a product, ~0.13 s each), and the stale factor
#: needed 6-30 steps there (camelhead↑180k fine polish 13.1 s with the attempt, 10.5 s without)
PCG_MAX_ITERS_PARDISO = 0


def _newton_direction(H: sp.csc_matrix, rhs: np.ndarray, fac: Factor | None, backend: str
                      ) -> tuple[np.ndarray, Factor, int]:
    """Solve H dx = rhs, reusing a stale factorization as a preconditioner while it still works (lagged Newton).

    Factorizing the (2n,2n) Hessian dominates an iteration; consecutive Hessians differ little, so a few
    preconditioned CG steps with the previous factor usually reach PCG_RTOL for a fraction of the cost.
    Returns (dx, the factor used, 1 if it was refactorized else 0).
    """
    cap = PCG_MAX_ITERS_PARDISO if backend == "pardiso" else PCG_MAX_ITERS
    if fac is not None and cap > 0:
        prec = spla.LinearOperator(H.shape, matvec=fac.solve, dtype=np.float64)
        dx, info = spla.cg(H, rhs, x0=fac.solve(rhs), rtol=PCG_RTOL, maxiter=cap, M=prec)
        if info == 0:
            return dx, fac, 0
    fac = Factor(H, backend) if fac is None else fac.refactor(H)
    return fac.solve(rhs), fac, 1


def _line_energy(t: float, J: np.ndarray, D: np.ndarray, w: np.ndarray, Js: np.ndarray, Ds: np.ndarray,
                 ws: np.ndarray) -> float:
    """Surface + scaffold energy at step t along the Jacobian directions D, Ds."""
    return symmetric_dirichlet(J + t * D, w)[0] + symmetric_dirichlet(Js + t * Ds, ws)[0]


def polish(uv: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, loops: list[np.ndarray], *,
           max_iters: int = 200, tol: float = 1e-6, backend: str = "auto", bar=None,
           guards: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Minimize the symmetric Dirichlet energy Σ A_f Ψ(J_f) from a bijective layout ``uv`` (n,2), keeping it bijective.

    Projected Newton on the surface energy plus a scaffold energy (:func:`build_scaffold`, rebuilt around the
    current layout at every iteration and measured against its own shape at its start, Jiang et al. 2017; each
    scaffold triangle weighs up to ``SCAFFOLD_WEIGHT`` × the mean surface face, relaxed by ``SCAFFOLD_ADAPT``
    after every uncut step). The line search starts at 0.9 × the largest step for which no surface or scaffold
    triangle flips (Smith & Schaefer 2015) and halves it until the energy decreases, or, after a full step, doubles
    it while that lowers the energy further (camelhead: 18 → 14 iterations). Converged when an uncut step
    (≥ half the Newton step) lowers the surface energy by less than ``tol`` of it; gives up after
    ``STALL_ITERS`` barrier-limited steps in a row that gain less. g (m,3,2): hat gradients of the rest triangles;
    area (m,): their areas; loops: boundary loops, outer first; guards (k,3): extra triangles, positive in ``uv``,
    that carry no energy but stay positive like the others (a finer level's triangles whose three corners all lie
    on the boundary: see :func:`coarse_to_fine`). Returns the layout (n,2) and a JSON-able report.
    """
    t0 = time.perf_counter()
    n = len(uv)
    backend = large_system_backend(2 * n, backend, POLISH_PARDISO_MIN_UNKNOWNS)
    w_surf = area / area.sum()
    w_scaf = w_max = SCAFFOLD_WEIGHT * float(w_surf.mean())
    w_min = SCAFFOLD_WEIGHT_MIN * w_max
    x = uv.copy()
    hist: list[float] = []
    fac, refactorizations, it, converged, stop = None, 0, 0, False, "iteration cap"
    small, full_step = 0, 0.5  # a step of at least half the Newton step counts as uncut
    J = jacobians(x, F, g)  # surface Jacobians and energy of the current layout, carried from step to step
    Es = symmetric_dirichlet(J, w_surf)[0]
    # Ψ ≥ 4 on every face (equality iff isometric), so no step can gain more than Es - 4: below the Newton-decrement
    # threshold the start is the minimum (the LSCM start of a developable part) and nothing is assembled
    if np.isfinite(Es) and Es - 4.0 <= DECREMENT_TOL * tol * Es:
        hist.append(Es)
        max_iters, converged, stop = 0, True, "converged (the start is an isometry to within the tolerance)"
    else:
        pat = _Pattern(F, n)
    guards = np.zeros((0, 3), dtype=np.int64) if guards is None else guards
    gg = hat_gradients(x[guards])  # any positive rest triangle will do: only the sign of det J is watched
    while it < max_iters:
        it += 1
        try:
            sc = build_scaffold(x, loops)
        except ValueError as exc:
            stop = f"scaffold failed: {exc}"
            break
        xs = np.vstack([x, sc.box])
        gs = hat_gradients(xs[sc.F])
        ws = np.full(len(sc.F), w_scaf)
        Js = jacobians(xs, sc.F, gs)
        hist.append(Es)
        E0 = Es + symmetric_dirichlet(Js, ws)[0]
        gJ, blocks = sd_newton_blocks(J, g, w_surf)
        gJs, blocks_s = sd_newton_blocks(Js, gs, ws)
        H = pat.matrix(blocks) + _scaffold_matrix(sc.F, blocks_s, n)
        gr = _scatter(gJ, F, g, n) + _scatter(gJs, sc.F, gs, n + 4)[:n]
        rhs = -np.concatenate([gr[:, 0], gr[:, 1]])
        H = H + sp.identity(2 * n, format="csc") * (1e-9 * float(H.diagonal().mean()))  # rigid rotation
        dx, fac, fresh = _newton_direction(H, rhs, fac, backend)
        refactorizations += fresh
        # Newton decrement: the quadratic model's predicted decrease. Negligible (far below tol, so that a stiff
        # scaffold holding boundary vertices back cannot fake it) means the start is already the minimum: e.g. the
        # LSCM start of a developable surface, an isometry to round-off, where line searches find no descent
        if 0.5 * float(rhs @ dx) <= DECREMENT_TOL * tol * E0:
            converged, stop = True, "converged"
            break
        d = np.column_stack([dx[:n], dx[n:]])
        D, Ds = jacobians(d, F, g), jacobians(np.vstack([d, np.zeros((4, 2))]), sc.F, gs)
        tmax = 0.9 * min(max_step(J, D), max_step(Js, Ds), max_step(jacobians(x, guards, gg), jacobians(d, guards, gg)))
        t = min(1.0, tmax)
        for _ in range(40):
            E1 = _line_energy(t, J, D, w_surf, Js, Ds, ws)
            if E1 < E0:
                break
            t *= 0.5
        else:
            stop = "no descent"
            break
        # far from the minimum the full Newton step undershoots (the 1/σ² terms are steep): try doubling it
        while t >= 1.0 and 2 * t <= tmax:
            E2 = _line_energy(2 * t, J, D, w_surf, Js, Ds, ws)
            if not E2 < E1:
                break
            t, E1 = 2 * t, E2
        x = x + t * d
        J = jacobians(x, F, g)
        Es1 = symmetric_dirichlet(J, w_surf)[0]
        if bar is not None:
            bar.set_postfix_str(f"energy {Es1 / 4:.5f} (1 = isometry)", refresh=False)
            bar.update(1)
        Es = Es1
        if (hist[-1] - Es1) / hist[-1] < tol:
            # a tiny decrease means convergence only if the Newton step was not cut short by the flip barrier and
            # the scaffold was already at its lightest (a stiff scaffold slows boundary vertices down); cut-short
            # steps usually recover once the scaffold is re-triangulated, so only a run of them stops
            small += 1
            if t >= full_step and w_scaf > w_min:
                w_scaf = w_min
                continue
            if t >= full_step or small >= STALL_ITERS:
                hist.append(Es1)
                converged, stop = t >= full_step, ("converged" if t >= full_step else "stalled at the barrier")
                break
        else:
            small = 0
        # a stiff scaffold keeps boundaries apart while they move a lot, but it acts like a proximal term on
        # boundary vertices (thin scaffold triangles): relax it while Newton steps go through uncut
        w_scaf = max(w_scaf / SCAFFOLD_ADAPT, w_min) if t >= full_step else min(w_scaf * SCAFFOLD_ADAPT, w_max)
    info = {"iterations": it, "converged": converged, "stop": stop,
            "energy_start": float(hist[0] / 4 if hist else np.nan),
            "energy_end": float(hist[-1] / 4 if hist else np.nan), "factorizations": refactorizations,
            "backend": backend,
            "seconds": round(time.perf_counter() - t0, 3)}
    return x, info


# ----------------------------------------------------------------------------------------------------------
# coarse-to-fine: polish a coarse mesh, prolongate, repair the few flips, polish the fine mesh from there
# ----------------------------------------------------------------------------------------------------------
MULTILEVEL_MIN_VERTICES = 30_000  # default of Options.refine_multilevel: meshes this large polish coarse-to-fine
COARSE_FRACTION = 1 / 8  # each coarser level has about this fraction of the vertices (camelhead↑727k: at 1/27 the
#                          repair of the prolongation's flips failed, at 1/6.5 it needed 7 rounds) ...
COARSE_MIN = 8_000  # ... but at least this many; levels of >= refine_multilevel vertices get a coarser level too
REPAIR_RINGS = 8  # each repair round re-solves the flipped faces' 8-ring neighbourhoods ...
REPAIR_ROUNDS = 12  # ... at most this many rounds
MULTILEVEL_MIN_EXCESS = 1e-2  # coarse-to-fine only when the start's energy exceeds 1 (isometry) by more than this
#: After a converged coarse level the fine polish stops at this multiple of ``refine_tol``: its start is already
#: within ~0.5% of the minimum, and at 1e-6 its last 2 of 7 Newton iterations (camelhead↑182k, ~2.5 s each) gained
#: < 1e-5 of the energy together and no metric to 4 digits (iso mean 2.05884 at 1e-4 and 1e-6; docs/refine.md)
MULTILEVEL_FINE_TOL_FACTOR = 100.0


def coarse_vertices(V: np.ndarray, F: np.ndarray, loops: list[np.ndarray], target: int) -> np.ndarray:
    """About ``target`` surface vertices spread evenly in 3D: every boundary vertex (loop order), then per cell of
    a uniform grid (cell side √(area/target)) the interior vertex nearest the cell centre, skipping cells that hold
    boundary vertices. Deterministic. Returns vertex ids (k,), boundary loops first."""
    from heatparam.mesh import face_areas

    bnd = np.concatenate(loops)
    h = float(np.sqrt(face_areas(V, F).sum() / target))
    lo = V.min(axis=0)
    key = np.floor((V - lo) / h).astype(np.int64)
    _, cell = np.unique(key, axis=0, return_inverse=True)
    cell = cell.ravel()
    dist = np.linalg.norm(V - (lo + (key + 0.5) * h), axis=1)
    order = np.lexsort((dist, cell))
    first = order[np.r_[True, cell[order][1:] != cell[order][:-1]]]  # nearest the centre, per cell
    blocked = np.zeros(int(cell.max()) + 1, dtype=bool)
    blocked[cell[bnd]] = True
    return np.concatenate([bnd, np.sort(first[~blocked[cell[first]]])]).astype(np.int64)


def coarse_mesh(uv: np.ndarray, loops: list[np.ndarray], ids: np.ndarray) -> np.ndarray:
    """Triangles (c,3) over ``ids`` (boundary loops first, as :func:`coarse_vertices`): the constrained Delaunay
    triangulation of ``uv[ids]`` inside the outer loop and outside the holes (gpytoolbox, no Steiner points),
    counter-clockwise. ``uv`` (n,2) must be bijective, so the coarse faces tile the same region of the plane."""
    import gpytoolbox as gpy

    P = uv[ids]
    try:
        P2, T = gpy.triangulate_polygon(P, _loop_edges(_loop_ranges(loops)), a=0.0, q=0.0, steiner=False)
    except (ValueError, RuntimeError) as exc:
        raise ValueError(f"coarse triangulation failed: {exc}") from exc
    if len(P2) != len(ids):
        raise ValueError("the coarse triangulation added vertices")
    T = np.asarray(T, dtype=np.int64)
    e1, e2 = P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    T[cw] = T[cw][:, [0, 2, 1]]
    return T


def prolongate(uv: np.ndarray, uvc0: np.ndarray, T: np.ndarray, uvc: np.ndarray) -> np.ndarray:
    """Carry the coarse result to every fine vertex: locate each point of ``uv`` (n,2) in the coarse triangles T
    laid out at ``uvc0`` (their start positions, the same region) and apply the barycentric combination of the
    polished coarse positions ``uvc``. A piecewise-affine map of a bijective layout, (n,2)."""
    import igl

    _, face, C = igl.point_mesh_squared_distance(uv, uvc0, T)
    a, b, c = (uvc0[T[face, i]] for i in range(3))
    e1, e2, p = b - a, c - a, C - a
    den = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    l1 = (p[:, 0] * e2[:, 1] - p[:, 1] * e2[:, 0]) / den
    l2 = (e1[:, 0] * p[:, 1] - e1[:, 1] * p[:, 0]) / den
    l0 = 1.0 - l1 - l2
    return l0[:, None] * uvc[T[face, 0]] + l1[:, None] * uvc[T[face, 1]] + l2[:, None] * uvc[T[face, 2]]


def mean_value_laplacian(X: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """Floater's mean value Laplacian D − W of the triangles F over points ``X`` (n,2) or (n,3):
    w_ij = (tan(α/2) + tan(β/2)) / |X_i − X_j| with α, β the angles at i beside edge ij. Positive weights (so a
    convex boundary gives a flip-free interpolant); in the plane they reproduce affine maps of ``X`` exactly."""
    n = len(X)
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j, k = F[:, c], F[:, (c + 1) % 3], F[:, (c + 2) % 3]
        eij, eik = X[j] - X[i], X[k] - X[i]
        lij, lik = np.linalg.norm(eij, axis=1), np.linalg.norm(eik, axis=1)
        cos = np.clip((eij * eik).sum(axis=1) / (lij * lik), -1.0, 1.0)
        t = np.tan(0.5 * np.arccos(cos))
        rows += [i, i]
        cols += [j, k]
        vals += [t / lij, t / lik]
    W = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


def repair_flips(x: np.ndarray, ref: np.ndarray, F: np.ndarray, g: np.ndarray, locked: np.ndarray
                 ) -> tuple[np.ndarray | None, int, int]:
    """Unflip the few faces a prolongation flips (needle triangles straddling a coarse edge): re-solve the union of
    the flipped faces' ``REPAIR_RINGS``-ring neighbourhoods as mean value (Floater) interpolants with the weights
    of the layout ``ref`` (n,2) (the bijective start: locally an affine image of it is flip-free; weights of the
    3D surface measured worse, camelhead↑45k start energy 1.891 vs 1.877; or ``x`` itself, which those weights
    reproduce wherever its vertex stars are valid: the fallback, start energy 2.88 vs 1.87 at 182k) and the rest
    of ``x`` (n,2) as boundary values; grow the union around what is still flipped, at most ``REPAIR_ROUNDS``
    times.
    ``locked`` (n,) bool: vertices never moved.
    Returns (layout or None when flips remain, faces flipped at first, rounds)."""
    n = len(x)
    bad = np.flatnonzero(_det(jacobians(x, F, g)) <= 0)
    first = len(bad)
    if first == 0:
        return x, 0, 0
    L = mean_value_laplacian(ref, F)
    adj = (abs(L) > 0).astype(np.int8).tocsr()
    y, region = x.copy(), np.zeros(n, dtype=bool)
    for r in range(1, REPAIR_ROUNDS + 1):
        grow = np.zeros(n, dtype=bool)
        grow[F[bad].ravel()] = True
        for _ in range(REPAIR_RINGS):
            grow |= adj @ grow.astype(np.int8) > 0
        region |= grow
        free = region & ~locked
        fi, fx = np.flatnonzero(free), np.flatnonzero(~free)
        Lf = L[fi]
        y[fi] = spla.splu(Lf[:, fi].tocsc()).solve(-(Lf[:, fx] @ x[fx]))
        bad = np.flatnonzero(_det(jacobians(y, F, g)) <= 0)
        if len(bad) == 0:
            return y, first, r
    return None, first, REPAIR_ROUNDS


def boundary_faces(F: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """The triangles of F (m,3) whose three corners are all boundary vertices (``boundary`` (n,) bool), (k,3)."""
    return F[boundary[F].all(axis=1)]


def coarse_to_fine(V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                   *, min_vertices: int, max_iters: int, tol: float, backend: str, progress=None,
                   guards: np.ndarray | None = None) -> tuple[np.ndarray | None, dict]:
    """A start for the fine polish from a coarse one: :func:`coarse_vertices` and :func:`coarse_mesh` in the
    bijective layout ``x`` (n,2), :func:`multilevel_polish` of the coarse mesh from ``x`` (itself coarse-to-fine
    while a level has >= ``min_vertices`` vertices), :func:`prolongate`, :func:`repair_flips`.

    Every level keeps all boundary vertices, which the repair never moves; so a triangle whose three corners are
    boundary vertices (a corner "ear" of the scan; plenty in the coarse levels' own triangulations) could come out
    of the coarse polish flipped, beyond repair, unless the coarse polish keeps it positive: such triangles of this
    level (and its own ``guards`` (k,3)) are passed down as guards, triangles without energy that the line search
    keeps positive. Returns (layout (n,2) or None when no bijective one came out, report).
    """
    t0 = time.perf_counter()
    n = len(V)
    target = int(max(COARSE_FRACTION * n, COARSE_MIN))
    ids = coarse_vertices(V, F, loops, target)
    nb = sum(len(lp) for lp in loops)
    info: dict = {"coarse_vertices": int(len(ids)), "boundary_vertices": int(nb)}
    if nb > target // 2:
        return None, info | {"used": False, "reason": "the boundary alone has more than half the coarse vertices"}
    if len(ids) >= n:
        return None, info | {"used": False, "reason": "the coarse mesh would not be coarser"}
    try:
        T = coarse_mesh(x, loops, ids)
    except ValueError as exc:
        return None, info | {"used": False, "reason": str(exc)}
    gc, ac = surface_gradients(V[ids], T)
    cloops = _loop_ranges(loops)  # the coarse mesh's boundary loops: its first vertices, in loop order
    locked = np.zeros(n, dtype=bool)
    locked[ids[:nb]] = True  # the boundary is the coarse one: polished, bijective, kept as is
    local = np.full(n, -1, dtype=np.int64)
    local[ids] = np.arange(len(ids))
    ears = boundary_faces(F if guards is None else np.vstack([F, guards]), locked)
    xc, cinfo, cml = multilevel_polish(V[ids], T, x[ids], cloops, gc, ac, min_vertices=min_vertices,
                                       max_iters=max_iters, tol=tol, backend=backend, progress=progress,
                                       guards=local[ears], label=f"coarse, {len(ids)} vertices")
    info.update(coarse_polish=cinfo, coarse_multilevel=cml, guards=int(len(ears)))
    y = prolongate(x, x[ids], T, xc)
    y[ids] = xc
    z, flipped, rounds = repair_flips(y, x, F, g, locked)
    info["repair_weights"] = "start layout"
    if z is None:
        # the start's weights fail where the start is far from an affine image of the result (LSCM's scale varies
        # a lot across a repair region: camelhead↑727k's 111k-vertex level, 4 flips grew to 443); weights of the
        # prolongated layout itself keep it wherever its stars are valid, and unfold the rest (1 round there)
        z, _, rounds = repair_flips(y, y, F, g, locked)
        info["repair_weights"] = "prolongated layout"
    y = z
    info.update(prolongation_flips=flipped, repair_rounds=rounds, seconds=round(time.perf_counter() - t0, 3))
    if y is None:
        return None, info | {"used": False, "reason": f"{flipped} prolongated faces still flipped after repair"}
    if metrics.boundary_crossings(y, F):  # cannot happen with the coarse boundary kept; checked, not assumed
        return None, info | {"used": False, "reason": "the prolongated boundary crosses itself"}
    return y, info | {"used": True}


def multilevel_polish(V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                      area: np.ndarray, *, min_vertices: int, max_iters: int, tol: float, backend: str,
                      progress=None, guards: np.ndarray | None = None, label: str = "Newton"
                      ) -> tuple[np.ndarray, dict, dict]:
    """:func:`polish` of (V (n,3), F (m,3)) from the bijective layout ``x`` (n,2); coarse-to-fine
    (:func:`coarse_to_fine`) when the mesh has >= ``min_vertices`` (> 0) vertices and ``x`` is more than
    ``MULTILEVEL_MIN_EXCESS`` above an isometry. After a converged coarse level the polish stops at
    ``MULTILEVEL_FINE_TOL_FACTOR`` × ``tol``. Returns (layout (n,2), polish report, coarse-to-fine report)."""
    if not 0 < min_vertices <= len(V):
        ml: dict = {"used": False, "reason": "small mesh"}
    elif not _energy(x, F, g, area) > 1.0 + MULTILEVEL_MIN_EXCESS:
        ml = {"used": False, "reason": "the start is already within 1% of an isometry"}
    else:
        try:
            y, ml = coarse_to_fine(V, F, x, loops, g, min_vertices=min_vertices, max_iters=max_iters, tol=tol,
                                   backend=backend, progress=progress, guards=guards)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # only a faster start: never fatal
            y, ml = None, {"used": False, "reason": f"coarse level failed: {exc}"}
        if y is not None:
            x = y
            if ml["coarse_polish"]["converged"]:
                tol *= MULTILEVEL_FINE_TOL_FACTOR
            ml["fine_tol"] = tol
    # open-ended: Newton stops when converged (5-50 iterations measured), far below the cap
    bar = progress.bar(None, f"polish ({label})") if progress is not None else None
    try:
        x, pinfo = polish(x, F, g, area, loops, max_iters=max_iters, tol=tol, backend=backend, bar=bar,
                          guards=guards)
    finally:
        if bar is not None:
            bar.close()
    return x, pinfo, ml


# ----------------------------------------------------------------------------------------------------------
# the stage
# ----------------------------------------------------------------------------------------------------------
def surface_gradients(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hat gradients (m,3,2) of each 3D triangle in its own frame, and the areas (m,) (mollified lengths)."""
    raw = edge_lengths(V, F)
    lengths, _ = mollify(raw, 1e-4 * float(raw.mean()))
    return hat_gradients(local_triangles(lengths)), intrinsic_areas(lengths)


def _is_bijective(uv: np.ndarray, F: np.ndarray, g: np.ndarray) -> tuple[int, int]:
    """(flipped faces, boundary crossings) of a layout; crossings are only counted when nothing is flipped."""
    flips = int((_det(jacobians(uv, F, g)) <= 0).sum())
    return flips, (int(metrics.boundary_crossings(uv, F)) if flips == 0 else -1)


#: With ``Options.mds_start == "auto"`` the heat geodesics and MDS are skipped when the LSCM start is bijective and
#: its energy exceeds an isometry's (1) by at most this: no start can be better by more than this, and the polish
#: converges from LSCM in 0-3 iterations. The MDS start's excess measured 2.7e-3 to 0.34 on every surface tried
#: (docs/refine.md), so skipping changed no start.
ISOMETRIC_START_EXCESS = 1e-3


#: An MDS layout with a few flipped faces (at most this fraction, and at least 1) is repaired before it competes as a
#: start: ``repair_flips`` with the boundary locked, accepted only when the result is bijective. A cylinder patch of
#: 49k vertices with noise of 0.2 × the edge length: MDS had 3 flips (energy 1.079 after the repair), LSCM energy
#: 4.69; polish 13 instead of 26 Newton iterations, the same map quality (SD 1.005365, iso 1.0563).
MDS_REPAIR_MAX_FRACTION = 1e-3


def repaired_layout(x: np.ndarray, F: np.ndarray, g: np.ndarray, loops: list[np.ndarray]
                    ) -> tuple[np.ndarray | None, dict]:
    """``x`` (n,2) made bijective by :func:`repair_flips` if only a few of its faces are flipped
    (≤ ``MDS_REPAIR_MAX_FRACTION``), with the boundary loops locked; (layout or None, report)."""
    flips = int((_det(jacobians(x, F, g)) <= 0).sum())
    if flips == 0:
        return None, {"flips": 0, "repaired": False, "reason": "nothing flipped"}
    if flips > max(1, MDS_REPAIR_MAX_FRACTION * len(F)):
        return None, {"flips": flips, "repaired": False, "reason": "too many flips to repair"}
    locked = np.zeros(len(x), dtype=bool)
    locked[np.concatenate(loops)] = True
    z, _, rounds = repair_flips(x, x, F, g, locked)
    if z is None:
        return None, {"flips": flips, "repaired": False, "reason": f"flips remain after {rounds} rounds"}
    if metrics.boundary_crossings(z, F):
        return None, {"flips": flips, "repaired": False, "reason": "the boundary crosses itself"}
    return z, {"flips": flips, "repaired": True, "rounds": rounds}


class LscmStart(NamedTuple):
    """The LSCM layout as a start candidate: the layout (None if it failed), flips, crossings (-1 when not
    counted), its energy per area / 4 (1 = isometry; None unless bijective) and why it failed."""

    uv: np.ndarray | None
    flips: int
    crossings: int
    energy: float | None
    failed: str | None = None

    @property
    def near_isometric(self) -> bool:
        return self.energy is not None and self.energy - 1.0 <= ISOMETRIC_START_EXCESS


def lscm_start(V: np.ndarray, F: np.ndarray, conformal: Callable[[], np.ndarray] | None = None,
               surface: tuple[np.ndarray, np.ndarray] | None = None) -> LscmStart:
    """The LSCM layout of (V, F) (``conformal()`` if given, else computed) judged as a start for the polish.

    surface : ``surface_gradients(V, F)`` if already computed.
    """
    g, area = surface if surface is not None else surface_gradients(V, F)
    try:
        xl = np.array(conformal() if conformal is not None else conformal_start(V, F, build_disk(V, F)))
    except HeatparamError as exc:  # a degenerate mesh: LSCM is only a candidate start, MDS or Tutte still serve
        return LscmStart(None, -1, -1, None, str(exc))
    flips, cross = _is_bijective(xl, F, g)
    energy = _energy(xl, F, g, area) if flips == 0 and cross == 0 else None
    return LscmStart(xl, flips, cross, energy)


def refine(V: np.ndarray, F: np.ndarray, uv: np.ndarray | None, opts=None, progress=None,
           conformal: Callable[[], np.ndarray] | None = None, lscm: LscmStart | None = None,
           surface: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, dict]:
    """Make the MDS layout ``uv`` (n,2) of (V (n,3), F (m,3)) bijective and near-isometric (true scale).

    Start: of the MDS layout (a few flipped faces repaired: :func:`repaired_layout`) and the LSCM layout (``lscm``
    if given, else :func:`lscm_start` with ``conformal()`` — the fill decision already computed it), the bijective
    one (no flipped face, no crossing of any boundary loop) with the lower energy; if neither is bijective, the
    Tutte embedding of the mesh with its holes fanned.
    ``uv=None``: no MDS layout was computed (the pipeline found it could not win: ``pipeline._start_checks``).
    Then :func:`polish` with the scaffold. ``surface``: :func:`surface_gradients` of (V, F) if already computed.

    Returns the refined layout (n,2) and a JSON-able report of what was done.
    """
    t0 = time.perf_counter()
    backend = getattr(opts, "solver", "auto")
    max_iters = int(getattr(opts, "refine_iters", 200))
    tol = float(getattr(opts, "refine_tol", 1e-6))
    n = len(V)
    disk = build_disk(V, F)
    loops = [disk.outer, *disk.holes]
    g, area = surface if surface is not None else surface_gradients(V, F)
    report: dict = {"method": "sd", "holes": len(disk.holes)}

    if lscm is None:
        lscm = lscm_start(V, F, conformal, (g, area))
    cands: dict[str, np.ndarray] = {}
    energy: dict[str, float] = {}
    if uv is None:
        report["start"] = {"mds": "not computed (the pipeline's method.geodesics says why)"}
    else:
        x = np.asarray(uv, dtype=np.float64)
        flips, cross = _is_bijective(x, F, g)
        report["start"] = {"flips": flips, "crossings": cross}
        if flips:  # crossings are only counted when nothing is flipped; a repaired layout has none
            x, report["start"]["repair"] = repaired_layout(x, F, g, loops)
            cross = 0
        if x is not None and not cross:
            cands["mds"], energy["mds"] = x, _energy(x, F, g, area)
    if lscm.failed is not None:
        report["start"]["lscm_failed"] = lscm.failed
    report["start"].update(lscm_flips=lscm.flips, lscm_crossings=lscm.crossings)
    if lscm.energy is not None:
        cands["lscm"], energy["lscm"] = lscm.uv, lscm.energy
    # of the bijective candidates, start from the one with the lower energy: on developable parts LSCM (already
    # computed by the fill decision) is an isometry up to round-off, where MDS needs 5-7 Newton iterations
    if cands:
        start = min(energy, key=energy.get)
        x = np.array(cands[start], dtype=np.float64)
        report["start"]["energy"] = energy
    else:
        x, start = tutte(V, disk, backend)[:n], "tutte"
    report["start"]["layout"] = start
    ml_min = int(getattr(opts, "refine_multilevel", MULTILEVEL_MIN_VERTICES))
    # One OpenBLAS thread: the polish's vector work is small, and OpenBLAS threads on it cost 10-60% on 2 cores
    # (2.2 s vs 2.5 s on camelhead alone, 6.2 s with another process busy). MKL (PARDISO) keeps its threads.
    with ThreadpoolController().select(internal_api="openblas").limit(limits=1):
        x, pinfo, report["multilevel"] = multilevel_polish(V, F, x, loops, g, area, min_vertices=ml_min,
                                                           max_iters=max_iters, tol=tol, backend=backend,
                                                           progress=progress)
    pinfo["method"] = "projected-newton + scaffold"
    report["polish"] = pinfo
    report["flips"] = int((_det(jacobians(x, F, g)) <= 0).sum())
    report["boundary_crossings"] = int(metrics.boundary_crossings(x, F))
    report["bijective"] = report["flips"] == 0 and report["boundary_crossings"] == 0
    report["seconds"] = round(time.perf_counter() - t0, 3)
    return x, report
