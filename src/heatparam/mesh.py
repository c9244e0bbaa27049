"""Mesh validation and topology, at the door (paper §2: M is a connected 2-manifold with border).

Everything downstream trusts a mesh that passed :func:`validate_mesh`. No file formats here (see ``io``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from heatparam.errors import MeshError


@dataclass
class MeshInfo:
    """Facts about a validated mesh (all counts refer to the input arrays)."""

    n_vertices: int
    n_faces: int
    referenced: np.ndarray  # (n,) bool: vertex is used by a face
    boundary_loops: list[np.ndarray]  # vertex loops, the longest (outer border) first
    zero_area_faces: int
    area: float
    mean_edge: float
    max_edge: float
    diameter: float  # bounding-box diagonal
    warnings: list[str] = field(default_factory=list)

    @property
    def n_unreferenced(self) -> int:
        return int((~self.referenced).sum())

    @property
    def n_holes(self) -> int:
        return max(len(self.boundary_loops) - 1, 0)

    def as_dict(self) -> dict:
        return {
            "vertices": self.n_vertices,
            "faces": self.n_faces,
            "unreferenced_vertices": self.n_unreferenced,
            "boundary_loops": len(self.boundary_loops),
            "holes": self.n_holes,
            "zero_area_faces": self.zero_area_faces,
            "area": self.area,
            "mean_edge_length": self.mean_edge,
            "max_edge_length": self.max_edge,
            "bbox_diagonal": self.diameter,
        }


def face_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Triangle areas, (m,) float64."""
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def boundary_loops(V: np.ndarray, F: np.ndarray) -> list[np.ndarray]:
    """Ordered boundary vertex loops of a manifold mesh, sorted by 3D length, longest (outer border) first."""
    loops = [np.asarray(lp, dtype=np.int64) for lp in igl.boundary_loop_all(F)]
    lengths = [np.linalg.norm(V[lp] - V[np.roll(lp, -1)], axis=1).sum() for lp in loops]
    order = np.argsort(lengths)[::-1]
    return [loops[i] for i in order]


def loop_length(V: np.ndarray, loop: np.ndarray) -> float:
    """Length of a closed vertex loop in 3D."""
    return float(np.linalg.norm(V[loop] - V[np.roll(loop, -1)], axis=1).sum())


def unique_edges(F: np.ndarray) -> np.ndarray:
    """(e,2) int64: every edge of the triangles once, as (smaller, larger) vertex index, sorted."""
    return np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)


def validate_mesh(V: np.ndarray, F: np.ndarray, flatten: bool = True) -> MeshInfo:
    """Check that (V, F) is a single connected, orientable 2-manifold disk (possibly with holes).

    Parameters
    ----------
    V : (n,3) float64 vertex positions.
    F : (m,3) int64 triangle indices.
    flatten : True (default) also refuses what cannot be flattened: closed surfaces, handles, nearly closed
        surfaces. False keeps only the checks that surface operators need (finite, manifold, oriented, one
        component, not degenerate), e.g. for geodesic distances on a closed scan.

    Returns
    -------
    MeshInfo, with non-fatal findings in ``warnings`` (unreferenced vertices, zero-area faces).

    Raises
    ------
    MeshError with a one-line message naming the problem and what to do.
    """
    V = np.asarray(V)
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) < 3:
        raise MeshError(f"expected at least 3 vertices with 3 coordinates, got array of shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise MeshError("the mesh has no triangles — check that the file holds faces, not only points")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        raise MeshError(
            f"{int(bad.sum())} vertices have NaN or infinite coordinates (first: vertex {int(np.argmax(bad))})"
            " — repair or remove them"
        )
    n, m = len(V), len(F)
    if F.min() < 0 or F.max() >= n:
        raise MeshError(
            f"face indices out of range (found {int(F.min())}..{int(F.max())} for {n} vertices) — the file is corrupt"
        )
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    if rep.any():
        raise MeshError(
            f"{int(rep.sum())} faces repeat a vertex index (first: face {int(np.argmax(rep))})"
            " — remove degenerate faces first"
        )

    # Edges: non-manifold (>2 faces) and orientation (a directed edge used twice), on int64 edge keys.
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # half-edge h belongs to face h % m
    lo, hi = he.min(axis=1), he.max(axis=1)
    ukey = lo * n + hi
    order = np.argsort(ukey, kind="stable")
    sk = ukey[order]
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    cnt_u = np.diff(np.r_[starts, len(sk)])
    if (cnt_u > 2).any():
        raise MeshError(
            f"{int((cnt_u > 2).sum())} non-manifold edges (shared by more than two faces)"
            " — repair the mesh (split non-manifold edges, remove duplicate faces) first"
        )
    # A directed edge used twice: the two half-edges of an interior edge run the same way.
    pair = starts[cnt_u == 2]
    h1, h2 = order[pair], order[pair + 1]  # the two half-edges of each interior edge
    same_way = int((he[h1, 0] == he[h2, 0]).sum())
    if same_way:
        raise MeshError(
            f"{same_way} edges run the same way in both of their faces: the faces are inconsistently"
            " oriented (or the surface is non-orientable) — reorient the faces first"
        )
    referenced = np.zeros(n, dtype=bool)
    referenced[F.ravel()] = True
    # Vertex manifoldness: the face corners at a vertex must form one fan. Corners (face, vertex) of two
    # faces sharing an edge are linked at both ends of the edge; each vertex must own one linked group.
    # Half-edge h = c·m + f runs from corner c of face f to corner (c+1)%3; its twin (opposite direction, as
    # checked above) from corner c2 of f2 to (c2+1)%3: so the edge's first end sits at corners c1 of f1 and
    # (c2+1)%3 of f2, its second end at (c1+1)%3 of f1 and c2 of f2.
    f1, c1 = h1 % m, h1 // m
    f2, c2 = h2 % m, h2 // m
    r = np.concatenate([3 * f1 + c1, 3 * f1 + (c1 + 1) % 3])
    c = np.concatenate([3 * f2 + (c2 + 1) % 3, 3 * f2 + c2])
    graph = sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(3 * m, 3 * m))
    _, comp = connected_components(graph, directed=False)
    fans = np.unique(F.ravel() * (3 * m) + comp)  # distinct (vertex, corner group) pairs
    fans_per_vertex = np.bincount(fans // (3 * m), minlength=n)
    nonman_v = fans_per_vertex > 1
    if nonman_v.any():
        raise MeshError(
            f"{int(nonman_v.sum())} non-manifold vertices (faces meeting at a single vertex, first: vertex "
            f"{int(np.argmax(nonman_v))}) — split them or remove the extra fans first"
        )

    # Connected components over faces sharing a vertex = components of the edge graph on the referenced
    # vertices (each face links its three vertices by its edges); unreferenced vertices are isolated.
    e = order[starts]  # one half-edge per edge
    edges = sp.csr_matrix((np.ones(len(e)), (he[e, 0], he[e, 1])), shape=(n, n))
    ncomp, _ = connected_components(edges, directed=False)
    ncomp -= n - int(referenced.sum())
    if ncomp > 1:
        raise MeshError(
            f"the mesh has {ncomp} connected components — split it and parameterize each part separately"
        )

    n_boundary_edges = int((cnt_u == 1).sum())
    if n_boundary_edges == 0 and flatten:
        raise MeshError("closed mesh — cut it open first (it has no boundary, so it cannot be flattened)")
    loops = boundary_loops(V, F) if n_boundary_edges else []
    n_edges = len(starts)
    chi = int(referenced.sum()) - n_edges + m
    genus2 = 2 - len(loops) - chi
    if genus2 > 0 and flatten:
        raise MeshError(
            f"the surface has {genus2 // 2 or 1} handle(s) (genus > 0) — cut it into a disk (with holes) first"
        )

    areas = face_areas(V, F)
    lengths = np.linalg.norm(V[he[:, 0]] - V[he[:, 1]], axis=1)
    mean_edge = float(lengths.mean())
    zero = areas <= 1e-12 * mean_edge**2
    info = MeshInfo(
        n_vertices=n,
        n_faces=m,
        referenced=referenced,
        boundary_loops=loops,
        zero_area_faces=int(zero.sum()),
        area=float(areas.sum()),
        mean_edge=mean_edge,
        max_edge=float(lengths.max()),
        diameter=float(np.linalg.norm(V[referenced].max(0) - V[referenced].min(0))),
    )
    if info.area <= 0:
        raise MeshError("all faces have zero area — the mesh is degenerate")
    if info.n_unreferenced:
        info.warnings.append(
            f"{info.n_unreferenced} unreferenced vertices kept in the output at the layout's centroid"
        )
    if info.zero_area_faces:
        info.warnings.append(
            f"{info.zero_area_faces} zero-area faces handled by intrinsic mollification of edge lengths"
        )
    # Nearly closed surfaces (a sphere with small holes) have an outer border that is short compared
    # with the size of the surface: no flat layout of them has low distortion.
    closure = loop_length(V, loops[0]) ** 2 / info.area if loops else 0.0
    if closure < NEARLY_CLOSED_RATIO and flatten:
        raise MeshError(
            f"nearly closed surface (outer border length²/area = {closure:.2f} < {NEARLY_CLOSED_RATIO}): it "
            "wraps around and cannot be flattened without huge distortion — cut it open or segment it first"
        )
    return info


#: Outer border length² / area below which a surface counts as nearly closed. A flat disk has 4π ≈ 12.6, a
#: hemisphere 2π ≈ 6.3, the strongly curved camelhead.off 1.0, stanford-bunny.obj (a sphere with 5 small holes) 0.23.
NEARLY_CLOSED_RATIO = 0.5


# ----------------------------------------------------------------------------------------------------------
# seams: cutting holes open to the border
# ----------------------------------------------------------------------------------------------------------
def edge_graph(F: np.ndarray, lengths: np.ndarray, n: int) -> sp.csr_matrix:
    """The mesh's edge graph as a sparse (n, n) matrix of edge lengths, one direction per half-edge (use
    ``directed=False`` in ``scipy.sparse.csgraph``). lengths : (m,3), column c the edge opposite corner c."""
    E = np.concatenate([F[:, [1, 2]], F[:, [2, 0]], F[:, [0, 1]]])
    return sp.csr_matrix((np.asarray(lengths).T.ravel(), (E[:, 0], E[:, 1])), shape=(n, n))


def hole_seams(V: np.ndarray, F: np.ndarray, loops: list[np.ndarray]) -> list[np.ndarray]:
    """Shortest edge paths on the surface that join every hole to the border: a minimum spanning tree of the
    boundary loops under surface distance.

    One multi-source Dijkstra from all boundary vertices splits the surface into the loops' regions (a Voronoi
    diagram of the loops); every edge between two regions offers a path loop → edge → loop of length
    d(u) + |uv| + d(v), and the minimum spanning tree of the loops over the shortest such offers (Mehlhorn's
    construction) picks ``len(loops) - 1`` of them. Cutting along them (:func:`cut_open`) leaves a disk.
    Each path runs through interior vertices only, between its two end vertices on different loops.

    Parameters
    ----------
    V : (n,3) float64. F : (m,3) int64. loops : boundary vertex loops (e.g. ``MeshInfo.boundary_loops``).

    Returns
    -------
    list of (k_i,) int64 vertex paths, shortest first (empty when there is a single loop).
    """
    from scipy.sparse.csgraph import dijkstra, minimum_spanning_tree

    if len(loops) < 2:
        return []
    n = len(V)
    graph = edge_graph(F, igl.edge_lengths(V, F), n)  # column c: the edge opposite corner c
    owner = np.full(n, -1, dtype=np.int64)
    for i, lp in enumerate(loops):
        owner[lp] = i
    bnd = np.flatnonzero(owner >= 0)
    dist, pred, src = dijkstra(graph, directed=False, indices=bnd, min_only=True, return_predecessors=True)
    region = np.where(src >= 0, owner[np.maximum(src, 0)], -1)
    E = unique_edges(F)
    u, v = E[:, 0], E[:, 1]
    across = (region[u] != region[v]) & (region[u] >= 0) & (region[v] >= 0)
    u, v = u[across], v[across]
    cost = dist[u] + np.linalg.norm(V[u] - V[v], axis=1) + dist[v]
    a, b = np.minimum(region[u], region[v]), np.maximum(region[u], region[v])
    L = len(loops)
    order = np.lexsort((cost, b, a))  # per loop pair, the cheapest edge first
    pair = a[order] * L + b[order]
    first = order[np.r_[True, pair[1:] != pair[:-1]]]
    # the MST needs positive weights; a tie at 0 (an edge between two loops' vertices has length > 0) cannot occur
    offers = sp.csr_matrix((cost[first], (a[first], b[first])), shape=(L, L))
    tree = minimum_spanning_tree(offers).tocoo()
    chosen = {(int(min(r, c)), int(max(r, c))) for r, c in zip(tree.row, tree.col, strict=True)}
    paths = []
    for e in first:
        if (int(a[e]), int(b[e])) not in chosen:
            continue
        paths.append((float(cost[e]), np.array(_back(pred, u[e])[::-1] + _back(pred, v[e]), dtype=np.int64)))
    paths.sort(key=lambda p: p[0])
    return [p for _, p in paths]


def _back(pred: np.ndarray, v: int) -> list[int]:
    """The vertices from v back to its Dijkstra source (v first)."""
    out = [int(v)]
    while pred[out[-1]] >= 0:
        out.append(int(pred[out[-1]]))
    return out


def cut_open(V: np.ndarray, F: np.ndarray, paths: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut the mesh along vertex paths (``igl.cut_mesh``): every vertex on a path is split into one copy per side.

    Returns
    -------
    Vs : (n_s,3) float64, the vertices with path vertices duplicated. Fs : (m,3) int64, F row for row, corners
    redirected to the copies. source : (n_s,) int64, the input vertex of each row of Vs.
    """
    n = len(V)
    if not paths:
        return V.copy(), F.copy(), np.arange(n, dtype=np.int64)
    P = np.concatenate([np.stack([p[:-1], p[1:]], axis=1) for p in paths])
    cut_keys = np.minimum(P[:, 0], P[:, 1]) * n + np.maximum(P[:, 0], P[:, 1])
    C = np.zeros(F.shape, dtype=bool)
    for j in range(3):
        a, b = F[:, j], F[:, (j + 1) % 3]
        C[:, j] = np.isin(np.minimum(a, b) * n + np.maximum(a, b), cut_keys)
    Vs, Fs, source = igl.cut_mesh(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64),
                                  C)
    return np.asarray(Vs), np.asarray(Fs, dtype=np.int64), np.asarray(source, dtype=np.int64)
