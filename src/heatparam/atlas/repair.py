"""Lossless repair of scan-like input: non-manifold vertices and edges split, components separated.

Geometry is never changed and nothing is dropped: every face keeps its row and its three corners; only which
corners share a vertex id changes. Corners of the same input vertex are welded exactly across the edges that
are manifold and consistently oriented (two faces, opposite directions); everything else (edges of three or
more faces, edges whose two faces disagree on orientation, bowtie vertices whose face fans only touch at the
vertex) becomes boundary. Each edge-connected group of faces is one component, a clean oriented 2-manifold.
Vertices no face references ("loose points") are kept and reported.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from heatparam.errors import MeshError
from heatparam.mesh.topology import connected_labels, degenerate_faces, face_areas, sort_with_order, unique_inverse
from heatparam.mesh.validate import ALL_ZERO_AREA, check_arrays, check_edges, check_vertex_fans, edge_structure

__all__ = ["Component", "Repair", "half_edge_opposites", "repair", "union"]


@dataclass
class Component:
    """One clean piece of the input.

    V : (n_c,3) float64 vertex positions (copies of input vertices). F : (m_c,3) int64 triangles.
    faces : (m_c,) int64 input face row of each row of F. vertex : (n_c,) int64 input vertex of each row of V
    (a split non-manifold vertex appears once per fan). zero_area : (m_c,) bool, its zero-area faces
    (``mesh.topology.degenerate_faces``), when known.
    """

    V: np.ndarray
    F: np.ndarray
    faces: np.ndarray
    vertex: np.ndarray
    zero_area: np.ndarray | None = None

    @functools.cached_property
    def area(self) -> float:
        """Its 3D surface area, computed once."""
        return float(face_areas(self.V, self.F).sum())


@dataclass
class Repair:
    """What :func:`repair` found: the components (largest first) and counts for the report."""

    components: list[Component]
    split_vertices: int = 0  # input vertices that became more than one vertex
    cut_edges: int = 0  # input edges that were not welded although two or more faces use them
    loose_points: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # unreferenced vertices
    #: the input's zero-area faces (m,) and half-edge opposites (3m,) (:func:`half_edge_opposites`), for the report
    degenerate: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    opp: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def report(self) -> dict:
        return {
            "components": len(self.components),
            "component_faces": [int(len(c.F)) for c in self.components],
            "split_vertices": int(self.split_vertices),
            "non_manifold_or_inconsistent_edges_cut": int(self.cut_edges),
            "loose_points": int(len(self.loose_points)),
        }


def half_edge_opposites(F: np.ndarray) -> np.ndarray:
    """(3m,) int64: for half-edge ``h = 3 f + j`` (from F[f,j] to F[f,(j+1)%3]) the opposite half-edge of a
    manifold, consistently oriented edge, else -1."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    a = F.ravel()
    b = F[:, [1, 2, 0]].ravel()
    n = int(F.max()) + 1 if m else 1
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    ks, order = sort_with_order(lo * n + hi)
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    cnt = np.diff(np.r_[starts, len(ks)])
    opp = np.full(3 * m, -1, dtype=np.int64)
    two = starts[cnt == 2]
    h1, h2 = order[two], order[two + 1]
    ok = (a[h1] == b[h2]) & (b[h1] == a[h2]) & (a[h1] != b[h1])
    opp[h1[ok]] = h2[ok]
    opp[h2[ok]] = h1[ok]
    return opp


def repair(V: np.ndarray, F: np.ndarray) -> Repair:
    """Split the input into clean components without changing geometry (module docstring).

    Parameters
    ----------
    V : (n,3) float64. F : (m,3) int64.

    Returns
    -------
    :class:`Repair`. Each component passes ``heatparam.mesh.validate_mesh(..., flatten=False)`` (one
    connected, oriented manifold; a component of zero-area faces only has no area to check).

    Raises
    ------
    MeshError for what no split repairs (NaN coordinates, indices out of range, faces repeating a vertex).
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    check_arrays(V, F)  # (a face repeating a vertex would become a proper triangle once its corners are split)
    n, m = len(V), len(F)
    degenerate = degenerate_faces(V, F)
    if degenerate.all():
        raise MeshError(ALL_ZERO_AREA)
    opp = half_edge_opposites(F)
    cls, cls_vertex, fcomp, ncomp = _weld(F, opp)
    per_vertex = np.bincount(cls_vertex, minlength=n)
    referenced = np.zeros(n, dtype=bool)
    referenced[F.ravel()] = True
    C = cls.reshape(m, 3)
    # the components side by side are (V[cls_vertex], C), connected each by construction; the other checks are
    # local, so one pass over them all checks each
    edges = edge_structure(C)
    check_edges(edges)
    check_vertex_fans(C, edges)
    comps = _components(V, C, cls_vertex, fcomp, ncomp, degenerate)
    split = int((per_vertex > 1).sum())
    return Repair(components=comps, split_vertices=split, cut_edges=_unwelded_edges(F, opp, n),
                  loose_points=np.flatnonzero(~referenced), degenerate=degenerate, opp=opp)


def _components(V: np.ndarray, C: np.ndarray, cls_vertex: np.ndarray, fcomp: np.ndarray, ncomp: int,
                degenerate: np.ndarray) -> list[Component]:
    """The components, largest first (ties: in component order): each one's faces ascending and its vertices in
    welded-vertex order (``C`` (m,3) the welded vertex of each corner, ``cls_vertex`` the input vertex of each;
    ``degenerate`` (m,) the zero-area faces)."""
    sizes = np.bincount(fcomp, minlength=ncomp)
    rank = np.empty(ncomp, dtype=np.int64)
    rank[np.argsort(-sizes, kind="stable")] = np.arange(ncomp)  # each component's place in the output
    forder = np.argsort(rank[fcomp], kind="stable")
    fstart = np.r_[0, np.cumsum(np.bincount(rank[fcomp], minlength=ncomp))]
    nv = len(cls_vertex)
    vcomp = np.empty(nv, dtype=np.int64)
    vcomp[C.ravel()] = np.repeat(rank[fcomp], 3)
    vorder = np.argsort(vcomp, kind="stable")  # by component, welded vertices ascending within each
    vstart = np.r_[0, np.cumsum(np.bincount(vcomp, minlength=ncomp))]
    local = np.empty(nv, dtype=np.int64)
    local[vorder] = np.arange(nv) - vstart[vcomp[vorder]]
    comps = []
    for c in range(ncomp):
        faces = forder[fstart[c]:fstart[c + 1]]
        vin = cls_vertex[vorder[vstart[c]:vstart[c + 1]]]
        comps.append(Component(V=V[vin], F=local[C[faces]], faces=faces, vertex=vin, zero_area=degenerate[faces]))
    return comps


def _weld(F: np.ndarray, opp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Corners c = 3 f + j of the same vertex glued across every welded half-edge pair: (the new vertex of each
    corner (3m,), numbered by first corner; the input vertex of each new vertex; the component of each face
    (edge-connected through welded edges); the number of components)."""
    m = len(F)
    h = np.flatnonzero(opp >= 0)
    o = opp[h]
    f, j = h // 3, h % 3
    g, k = o // 3, o % 3
    r = np.concatenate([3 * f + j, 3 * f + (j + 1) % 3])
    c = np.concatenate([3 * g + (k + 1) % 3, 3 * g + k])
    _, label = connected_labels(3 * m, r, c)
    ncomp, fcomp = connected_labels(m, f, g)
    uniq, first, inv = unique_inverse(label)
    new_id = np.empty(len(uniq), dtype=np.int64)
    new_id[np.argsort(first, kind="stable")] = np.arange(len(uniq))
    cls = new_id[inv]
    cls_vertex = np.empty(len(uniq), dtype=np.int64)
    cls_vertex[cls] = F.ravel()
    return cls, cls_vertex, fcomp, ncomp


def _unwelded_edges(F: np.ndarray, opp: np.ndarray, n: int) -> int:
    """Input edges used by two or more faces but not welded (non-manifold, or inconsistently oriented)."""
    a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
    _, _, inv = unique_inverse(np.minimum(a, b) * n + np.maximum(a, b))
    return int(((np.bincount(inv) >= 2) & (np.bincount(inv, weights=opp >= 0) == 0)).sum())


def union(parts: list[Component], ids: list[int]) -> tuple[Component, np.ndarray]:
    """Several components as one (their disjoint union) and the component id (from ``ids``) of each of its faces."""
    offs = np.cumsum([0] + [len(c.V) for c in parts])
    F = np.vstack([c.F + o for c, o in zip(parts, offs[:-1], strict=True)])
    known = all(c.zero_area is not None for c in parts)
    comp = Component(np.vstack([c.V for c in parts]), F, np.concatenate([c.faces for c in parts]),
                     np.concatenate([c.vertex for c in parts]),
                     np.concatenate([c.zero_area for c in parts]) if known else None)
    return comp, np.repeat(np.asarray(ids, dtype=np.int64), [len(c.F) for c in parts])
