"""Conformal layouts: least-squares conformal maps (LSCM, Lévy et al. 2002) and orientation of a layout.

Not MDS: the fill uses the LSCM layout to decide where M* extends, the refinement as a start candidate. LSCM is
exact up to scale on developable surfaces (``conformal_layout`` scales it to the 3D area).
"""

from __future__ import annotations

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.mesh.planar import signed_areas
from heatparam.mesh.topology import face_areas


def needs_mirror(uv: np.ndarray, F: np.ndarray) -> bool:
    """Whether most of the layout's signed area is clockwise (MDS fixes coordinates only up to a reflection)."""
    return bool(signed_areas(uv, F).sum() < 0)


def orient_layout(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Mirror the layout if most of its signed area is clockwise, so the faces keep the mesh's orientation."""
    if needs_mirror(uv, F):
        uv = uv.copy()
        uv[:, 1] *= -1
    return uv

def lscm(V: np.ndarray, F: np.ndarray, pinned: np.ndarray, pinned_uv: np.ndarray, backend: str = "auto") -> np.ndarray:
    """Least-squares conformal map (Lévy et al. 2002) with ``pinned`` (k,) vertices at ``pinned_uv`` (k,2).

    Minimizes E_C = ½ ∫ |J|² − ∫ det J = ½ xᵀ (K ⊕ K) x − A(x), K the cotangent Laplacian (∫|∇u|² = uᵀKu) and
    A(x) = ½ Σ (u_i v_j − u_j v_i) over the boundary half-edges i → j (the layout's signed area, holes included),
    so the Hessian is Q = (K ⊕ K) − 2M with M the symmetric form of A. Q restricted to the free unknowns is SPD once
    two vertices are pinned; it is factorized by ``solvers.Factor`` (PARDISO for large systems when installed:
    ``solvers.large_system_backend``). Returns uv (n,2); vertices no face uses stay at 0.
    """
    import igl
    import scipy.sparse as sp

    from heatparam.mesh.topology import boundary_loops
    from heatparam.solvers import Factor, large_system_backend

    n = len(V)
    K = (-igl.cotmatrix(V, F)).tocsc()
    he = [(lp, np.roll(lp, -1)) for lp in boundary_loops(F)]  # half-edges i → j as oriented in their faces
    i = np.concatenate([h[0] for h in he]) if he else np.zeros(0, np.int64)
    j = np.concatenate([h[1] for h in he]) if he else np.zeros(0, np.int64)
    # M: A(x) = xᵀ M x with x = (u, v); each half-edge adds u_i v_j / 2 − u_j v_i / 2, split symmetrically
    r = np.concatenate([i, j + n, j, i + n])
    c = np.concatenate([j + n, i, i + n, j])
    w = np.repeat([0.25, 0.25, -0.25, -0.25], len(i))
    M = sp.csc_matrix((w, (r, c)), shape=(2 * n, 2 * n))
    Q = (sp.block_diag([K, K], format="csc") - 2.0 * M).tocsc()
    used = np.zeros(n, dtype=bool)
    used[F.ravel()] = True
    fixed = np.concatenate([pinned, pinned + n])
    free = np.setdiff1d(np.flatnonzero(np.concatenate([used, used])), fixed)
    xp = np.concatenate([pinned_uv[:, 0], pinned_uv[:, 1]])
    Qf = Q[free]
    rhs = -(Qf[:, fixed] @ xp)
    Qff = Qf[:, free]
    x = np.zeros(2 * n)
    x[fixed] = xp
    try:
        x[free] = Factor(Qff, large_system_backend(len(free), backend)).solve(rhs)
    except (ValueError, RuntimeError) as exc:  # not positive definite: degenerate faces, several components
        raise HeatparamError(f"the conformal (LSCM) layout failed ({exc}): is the mesh degenerate?") from exc
    return np.column_stack([x[:n], x[n:]])

def conformal_layout(V: np.ndarray, F: np.ndarray, outer: np.ndarray, backend: str = "auto") -> np.ndarray:
    """A quick reference layout: free-boundary LSCM (two far vertices of the outer loop pinned), mirrored to keep
    the mesh's orientation, scaled to the 3D area and centred. (n,2) float64.

    Not MDS: the fill uses it to decide where M* extends, the refinement as a fallback start when the MDS layout
    folds. LSCM is exact up to scale on developable surfaces. Large systems that PARDISO would factorize
    (``solvers.large_system_backend``) go through :func:`lscm` (196k-vertex cylinder patch 1.7 s vs 10.0 s for
    ``igl.lscm``, camelhead↑180k 2.9 s vs 6.2 s); smaller ones through ``igl.lscm`` (45k: 0.59 s vs 0.96 s). Same map.
    """
    import igl

    from heatparam.solvers import large_system_backend

    a = int(outer[0])
    b = int(outer[np.argmax(np.linalg.norm(V[outer] - V[a], axis=1))])
    pins, pin_uv = np.array([a, b], dtype=np.int64), np.array([[0.0, 0.0], [1.0, 0.0]])
    if large_system_backend(2 * len(V), backend) == "pardiso":
        uv = lscm(V, F, pins, pin_uv, backend="pardiso")
    else:
        try:
            uv, _ = igl.lscm(V, F, pins, pin_uv)
        except RuntimeError:  # "igl::lscm failed": its solver gave up on degenerate faces (thin limbs, slivers)
            raise HeatparamError("the conformal (LSCM) layout failed: is the mesh degenerate?") from None
    uv = np.asarray(uv, dtype=np.float64)
    if not np.isfinite(uv).all():
        raise HeatparamError("the conformal (LSCM) layout failed: is the mesh degenerate?")
    signed = signed_areas(uv, F).sum()
    if signed < 0:
        uv[:, 1] *= -1
    uv *= np.sqrt(face_areas(V, F).sum() / max(abs(signed), 1e-300))
    return uv - uv.mean(axis=0)
