"""Mesh validation at the door (paper §2: M is a connected 2-manifold with border).

Everything downstream trusts a mesh that passed :func:`validate_mesh`. Each check is its own function, raising
:class:`~heatparam.errors.MeshError` with one line that says what is wrong and what to do.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from heatparam.errors import MeshError, TopologyError
from heatparam.mesh.topology import (
    connected_labels,
    face_areas,
    loop_length,
    loops_outer_first,
    repeated_vertex_faces,
    sort_with_order,
    zero_area,
)

#: Outer border length² / area below which a surface counts as nearly closed. A flat disk has 4π ≈ 12.6, a
#: hemisphere 2π ≈ 6.3, the strongly curved camelhead.off 1.0, stanford-bunny.obj (a sphere with 5 small holes) 0.23.
NEARLY_CLOSED_RATIO = 0.5


#: the refusal of a mesh without area (the validation's and the atlas repair's)
ALL_ZERO_AREA = ("all faces have zero area (collinear or coincident corners): there is no surface to flatten — check "
                 "the file's export")


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

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> info = validate_mesh(V, np.array([[0, 1, 2], [1, 3, 2]]))
    >>> info.n_holes, len(info.boundary_loops[0])
    (0, 4)
    """
    V, F = check_arrays(V, F)
    edges = edge_structure(F)
    check_edges(edges)
    referenced = np.zeros(len(V), dtype=bool)
    referenced[F.ravel()] = True
    check_vertex_fans(F, edges)
    check_connected(edges, referenced)
    loops = loops_outer_first(V, F) if edges.n_boundary else []
    if flatten:
        check_flattenable(edges, referenced, loops, len(F))
    info = _facts(V, F, edges, referenced, loops)
    if flatten:
        check_not_nearly_closed(V, info)
    return info


def as_arrays(V, F) -> tuple[np.ndarray, np.ndarray]:
    """The input as contiguous V float64 and F int64 (no copy where it is so already), or a one-line MeshError:
    coordinates that are not numbers, face indices that are not whole numbers (a cast would truncate 1.5 to 1)."""
    try:
        V = np.ascontiguousarray(V, dtype=np.float64)
    except (TypeError, ValueError):
        raise MeshError("the vertex coordinates are not numbers — pass an (n,3) array of floats") from None
    try:
        Fa = np.asarray(F)
        if Fa.dtype.kind in "fc" and not np.array_equal(Fa, np.round(Fa.real)):
            raise ValueError
        return V, np.ascontiguousarray(Fa, dtype=np.int64)
    except (TypeError, ValueError, OverflowError):
        raise MeshError("the face indices are not whole numbers — pass an (m,3) array of vertex indices") from None


def check_arrays(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shapes, finite coordinates, indices in range, no face repeating a vertex."""
    V = np.asarray(V)
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) < 3:
        raise MeshError(f"expected at least 3 vertices with 3 coordinates, got array of shape {V.shape}")
    if F.ndim == 2 and F.shape[1] != 3 and len(F):
        raise MeshError(f"faces must be triangles, an (m,3) array; got shape {F.shape} — triangulate them first")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise MeshError("the mesh has no triangles — check that the file holds faces, not only points")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        raise MeshError(
            f"{int(bad.sum())} vertices have NaN or infinite coordinates (first: vertex {int(np.argmax(bad))})"
            " — repair or remove them"
        )
    n = len(V)
    if F.min() < 0 or F.max() >= n:
        raise MeshError(
            f"face indices out of range (found {int(F.min())}..{int(F.max())} for {n} vertices) — the file is corrupt"
        )
    rep = repeated_vertex_faces(F)
    if rep.any():
        raise MeshError(
            f"{int(rep.sum())} faces repeat a vertex index (first: face {int(np.argmax(rep))})"
            " — remove degenerate faces first"
        )
    return V, F


class Edges(NamedTuple):
    """Half-edges of F grouped by undirected edge. he (3m,2): half-edge h belongs to face h % m; order: the
    half-edges sorted by edge; starts: where each edge's group begins in ``order``; count: faces per edge."""

    he: np.ndarray
    order: np.ndarray
    starts: np.ndarray
    count: np.ndarray
    n: int
    m: int

    @property
    def n_boundary(self) -> int:
        return int((self.count == 1).sum())

    @property
    def interior_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The two half-edges (h1, h2) of each interior edge."""
        pair = self.starts[self.count == 2]
        return self.order[pair], self.order[pair + 1]


def edge_structure(F: np.ndarray) -> Edges:
    """Group the half-edges of F (m,3) by undirected edge (int64 edge keys, one stable sort)."""
    n, m = int(F.max()) + 1, len(F)
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    lo, hi = he.min(axis=1), he.max(axis=1)
    ukey = lo * n + hi
    sk, order = sort_with_order(ukey)
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    count = np.diff(np.r_[starts, len(sk)])
    return Edges(he, order, starts, count, n, m)


def check_edges(edges: Edges) -> None:
    """Manifold edges (at most two faces) and consistent orientation (the two half-edges run opposite ways)."""
    if (edges.count > 2).any():
        raise TopologyError(
            f"{int((edges.count > 2).sum())} non-manifold edges (shared by more than two faces)",
            "repair the mesh (split non-manifold edges, remove duplicate faces) first"
        )
    h1, h2 = edges.interior_pairs
    same_way = int((edges.he[h1, 0] == edges.he[h2, 0]).sum())
    if same_way:
        raise TopologyError(
            f"{same_way} edges run the same way in both of their faces: the faces are inconsistently"
            " oriented (or the surface is non-orientable)", "reorient the faces first"
        )


def check_vertex_fans(F: np.ndarray, edges: Edges) -> None:
    """Vertex manifoldness: the face corners at a vertex must form one fan.

    Corners (face, vertex) of two faces sharing an edge are linked at both ends of the edge; each vertex must own
    one linked group. Half-edge h = c·m + f runs from corner c of face f to corner (c+1)%3; its twin (opposite
    direction, checked by :func:`check_edges`) from corner c2 of f2 to (c2+1)%3: so the edge's first end sits at
    corners c1 of f1 and (c2+1)%3 of f2, its second end at (c1+1)%3 of f1 and c2 of f2.
    """
    m = edges.m
    h1, h2 = edges.interior_pairs
    f1, c1 = h1 % m, h1 // m
    f2, c2 = h2 % m, h2 // m
    r = np.concatenate([3 * f1 + c1, 3 * f1 + (c1 + 1) % 3])
    c = np.concatenate([3 * f2 + (c2 + 1) % 3, 3 * f2 + c2])
    fans, comp = connected_labels(3 * m, r, c)
    # a fan's corners all sit at one vertex (its edges run opposite ways: check_edges), so any of them names it
    fan_vertex = np.empty(fans, dtype=np.int64)
    fan_vertex[comp] = F.ravel()
    nonman_v = np.bincount(fan_vertex) > 1
    if nonman_v.any():
        raise TopologyError(
            f"{int(nonman_v.sum())} non-manifold vertices (faces meeting at a single vertex, first: vertex "
            f"{int(np.argmax(nonman_v))})", "split them or remove the extra fans first"
        )


def check_connected(edges: Edges, referenced: np.ndarray) -> None:
    """One connected component (over faces sharing a vertex = the edge graph on the referenced vertices)."""
    n = len(referenced)
    e = edges.order[edges.starts]  # one half-edge per edge
    ncomp, _ = connected_labels(n, edges.he[e, 0], edges.he[e, 1])
    ncomp -= n - int(referenced.sum())
    if ncomp > 1:
        raise TopologyError(
            f"the mesh has {ncomp} connected components", "split it and parameterize each part separately"
        )


def check_flattenable(edges: Edges, referenced: np.ndarray, loops: list[np.ndarray], m: int) -> None:
    """A border (not closed) and no handles (genus 0: Euler characteristic 2 − loops)."""
    if edges.n_boundary == 0:
        raise TopologyError("closed mesh", "cut it open first (it has no boundary, so it cannot be flattened)")
    chi = int(referenced.sum()) - len(edges.starts) + m
    genus2 = 2 - len(loops) - chi
    if genus2 > 0:
        raise TopologyError(
            f"the surface has {genus2 // 2 or 1} handle(s) (genus > 0)", "cut it into a disk (with holes) first"
        )


def _facts(V: np.ndarray, F: np.ndarray, edges: Edges, referenced: np.ndarray, loops: list[np.ndarray]
           ) -> MeshInfo:
    """Areas, edge lengths, size; non-fatal findings as warnings."""
    areas = face_areas(V, F)
    lengths = np.linalg.norm(V[edges.he[:, 0]] - V[edges.he[:, 1]], axis=1)
    longest2 = np.max(lengths.reshape(3, -1), axis=0) ** 2
    info = MeshInfo(
        n_vertices=len(V),
        n_faces=len(F),
        referenced=referenced,
        boundary_loops=loops,
        zero_area_faces=int(zero_area(2 * areas, longest2, V, F).sum()),
        area=float(areas.sum()),
        mean_edge=float(lengths.mean()),
        max_edge=float(lengths.max()),
        diameter=float(np.linalg.norm(V[referenced].max(0) - V[referenced].min(0))),
    )
    if info.area <= 0:
        raise MeshError(ALL_ZERO_AREA)
    if info.n_unreferenced:
        info.warnings.append(
            f"{info.n_unreferenced} unreferenced vertices kept in the output at the layout's centroid"
        )
    if info.zero_area_faces:
        info.warnings.append(
            f"{info.zero_area_faces} zero-area faces handled by intrinsic mollification of edge lengths"
        )
    return info


def check_not_nearly_closed(V: np.ndarray, info: MeshInfo) -> None:
    """Nearly closed surfaces (a sphere with small holes) have an outer border that is short compared with the
    size of the surface: no flat layout of them has low distortion."""
    loops = info.boundary_loops
    closure = loop_length(V, loops[0]) ** 2 / info.area if loops else 0.0
    if closure < NEARLY_CLOSED_RATIO:
        raise TopologyError(
            f"nearly closed surface (outer border length²/area = {closure:.2f} < {NEARLY_CLOSED_RATIO}): it "
            "wraps around and cannot be flattened without huge distortion", "cut it open or segment it first"
        )
