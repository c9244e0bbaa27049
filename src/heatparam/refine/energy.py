"""The symmetric Dirichlet energy of a layout: per-face Jacobians, energy, gradient, PSD-projected Hessian blocks.

Symmetric Dirichlet energy Σ A_f (|J|² + |J⁻¹|²) (Eq. 1's isometric goal at true scale: its minimum is the isometry
itself, no rescaling), with the closed-form Hessian eigensystem of Smith et al. 2019 (:func:`sd_eigensystem`; the
PSD projection is a clamp of one eigenvalue), and the largest step keeping every det J positive (Smith & Schaefer
2015, :func:`max_step`).
"""

from __future__ import annotations

import numpy as np

from heatparam.compiled import COMPILED_MIN_FACES, Compiled, compiled, warmup
from heatparam.operators import intrinsic_areas, local_triangles, mollified_lengths


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

# From COMPILED_MIN_FACES faces the per-face work of :func:`jacobians` and :func:`sd_newton_entries` runs in compiled
# loops: at 235k faces the entries took 27 against numpy's 91 ms; a held-out part of 235k faces spent 2.0 s of 21 s in
# Jacobians (479 calls), 0.8 s compiled. Both give the same bits (the entries on this machine; the Jacobians by the
# same sums in the same order).


def jacobians(uv: np.ndarray, F: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Per-face Jacobians (m,2,2) of the map to ``uv`` (n,2): J[f,a,c] = Σ_i uv[F[f,i],a] g[f,i,c].

    A face's J is the same bits however many faces come with it (compiled or numpy, both summing i = 0, 1, 2 in
    turn): a zero-area face laid out flat has det J at round-off, and a coarse level that holds it
    (``multilevel.CoarseLevel``) must see the sign its mesh saw (numpy's matmul, summing otherwise, flipped one)."""
    if len(F) < COMPILED_MIN_FACES:
        X = uv[F]
        J = np.empty((len(F), 2, 2))
        for a in range(2):
            for c in range(2):
                J[:, a, c] = X[:, 0, a] * g[:, 0, c] + X[:, 1, a] * g[:, 1, c] + X[:, 2, a] * g[:, 2, c]
        return J
    J = np.empty((len(F), 2, 2))
    _jacobian_loop(np.ascontiguousarray(uv, dtype=np.float64), np.ascontiguousarray(F),
                   np.ascontiguousarray(g, dtype=np.float64), J)
    return J


@compiled()
def face_jacobian(uv, F, g, f):  # pragma: no cover - compiled
    """Face f's Jacobian (J00, J01, J10, J11) of the map to ``uv``: J[r,s] = Σ_i uv[F[f,i],r] g[f,i,s], for compiled
    per-face loops (:func:`_jacobian_loop`, ``refine.smoother``)."""
    a, b, c = F[f, 0], F[f, 1], F[f, 2]
    return (uv[a, 0] * g[f, 0, 0] + uv[b, 0] * g[f, 1, 0] + uv[c, 0] * g[f, 2, 0],
            uv[a, 0] * g[f, 0, 1] + uv[b, 0] * g[f, 1, 1] + uv[c, 0] * g[f, 2, 1],
            uv[a, 1] * g[f, 0, 0] + uv[b, 1] * g[f, 1, 0] + uv[c, 1] * g[f, 2, 0],
            uv[a, 1] * g[f, 0, 1] + uv[b, 1] * g[f, 1, 1] + uv[c, 1] * g[f, 2, 1])


@compiled(face_jacobian)
def _jacobian_loop(uv, F, g, J):  # pragma: no cover - compiled
    """:func:`jacobians` into J (m,2,2), one face at a time."""
    for f in range(F.shape[0]):
        J[f, 0, 0], J[f, 0, 1], J[f, 1, 0], J[f, 1, 1] = face_jacobian(uv, F, g, f)


def det(J: np.ndarray) -> np.ndarray:
    return J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]

def scatter(dJ: np.ndarray, F: np.ndarray, g: np.ndarray, n: int) -> np.ndarray:
    """Chain rule: per-face dE/dJ (m,2,2) → dE/duv (n,2)."""
    dQ = np.matmul(g, dJ.transpose(0, 2, 1))  # (m,3,2)
    out = np.empty((n, 2))
    idx = F.ravel()
    out[:, 0] = np.bincount(idx, weights=dQ[:, :, 0].ravel(), minlength=n)
    out[:, 1] = np.bincount(idx, weights=dQ[:, :, 1].ravel(), minlength=n)
    return out

def symmetric_dirichlet(J: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Σ w_f (|J|² + |J⁻¹|²) and per-face values (inf where det J ≤ 0)."""
    d = det(J)
    f2 = (J * J).sum(axis=(1, 2))
    with np.errstate(divide="ignore"):
        e = np.where(d > 0, f2 * (1.0 + 1.0 / np.where(d > 0, d, 1.0) ** 2), np.inf)
    return float(np.dot(w, e)) if np.all(d > 0) else float("inf"), e

def normalized_energy(uv: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray) -> float:
    """Symmetric Dirichlet energy per area / 4 of a layout (1 = isometry)."""
    return symmetric_dirichlet(jacobians(uv, F, g), area / area.sum())[0] / 4

def max_step(J: np.ndarray, D: np.ndarray) -> float:
    """Largest t ≤ ∞ such that det(J + sD) > 0 for all s in [0, t) (per-face quadratic, first positive root)."""
    t = face_step_limits(J, D)
    return float(t.min()) if len(t) else float("inf")


def face_step_limits(J: np.ndarray, D: np.ndarray) -> np.ndarray:
    """(m,) per face: the largest t ≤ ∞ such that det(J + sD) > 0 for all s in [0, t) (:func:`max_step`)."""
    c = det(J)
    a = det(D)
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
    return t

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

#: The 21 entries (p, q), p ≤ q, of a face's symmetric 6×6 block that :func:`sd_newton_entries` computes, in its
#: order: the (u, u) block's upper triangle (i ≤ j), the (v, v) block's, then the (u, v) block's 9 (u_i, v_j); the
#: unknowns of a face are ordered (u₀,u₁,u₂,v₀,v₁,v₂) as in :func:`sd_newton_blocks`
_I3, _J3 = np.triu_indices(3)
BLOCK_ENTRIES = np.array([(i, j) for i, j in zip(_I3, _J3, strict=True)]
                         + [(3 + i, 3 + j) for i, j in zip(_I3, _J3, strict=True)]
                         + [(i, 3 + j) for i in range(3) for j in range(3)], dtype=np.int64)

#: Faces per pass of :func:`sd_newton_entries`: its ~60 temporaries of this length stay in the CPU's cache (363k faces
#: at once: 0.21 s; in passes of 4k-16k faces: 0.10 s; :func:`sd_newton_blocks`: 0.34 s)
ENTRY_CHUNK = 8192


def sd_newton_entries(J: np.ndarray, g: np.ndarray, w: np.ndarray, chunk: int = ENTRY_CHUNK
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sd_newton_blocks` as the 21 distinct entries of each symmetric block (``BLOCK_ENTRIES``), in closed
    form, ``chunk`` faces at a time (from ``COMPILED_MIN_FACES`` faces, one compiled loop over all): dE/dJ (m,2,2)
    and the entries (21, m).

    With J = U diag(σ) Vᵀ, U = rot(θ_U) (columns u₁, u₂), V = rot(θ_V), the pulled-back corner vectors P = g v₁ and
    R = g v₂ (3,) and the clamped eigenvalues of :func:`sd_eigensystem` (λ₁, λ₂, twist λ₃⁺, flip λ₄) with
    μ = λ₃⁺/2, ν = λ₄/2, σ = μ + ν, δ = ν − μ, the block Σ_k λ_k b_k b_kᵀ is, for unknown blocks a, b ∈ {u, v}:

        H_ab[i, j] = w (α_ab P_i P_j + β_ab R_i R_j + γ_ab P_i R_j + γ_ba R_i P_j),
        α_ab = λ₁ u₁ₐ u₁ᵦ + σ u₂ₐ u₂ᵦ,  β_ab = λ₂ u₂ₐ u₂ᵦ + σ u₁ₐ u₁ᵦ,  γ_ab = δ u₂ₐ u₁ᵦ

    (the twist and flip terms expanded), one component array at a time instead of (m,4,6) stacks and a batched
    product: 3.3× faster at 363k faces, equal to round-off (tests)."""
    m = len(J)
    grad, out = np.empty((m, 2, 2)), np.empty((21, m))
    if m >= COMPILED_MIN_FACES:
        _entries_loop(np.ascontiguousarray(J, dtype=np.float64), np.ascontiguousarray(g, dtype=np.float64),
                      np.ascontiguousarray(w, dtype=np.float64), grad, out)
        return grad, out
    for a0 in range(0, m, max(1, chunk)):
        b0 = min(m, a0 + max(1, chunk))
        _entries(J[a0:b0], g[a0:b0], w[a0:b0], grad[a0:b0], out[:, a0:b0])
    return grad, out


def _entries(J: np.ndarray, g: np.ndarray, w: np.ndarray, grad: np.ndarray, out: np.ndarray) -> None:
    """:func:`sd_newton_entries` on one pass of faces, written into ``grad`` (k,2,2) and ``out`` (21,k)."""
    cu, su, cv, sv, l1, l2, sig, dl, d1, d2 = _svd_terms(J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1], w)
    cd1, sd1, cd2, sd2 = cu * d1, su * d1, cu * d2, su * d2
    grad[:, 0, 0] = cd1 * cv + sd2 * sv
    grad[:, 0, 1] = cd1 * sv - sd2 * cv
    grad[:, 1, 0] = sd1 * cv - cd2 * sv
    grad[:, 1, 1] = sd1 * sv + cd2 * cv
    P = [g[:, i, 0] * cv + g[:, i, 1] * sv for i in range(3)]  # g v₁
    R = [g[:, i, 1] * cv - g[:, i, 0] * sv for i in range(3)]  # g v₂
    A0, B0, G0, A1, B1, G1, A01, B01, G01, G10 = _block_terms(cu, su, l1, l2, sig, dl)
    for k, (i, j) in enumerate(zip(_I3, _J3, strict=True)):
        pp, rr, pr = P[i] * P[j], R[i] * R[j], P[i] * R[j] + R[i] * P[j]
        out[k] = A0 * pp + B0 * rr + G0 * pr
        out[k + 6] = A1 * pp + B1 * rr + G1 * pr
    for k in range(9):
        i, j = divmod(k, 3)
        out[12 + k] = A01 * (P[i] * P[j]) + B01 * (R[i] * R[j]) + G01 * (P[i] * R[j]) + G10 * (R[i] * P[j])


def _svd_terms(a, b, c, d, w):
    """Of J = [[a, b], [c, d]] and the weight w (arrays, or scalars in :func:`_entries_loop`): the rotations' cos and
    sin (cu, su of U, cv, sv of V), the weighted eigenvalues l1, l2, σ = μ + ν and δ = ν − μ (μ, ν: half the clamped
    twist and the flip eigenvalues), and the weighted dΨ/dσ₁,₂ (d1, d2)."""
    # signed SVD as svd2: σ₁,₂ = q ± r, θ_U = (a₂ + a₁)/2, θ_V = (a₁ − a₂)/2
    e, f, gg, h = 0.5 * (a + d), 0.5 * (a - d), 0.5 * (c + b), 0.5 * (c - b)
    q, r = np.sqrt(e * e + h * h), np.sqrt(f * f + gg * gg)
    a1, a2 = np.arctan2(gg, f), np.arctan2(h, e)
    tu, tv = 0.5 * (a2 + a1), 0.5 * (a1 - a2)
    s1, s2 = q + r, q - r
    s11, s22, s12 = s1 * s1, s2 * s2, s1 * s2
    p3 = s12 * s12 * s12
    l1 = w * (2 + 6 / (s11 * s11))
    l2 = w * (2 + 6 / (s22 * s22))
    mu = w * np.maximum(1 - (s11 - s12 + s22) / p3, 0.0)  # half the twist eigenvalue, clamped (the PSD projection)
    nu = w * np.maximum(1 + (s11 + s12 + s22) / p3, 0.0)  # half the flip eigenvalue (< 0 only where det J < 0)
    # dΨ/dJ = U diag(2σ − 2σ⁻³) Vᵀ, weighted
    d1, d2 = w * (2 * s1 - 2 / (s1 * s11)), w * (2 * s2 - 2 / (s2 * s22))
    return np.cos(tu), np.sin(tu), np.cos(tv), np.sin(tv), l1, l2, mu + nu, nu - mu, d1, d2


def _block_terms(cu, su, l1, l2, sig, dl):
    """The coefficients α, β, γ of the (u, u), (v, v) and (u, v) blocks (:func:`sd_newton_entries`), with
    u₁ = (cu, su), u₂ = (−su, cu): A0, B0, G0, A1, B1, G1, A01, B01, G01, G10."""
    cc, ss, cs = cu * cu, su * su, cu * su
    return (l1 * cc + sig * ss, l2 * ss + sig * cc, -(dl * cs), l1 * ss + sig * cc, l2 * cc + sig * ss, dl * cs,
            (l1 - sig) * cs, (sig - l2) * cs, -(dl * ss), dl * cc)


#: the per-face terms compiled for :func:`_entries_loop`, which names them (Python calls them as they are, on arrays)
_COMPILED_TERMS = (Compiled(_svd_terms, options={"error_model": "numpy"}), Compiled(_block_terms))


@compiled(*_COMPILED_TERMS)
def _entries_loop(J, g, w, grad, out):  # pragma: no cover - compiled
    """:func:`_entries` one face at a time, with the same terms (:func:`_svd_terms`, :func:`_block_terms`)."""
    for f in range(J.shape[0]):
        cu, su, cv, sv, l1, l2, sig, dl, d1, d2 = _svd_terms(J[f, 0, 0], J[f, 0, 1], J[f, 1, 0], J[f, 1, 1], w[f])
        cd1, sd1, cd2, sd2 = cu * d1, su * d1, cu * d2, su * d2
        grad[f, 0, 0] = cd1 * cv + sd2 * sv
        grad[f, 0, 1] = cd1 * sv - sd2 * cv
        grad[f, 1, 0] = sd1 * cv - cd2 * sv
        grad[f, 1, 1] = sd1 * sv + cd2 * cv
        P = (g[f, 0, 0] * cv + g[f, 0, 1] * sv, g[f, 1, 0] * cv + g[f, 1, 1] * sv, g[f, 2, 0] * cv + g[f, 2, 1] * sv)
        R = (g[f, 0, 1] * cv - g[f, 0, 0] * sv, g[f, 1, 1] * cv - g[f, 1, 0] * sv, g[f, 2, 1] * cv - g[f, 2, 0] * sv)
        A0, B0, G0, A1, B1, G1, A01, B01, G01, G10 = _block_terms(cu, su, l1, l2, sig, dl)
        k = 0
        for i in range(3):  # the upper triangles in BLOCK_ENTRIES' order
            for j in range(i, 3):
                pp, rr, pr = P[i] * P[j], R[i] * R[j], P[i] * R[j] + R[i] * P[j]
                out[k, f] = A0 * pp + B0 * rr + G0 * pr
                out[k + 6, f] = A1 * pp + B1 * rr + G1 * pr
                k += 1
        for k in range(9):
            i, j = k // 3, k % 3
            out[12 + k, f] = A01 * (P[i] * P[j]) + B01 * (R[i] * R[j]) + G01 * (P[i] * R[j]) + G10 * (R[i] * P[j])


def surface_gradients(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hat gradients (m,3,2) of each 3D triangle in its own frame, and the areas (m,) (mollified lengths)."""
    lengths = mollified_lengths(V, F)
    return hat_gradients(local_triangles(lengths)), intrinsic_areas(lengths)


@warmup
def _warm() -> None:
    """The compiled loops run once on one triangle (:func:`heatparam.compiled.warm_all`)."""
    _jacobian_loop(np.eye(3, 2), np.array([[0, 1, 2]]), np.ones((1, 3, 2)), np.empty((1, 2, 2)))
    _entries_loop(np.eye(2)[None], np.ones((1, 3, 2)), np.ones(1), np.empty((1, 2, 2)), np.empty((21, 1)))
