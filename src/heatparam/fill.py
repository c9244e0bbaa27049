"""The fill surface M* ⊃ M of paper §2.5 (Eq. 15-16), trimmed to a disk, and the M → M* correspondence.

Geodesics on a mesh M with holes or a concave border bend around the gaps, so MDS of them distorts or folds
the layout. The paper computes them instead on a surface M* that contains M and spans its holes and concave
bays, then restricts the distances to M's points. Two constructions of M* are offered (see docs/fill.md):

``poisson`` (the paper's, :func:`poisson_fill`)
    Screened Poisson reconstruction (Kazhdan's PoissonRecon through ``gpytoolbox.point_cloud_to_mesh``): the
    indicator χ solves Δχ = ∇·N (Eq. 16) for the oriented samples N of M, and M* is its level set at the mean
    value of χ over the samples (Eq. 15). The open Poisson surface is then trimmed (:func:`trim_to_hull`) to a
    disk over the convex hull of M's provisional layout, and M's vertices are located on it by closest point.

``biharmonic`` (:func:`biharmonic_fill`)
    The same region — convex hull of M's provisional layout — but M is kept as it is and only the gaps
    (holes, bays between the outer border and the hull) are triangulated in the provisional 2D layout and lifted
    to 3D by a biharmonic extension of M's coordinates. It continues a developable surface across wide gaps far
    more faithfully than Poisson's indicator function, which bulges there (the S-strip on a cone).

Every function takes plain arrays: ``V`` (n,3) float64, ``F`` (m,3) int64, and returns plain arrays.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import igl
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, Delaunay, QhullError

from heatparam.errors import HeatparamError
from heatparam.layout.conformal import conformal_layout
from heatparam.mesh.planar import signed_areas, triangulate
from heatparam.mesh.topology import boundary_loops, face_areas
from heatparam.mesh.validate import MeshInfo

__all__ = [
    "FILL_METHODS",
    "FillResult",
    "biharmonic_fill",
    "concavity",
    "fill_surface",
    "locate_points",
    "needs_fill",
    "poisson_fill",
    "poisson_reconstruct",
    "provisional_layout",
    "trim_to_hull",
]

FILL_METHODS = ("poisson", "biharmonic")

#: needs_fill: convex-hull area / area of the provisional layout above which the border counts as concave.
CONCAVITY_THRESHOLD = 1.10
#: Trimming: a Poisson vertex is kept only within this multiple of the bbox diagonal of M (3D distance to M).
NEAR_FRACTION = 0.25
#: Trimming: a Poisson face is kept only if its normal and M's normal at the closest point have a dot
#: product above this (rejects the far side of a closed reconstruction).
NORMAL_AGREEMENT = 0.0
#: Poisson samples per vertex of M (area-weighted surface samples, plus the vertices themselves), and bounds.
SAMPLES_PER_VERTEX = 10
MIN_SAMPLES, MAX_SAMPLES = 20_000, 200_000
#: Biharmonic fill: bays of the border shallower than this many mean edges are left unfilled (no slivers).
MIN_BAY_DEPTH = 0.5
#: Biharmonic fill: ... and bays shallower than this fraction of M's diameter.
MIN_BAY_DEPTH_REL = 0.02
#: Automatic depth: the octree cell is about CELL_PER_EDGE of M's mean edge, clamped to these depths.
CELL_PER_EDGE = 0.5
MIN_DEPTH, MAX_DEPTH = 6, 9


@dataclass(frozen=True, eq=False)
class FillResult:
    """A fill surface M* and where the vertices of M lie on it.

    Attributes
    ----------
    V : (N,3) float64 vertices of M*. F : (K,3) int64 triangles of M* (one connected disk, one boundary loop).
    face : (n,) int64 face of M* holding each vertex of M. bary : (n,3) float64 its barycentric coordinates.
    report : JSON-able facts (method, sizes, depth, M → M* distances, trimming parameters).
    warnings : user-facing findings (e.g. M* has more than one boundary loop).
    """

    V: np.ndarray
    F: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    report: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


# ----------------------------------------------------------------------------------------------------------
# provisional layout and the decision
# ----------------------------------------------------------------------------------------------------------
def provisional_layout(V: np.ndarray, F: np.ndarray, info: MeshInfo | None = None,
                       conformal: Callable[[], np.ndarray] | None = None) -> np.ndarray:
    """A quick conformal layout of M (``layout.conformal.conformal_layout``: the spectral conformal map scaled to
    M's area), (n,2) float64.

    Only used to decide where M* extends (the convex hull of this layout) and to triangulate the gaps; the
    final map never uses it. ``conformal``, if given, returns that layout already computed (the pipeline
    computes it at most once per run and shares it with the refinement's fallback start).
    """
    if conformal is not None:
        return conformal()
    return conformal_layout(V, F)


def concavity(uv: np.ndarray, F: np.ndarray) -> float:
    """Convex-hull area / area of the layout ``uv`` (n,2) of (·, F): 1 for a convex disk without holes."""
    area = float(np.abs(signed_areas(uv, F)).sum())
    try:
        hull = ConvexHull(uv[np.unique(F)])
    except QhullError:
        return 1.0
    return float(hull.volume) / max(area, 1e-300)


def needs_fill(V: np.ndarray, F: np.ndarray, info: MeshInfo,
               conformal: Callable[[], np.ndarray] | None = None) -> tuple[bool, str]:
    """Whether M needs a fill surface M*: it has holes, or its border is concave.

    Concavity is measured on the provisional layout (:func:`provisional_layout`): convex-hull area / area
    above :data:`CONCAVITY_THRESHOLD`. Returns (decision, reason), the reason a short line for the report.
    """
    if info.n_holes > 0:
        return True, f"auto: {info.n_holes} hole{'s' if info.n_holes > 1 else ''}"
    try:
        ratio = concavity(provisional_layout(V, F, info, conformal), F)
    except HeatparamError:
        return False, "auto: no fill (the concavity test failed: provisional layout degenerate)"
    if ratio > CONCAVITY_THRESHOLD:
        return True, f"auto: concave border (hull/area {ratio:.2f} > {CONCAVITY_THRESHOLD})"
    return False, f"auto: convex disk without holes (hull/area {ratio:.2f} <= {CONCAVITY_THRESHOLD})"


def fill_surface(V: np.ndarray, F: np.ndarray, info: MeshInfo, method: str = "biharmonic", seed: int = 0,
                 depth: int = 0, conformal: Callable[[], np.ndarray] | None = None) -> FillResult:
    """Build M* with ``method`` (one of :data:`FILL_METHODS`); see :func:`poisson_fill`, :func:`biharmonic_fill`."""
    if method == "poisson":
        return poisson_fill(V, F, info, seed=seed, depth=depth, conformal=conformal)
    if method == "biharmonic":
        return biharmonic_fill(V, F, info, conformal=conformal)
    raise HeatparamError(f"fill method must be one of {', '.join(FILL_METHODS)}; got {method!r}")


# ----------------------------------------------------------------------------------------------------------
# the Poisson fill (the paper's)
# ----------------------------------------------------------------------------------------------------------
def auto_depth(info: MeshInfo) -> int:
    """Octree depth with a cell of about half of M's mean edge (PoissonRecon's cube is ~1.1x the bbox),
    clamped to MIN_DEPTH..MAX_DEPTH (6..9). Measured: a cell of one edge (depth 7 on the beetle) folds the
    beetle (113 flips) and leaves M up to ~1% of the diameter off M* (docs/fill.md)."""
    d = int(np.ceil(np.log2(1.1 * info.diameter / max(CELL_PER_EDGE * info.mean_edge, 1e-300))))
    return int(np.clip(d, MIN_DEPTH, MAX_DEPTH))


def oriented_samples(V: np.ndarray, F: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted random surface samples of M plus its vertices, with unit normals from the face orientation.

    Returns P (s,3), N (s,3). Vertex normals are area-weighted face normals.
    """
    import gpytoolbox as gpy

    n = int(np.clip(SAMPLES_PER_VERTEX * len(V), MIN_SAMPLES, MAX_SAMPLES))
    P, fi, _ = gpy.random_points_on_mesh(V, F, n, rng=np.random.default_rng(seed), return_indices=True)
    Nf = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    Nv = np.zeros_like(V)
    for c in range(3):
        np.add.at(Nv, F[:, c], Nf)
    Nf = Nf / (np.linalg.norm(Nf, axis=1, keepdims=True) + 1e-300)
    Nv = Nv / (np.linalg.norm(Nv, axis=1, keepdims=True) + 1e-300)
    return np.vstack([P, V]), np.vstack([Nf[fi], Nv])


def poisson_reconstruct(V: np.ndarray, F: np.ndarray, depth: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Screened Poisson surface (Eq. 15-16) of M's oriented samples, untrimmed. Returns (Vp (N,3), Fp (K,3))."""
    import gpytoolbox as gpy

    P, N = oriented_samples(V, F, seed)
    try:
        Vp, Fp = gpy.point_cloud_to_mesh(P, N, method="PSR", psr_depth=int(depth),
                                         psr_outer_boundary_type="Neumann")
    except (RuntimeError, ValueError, MemoryError) as exc:
        raise HeatparamError(f"the Poisson reconstruction (depth {depth}) failed: {str(exc).splitlines()[0]}"
                             " — try another fill_depth or fill='none'") from None
    Vp, Fp = np.asarray(Vp, dtype=np.float64), np.asarray(Fp, dtype=np.int64)
    if len(Fp) == 0:
        raise HeatparamError(f"the Poisson reconstruction (depth {depth}) produced no surface — try another "
                             "fill_depth or fill='none'")
    # Drop unreferenced vertices.
    used = np.unique(Fp)
    remap = np.full(len(Vp), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return Vp[used], remap[Fp]


def _face_maps(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Per face the (2,3) linear map taking a 3D offset in the face plane to the UV offset. (m,2,3)."""
    E = np.stack([V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]], axis=2)  # (m,3,2)
    Euv = np.stack([uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]], axis=2)  # (m,2,2)
    return Euv @ np.linalg.pinv(E)


def provisional_uv_of_points(P: np.ndarray, V: np.ndarray, F: np.ndarray, uv: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Provisional 2D position of 3D points P (p,3) near M: closest point on M, its UV, plus the tangent offset
    through that face's linear map. Returns (uvP (p,2), 3D distance to M (p,))."""
    d2, fi, C = igl.point_mesh_squared_distance(P, V, F)
    B = igl.barycentric_coordinates(C, V[F[fi, 0]], V[F[fi, 1]], V[F[fi, 2]])
    uvC = np.einsum("pc,pcd->pd", B, uv[F[fi]])
    A = _face_maps(V, F, uv)[fi]
    return uvC + np.einsum("pij,pj->pi", A, P - C), np.sqrt(np.maximum(d2, 0.0))


def _unit_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return N / (np.linalg.norm(N, axis=1, keepdims=True) + 1e-300)


def _largest_component_faces(F: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Mask of the faces of the largest edge-connected component among ``keep`` faces."""
    idx = np.flatnonzero(keep)
    if len(idx) == 0:
        return keep
    TT = _face_adjacency(F[idx])
    _, lab = connected_components(TT, directed=False)
    big = np.argmax(np.bincount(lab))
    out = np.zeros(len(F), dtype=bool)
    out[idx[lab == big]] = True
    return out


def _face_adjacency(F: np.ndarray) -> sp.csr_matrix:
    """(m,m) adjacency of faces sharing an edge."""
    m = len(F)
    he = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    fid = np.tile(np.arange(m), 3)
    _, inv = np.unique(he, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    s_inv, s_f = inv[order], fid[order]
    same = s_inv[1:] == s_inv[:-1]
    a, b = s_f[:-1][same], s_f[1:][same]
    return sp.csr_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(m, m))


def _fill_enclosed(F: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Re-admit rejected faces enclosed by kept ones: the trimmed patch gets no inner holes.

    A rejected component stays rejected when it reaches the border of (·, F) or is the largest one (the
    outside, when (·, F) is closed)."""
    rej = np.flatnonzero(~keep)
    if len(rej) == 0:
        return keep
    border_faces = np.zeros(len(F), dtype=bool)
    he = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, inv, cnt = np.unique(he, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    border_faces[np.tile(np.arange(len(F)), 3)[cnt[inv] == 1]] = True
    _, lab = connected_components(_face_adjacency(F[rej]), directed=False)
    touches = np.zeros(lab.max() + 1, dtype=bool)
    touches[lab[border_faces[rej]]] = True
    touches[np.argmax(np.bincount(lab))] = True  # the outside of a closed Poisson surface
    out = keep.copy()
    out[rej[~touches[lab]]] = True
    return out


def trim_to_hull(Vp: np.ndarray, Fp: np.ndarray, V: np.ndarray, F: np.ndarray, uv: np.ndarray,
                 near: float) -> tuple[np.ndarray, np.ndarray, dict]:
    """Trim an (open) Poisson surface (Vp, Fp) to the disk M* over the convex hull of M's provisional layout.

    Rule: give every vertex of (Vp, Fp) a provisional 2D position (:func:`provisional_uv_of_points`); keep the
    faces with a vertex inside the convex hull of ``uv`` (M's provisional layout, (n,2)) and all three within
    3D distance ``near`` of M, and whose normal agrees with M's at the closest point (dot > NORMAL_AGREEMENT);
    keep the largest edge-connected component; re-admit rejected faces enclosed by it (no inner holes).
    Returns (V* (N,3), F* (K,3), facts dict).
    """
    uvP, dist = provisional_uv_of_points(Vp, V, F, uv)
    hull = Delaunay(uv[ConvexHull(uv).vertices])
    in_hull = hull.find_simplex(uvP) >= 0
    keep = in_hull[Fp].any(axis=1) & (dist <= near)[Fp].all(axis=1)  # overlap the hull by one face: M ⊂ M*
    # Same side as M: PoissonRecon often closes the surface; its far side maps into the hull too.
    nP = _unit_normals(Vp, Fp)
    _, fi, _ = igl.point_mesh_squared_distance(Vp[Fp].mean(axis=1), V, F)
    agree = np.einsum("ij,ij->i", nP, _unit_normals(V, F)[fi]) > NORMAL_AGREEMENT
    keep &= agree
    keep = _largest_component_faces(Fp, keep)
    keep = _fill_enclosed(Fp, keep)
    keep = _largest_component_faces(Fp, keep)
    Fk = Fp[keep]
    used = np.unique(Fk)
    remap = np.full(len(Vp), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return Vp[used], remap[Fk], {"kept_faces": int(keep.sum()), "poisson_faces": int(len(Fp))}


def locate_points(P: np.ndarray, V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of P (p,3) on the mesh (V, F): face (p,) int64, bary (p,3) float64, distance (p,)."""
    d2, fi, C = igl.point_mesh_squared_distance(P, V, F)
    B = igl.barycentric_coordinates(C, V[F[fi, 0]], V[F[fi, 1]], V[F[fi, 2]])
    B = np.clip(np.nan_to_num(B, nan=1.0 / 3.0), 0.0, 1.0)
    B /= B.sum(axis=1, keepdims=True)
    return np.asarray(fi, dtype=np.int64), B, np.sqrt(np.maximum(d2, 0.0))


#: RMS distance to the best-fit plane, relative to the bounding-box diagonal, below which M counts as planar.
PLANAR_TOL = 1e-6


def poisson_fill(V: np.ndarray, F: np.ndarray, info: MeshInfo, seed: int = 0, depth: int = 0,
                 remesh: bool = True, conformal: Callable[[], np.ndarray] | None = None) -> FillResult:
    """The paper's fill: screened Poisson surface M* of M's oriented samples (Eq. 15-16), trimmed.

    Parameters
    ----------
    V : (n,3) float64, F : (m,3) int64 — the mesh M (validated, all vertices referenced).
    info : its :class:`heatparam.mesh.MeshInfo`. seed : the surface sampling.
    depth : octree depth of PoissonRecon (0 = :func:`auto_depth`, a cell of about half a mean edge).
    remesh : remesh M* to a uniform edge length of M's mean edge (gpytoolbox ``remesh_botsch``).
    conformal : the provisional layout, if already computed (see :func:`provisional_layout`).

    Returns
    -------
    FillResult with M* (one disk, one boundary loop) and each vertex of M located on it by closest point.

    Raises
    ------
    HeatparamError when the reconstruction or the trimming leaves nothing usable, or when M is planar.
    """
    c = V.mean(axis=0)
    thickness = np.linalg.svd(V - c, compute_uv=False)[-1] / np.sqrt(len(V))  # RMS distance to best-fit plane
    if thickness <= PLANAR_TOL * info.diameter:
        raise HeatparamError("the mesh is planar: the Poisson surface of a flat sheet is degenerate — "
                             "use fill='biharmonic' (or 'auto')")
    t0 = time.perf_counter()
    d = int(depth) if depth else auto_depth(info)
    Vp, Fp = poisson_reconstruct(V, F, d, seed)
    uv = provisional_layout(V, F, info, conformal)
    near = NEAR_FRACTION * info.diameter
    Vs, Fs, facts = trim_to_hull(Vp, Fp, V, F, uv, near)
    if len(Fs) < 10:
        raise HeatparamError(f"the Poisson fill (depth {d}) left no usable surface after trimming — "
                             "try fill='none' or another fill_depth")
    if remesh:
        import gpytoolbox as gpy

        Vs, Fs = gpy.remesh_botsch(Vs, Fs.astype(np.int32), i=10, h=info.mean_edge, project=True)
        Vs, Fs = np.asarray(Vs, dtype=np.float64), np.asarray(Fs, dtype=np.int64)
    face, bary, dist = locate_points(V, Vs, Fs)
    return _result(V, F, info, Vs, Fs, face, bary, dist, t0, {
        "method": "poisson",
        "depth": d,
        "samples": int(np.clip(SAMPLES_PER_VERTEX * len(V), MIN_SAMPLES, MAX_SAMPLES) + len(V)),
        "trim": {"rule": "provisional-layout convex hull, near M in 3D, normal agrees with M, largest component, "
                         "no inner holes",
                 "near_fraction_of_diameter": NEAR_FRACTION, "normal_agreement": NORMAL_AGREEMENT, **facts},
        "remeshed": bool(remesh),
    })


def _result(V, F, info, Vs, Fs, face, bary, dist, t0, extra) -> FillResult:
    warnings: list[str] = []
    loops = boundary_loops(Fs)
    diam = info.diameter
    ext = float(np.linalg.norm(Vs.max(0) - Vs.min(0)))
    report = {
        **extra,
        "vertices": int(len(Vs)),
        "faces": int(len(Fs)),
        "boundary_loops": int(len(loops)),
        "distance_max": float(dist.max()),
        "distance_mean": float(dist.mean()),
        "distance_max_rel": float(dist.max() / diam),
        "distance_mean_rel": float(dist.mean() / diam),
        "extent_rel": ext / diam,
        "area_rel": float(face_areas(Vs, Fs).sum() / info.area),
        "build_s": round(time.perf_counter() - t0, 3),
    }
    if len(loops) != 1:
        warnings.append(f"the fill surface M* has {len(loops)} boundary loops (expected 1); "
                        "geodesics may still bend around its gaps")
    if dist.max() > 0.02 * diam:
        warnings.append(f"the fill surface M* is up to {100 * dist.max() / diam:.1f}% of the diameter away from M")
    return FillResult(Vs, Fs, face, bary, report, warnings)


# ----------------------------------------------------------------------------------------------------------
# the biharmonic fill
# ----------------------------------------------------------------------------------------------------------
def _subdivide(P: np.ndarray, Q: np.ndarray, h: float) -> np.ndarray:
    """Points strictly between P (2,) and Q (2,) at spacing <= h. (k,2)."""
    k = int(np.ceil(np.linalg.norm(Q - P) / h - 1e-9))
    t = np.arange(1, k) / max(k, 1)
    return P + t[:, None] * (Q - P)


def _triangulate_region(poly: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Constrained Delaunay triangulation of a simple closed polygon (k,2) without splitting its edges,
    interior refined to edge length ~h. Returns (P (k+s,2) — the polygon's points first — and T (t,3))."""
    k = len(poly)
    E = np.column_stack([np.arange(k), (np.arange(k) + 1) % k])
    try:
        P2, T = triangulate(poly, E, max_area=0.5 * h * h, min_angle=np.deg2rad(25.0))
    except ValueError as exc:
        raise HeatparamError(f"triangulating a gap of the fill failed ({exc})") from exc
    if len(P2) < k or not np.allclose(P2[:k], poly):
        # Map the input points onto their output rows.
        d, j = _nearest(poly, P2)
        if d.max() > 1e-9 * (np.ptp(poly, axis=0).max() + 1e-300):
            raise HeatparamError("triangulating a gap of the fill failed (self-intersecting provisional layout)")
        order = np.r_[j, np.setdiff1d(np.arange(len(P2)), j)]
        inv = np.empty(len(P2), dtype=np.int64)
        inv[order] = np.arange(len(P2))
        P2, T = P2[order], inv[T]
    return P2, T


def _nearest(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from scipy.spatial import cKDTree

    return cKDTree(B).query(A)


def _gap_polygons(uv: np.ndarray, loops: list[np.ndarray], h: float, diameter: float = 0.0
                  ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The gaps of the hull of M's layout: (vertex ids of M on the polygon or -1 for new points, polygon (k,2)).

    Holes: the inner loops. Bays: between the outer loop and the convex hull, one per hull edge that skips
    border vertices and is deeper than MIN_BAY_DEPTH·h; the hull edge is subdivided at spacing h.
    """
    out = []
    for lp in loops[1:]:
        out.append((lp, uv[lp]))
    outer = loops[0]
    x, y = uv[outer, 0], uv[outer, 1]
    if 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        outer = outer[::-1]
    hv = np.sort(ConvexHull(uv[outer]).vertices)  # positions along the (ccw) outer loop
    n = len(outer)
    for a, b in zip(hv, np.roll(hv, -1), strict=True):
        span = (b - a) % n
        if span <= 1:
            continue
        ids = outer[(a + np.arange(span + 1)) % n]
        if _bay_depth(uv[ids]) < max(MIN_BAY_DEPTH * h, MIN_BAY_DEPTH_REL * diameter):
            continue  # a nearly straight stretch of border, not a concavity: leave it (and its slivers) out
        ids = _trim_bay_ends(uv, ids, MIN_BAY_DEPTH * h)
        extra = _subdivide(uv[ids[-1]], uv[ids[0]], h)
        out.append((np.r_[ids, np.full(len(extra), -1)], np.vstack([uv[ids], extra])))
    return out


def _trim_bay_ends(uv: np.ndarray, ids: np.ndarray, tol: float) -> np.ndarray:
    """Drop the ends of a bay's border chain that run along its hull edge (closer than ``tol``).

    Such a stretch would make the bay polygon a sliver of near-zero width along the hull edge, on which the
    constrained triangulation (without boundary splits) degenerates: a 34-point bay of a coarse cylinder with a
    notch took Triangle 38 s and 300k points. The new ends are the last chain points within ``tol`` of the hull
    edge, so the shortened chord stays within ``tol`` of the hull, outside M.
    """
    P = uv[ids]
    d = P[-1] - P[0]
    nrm = np.array([-d[1], d[0]]) / (np.linalg.norm(d) + 1e-300)
    far = np.flatnonzero(np.abs((P - P[0]) @ nrm) >= tol)
    if len(far) == 0:
        return ids
    return ids[max(far[0] - 1, 0) : min(far[-1] + 1, len(ids) - 1) + 1]


def _bay_depth(chain: np.ndarray) -> float:
    """Largest distance of the points of a border chain (k,2) from the segment joining its ends."""
    d = chain[-1] - chain[0]
    nrm = np.array([-d[1], d[0]]) / (np.linalg.norm(d) + 1e-300)
    return float(np.abs((chain - chain[0]) @ nrm).max())


def _bilaplacian_extend(X: np.ndarray, l_sq: np.ndarray, T: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Biharmonic extension of the rows of X (N,3) given at ``fixed`` (N,) bool: Δ² x = 0 at the free vertices.

    Δ is the intrinsic cotangent Laplacian of the triangles T (t,3) with squared half-edge lengths l_sq (t,3)
    (gpytoolbox convention), K = L M⁻¹ L with the Voronoi mass M. Returns (N,3).
    """
    import gpytoolbox as gpy

    n = len(X)
    L = gpy.cotangent_laplacian_intrinsic(l_sq, T, n=n)  # positive semidefinite
    Mv = gpy.massmatrix_intrinsic(l_sq, T, n=n, type="voronoi").diagonal()
    K = (L @ sp.diags(1.0 / np.maximum(Mv, 1e-300)) @ L).tocsr()
    free = np.flatnonzero(~fixed)
    fix = np.flatnonzero(fixed)
    out = X.copy()
    if len(free):
        Kff = K[free][:, free].tocsc()
        rhs = -(K[free][:, fix] @ X[fix])
        try:
            out[free] = spla.splu(Kff).solve(rhs)
        except RuntimeError:  # singular: a gap triangle degenerate
            raise HeatparamError("the biharmonic fill could not be solved (degenerate gap triangles)") from None
        if not np.isfinite(out).all():
            raise HeatparamError("the biharmonic fill produced non-finite positions (degenerate gap triangles)")
    return out


def _plane_frame(ids: np.ndarray, poly: np.ndarray, V: np.ndarray) -> np.ndarray:
    """The gap polygon drawn in the best-fit plane of its 3D outline (k,2), a second chance when its provisional
    layout self-intersects. New points (``ids == -1``, on the closing hull edge) are interpolated in 3D."""
    X = np.zeros((len(ids), 3))
    on = ids >= 0
    X[on] = V[ids[on]]
    if (~on).any():
        last = np.flatnonzero(on)[-1]
        a, b = poly[last], poly[0]
        t = np.linalg.norm(poly[~on] - a, axis=1) / max(np.linalg.norm(b - a), 1e-300)
        X[~on] = V[ids[last]] + t[:, None] * (V[ids[0]] - V[ids[last]])
    c = X.mean(axis=0)
    _, _, Wt = np.linalg.svd(X - c, full_matrices=False)
    return (X - c) @ Wt[:2].T


def _orient_gap(T: np.ndarray, P2: np.ndarray, ids: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Orient the gap triangles T (t,3) (indices into the polygon-first points P2) opposite to M along their
    shared border edge ids[0] -> ids[1], so M* is consistently oriented."""
    neg = signed_areas(P2, T) < 0
    T = T.copy()
    T[neg] = T[neg][:, ::-1]  # all counter-clockwise in their frame
    a, b = int(ids[0]), int(ids[1])
    m_has_ab = bool(((F == a) & (np.roll(F, -1, axis=1) == b)).any())
    g_has_ab = bool(((T == 0) & (np.roll(T, -1, axis=1) == 1)).any())
    return T[:, ::-1].copy() if m_has_ab == g_has_ab else T


def biharmonic_fill(V: np.ndarray, F: np.ndarray, info: MeshInfo,
                    conformal: Callable[[], np.ndarray] | None = None) -> FillResult:
    """M* = M plus its gaps, triangulated in M's provisional layout and lifted by a biharmonic extension.

    The region is the convex hull of M's provisional layout (as for :func:`poisson_fill`); its gaps are the
    holes and the bays between the outer border and the hull. Each gap is triangulated (constrained Delaunay,
    M's border edges kept, edge length ~ M's mean edge) in the provisional layout — or, if its outline
    self-intersects there, in the best-fit plane of its 3D outline — and its new vertices get 3D positions
    minimizing the Laplacian energy ∫|Δx|² (intrinsic cotangent Laplacian: M's triangles with their 3D lengths,
    gap triangles with the lengths of the frame they were made in) with every vertex of M fixed. M's triangles
    are kept as they are, so M ⊂ M* exactly (each vertex of M is a vertex of M*) and M* is one disk with one
    boundary loop.

    Parameters and returns as :func:`poisson_fill` (no depth: nothing is reconstructed).
    """
    t0 = time.perf_counter()
    n = len(V)
    uv = provisional_layout(V, F, info, conformal)
    h = info.mean_edge
    Fs, L, count, skipped, replanned = _gap_mesh(V, F, uv, info, h)
    fixed = np.zeros(count, dtype=bool)
    fixed[:n] = True
    X = np.zeros((count, 3))
    X[:n] = V
    Vs = _bilaplacian_extend(X, L, Fs, fixed)
    face, bary = _own_corners(F, n)
    res = _result(V, F, info, Vs, Fs, face, bary, np.zeros(n), t0, {
        "method": "biharmonic",
        "gaps_skipped": skipped,
        "gaps_in_own_plane": replanned,
        "depth": None,
        "gap_vertices": int(count - n),
        "trim": {"rule": "convex hull of the provisional (conformal) layout; gaps triangulated at M's mean edge",
                 "edge_length": h, "min_bay_depth_edges": MIN_BAY_DEPTH,
                 "min_bay_depth_diameter": MIN_BAY_DEPTH_REL},
    })
    if skipped:  # a note, not a warning: nothing for the user to do, and the map's own metrics say how it came out
        res.report["gaps_note"] = (f"{skipped} gap(s) of the fill could not be triangulated (their outline "
                                   "self-intersects in the provisional layout) and were left open: geodesics bend "
                                   "around them, which affects only the MDS start candidate, not the refined map")
    return res


def _triangulated_gap(ids: np.ndarray, poly: np.ndarray, V: np.ndarray, h: float
                      ) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """A gap's outline triangulated in the provisional layout, or else in the best-fit plane of its 3D outline:
    (points (p,2), triangles, whether in that plane); None where both self-intersect."""
    try:
        return (*_triangulate_region(poly, h), False)
    except (ValueError, HeatparamError):  # the outline self-intersects in the provisional layout
        try:
            return (*_triangulate_region(_plane_frame(ids, poly, V), h), True)
        except (ValueError, HeatparamError):
            return None


def _gap_mesh(V: np.ndarray, F: np.ndarray, uv: np.ndarray, info: MeshInfo, h: float
              ) -> tuple[np.ndarray, np.ndarray, int, int, int]:
    """M's triangles followed by its gaps' (the gaps' new vertices numbered from n on): (faces, their squared
    half-edge lengths (M's triangles: their 3D lengths; the gaps': in the frame they were made in), vertex count,
    gaps skipped, gaps triangulated in their own plane)."""
    import gpytoolbox as gpy

    Tall = [F]
    Lall = [gpy.halfedge_lengths_squared(V, F)]
    count = len(V)
    skipped = replanned = 0
    for ids, poly in _gap_polygons(uv, info.boundary_loops, h, info.diameter):
        gap = _triangulated_gap(ids, poly, V, h)
        if gap is None:
            skipped += 1
            continue
        P2, T, in_plane = gap
        replanned += in_plane
        T = _orient_gap(T, P2, ids, F)
        gid = np.empty(len(P2), dtype=np.int64)
        k = len(poly)
        on = ids >= 0
        gid[:k][on] = ids[on]
        new = np.r_[np.flatnonzero(~on), np.arange(k, len(P2))]
        gid[new] = count + np.arange(len(new))
        count += len(new)
        Tall.append(gid[T])
        Lall.append(gpy.halfedge_lengths_squared(P2, T))
    return np.vstack(Tall), np.vstack(Lall), count, skipped, replanned


def _own_corners(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Each vertex of M as a corner of one of M's faces (kept as faces 0..m-1 of M*): (face (n,), bary (n,3))."""
    face = np.empty(n, dtype=np.int64)
    bary = np.zeros((n, 3))
    for c in range(3):
        face[F[:, c]] = np.arange(len(F))
    corner = np.argmax(F[face] == np.arange(n)[:, None], axis=1)
    bary[np.arange(n), corner] = 1.0
    return face, bary
