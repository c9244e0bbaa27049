"""A Blender mesh as heatparam's triangles and heatparam's UVs back into its face corners (loops), with NumPy over
``foreach_get`` / ``foreach_set`` (no per-element Python).

heatparam takes no list of cuts (its ``seams`` option cuts holes open, nothing else), so the edges the user marked
as seams are cut here: a vertex gets one copy per fan of face corners that the marked edges separate around it
(:func:`corner_vertices`), and heatparam sees the cut as mesh border. Quads and n-gons go to heatparam as Blender's
own triangulation (``loop_triangles``); each triangle corner's UV goes back to the loop it came from.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


def _get(collection, attr: str, dtype, width: int = 1) -> np.ndarray:
    out = np.empty(len(collection) * width, dtype=dtype)
    collection.foreach_get(attr, out)
    return out.reshape(-1, width) if width > 1 else out


class Loops(NamedTuple):
    """A mesh's face corners: vertex (L,) and edge (L,) of each loop, the loop after it in its face (L,), the
    polygon of each loop (L,)."""

    vertex: np.ndarray
    edge: np.ndarray
    next: np.ndarray
    polygon: np.ndarray

    @classmethod
    def of(cls, mesh) -> Loops:
        start = _get(mesh.polygons, "loop_start", np.int64)
        total = _get(mesh.polygons, "loop_total", np.int64)
        poly = np.repeat(np.arange(len(start)), total)
        first = start[poly]
        nxt = first + (np.arange(len(poly)) - first + 1) % total[poly]
        return cls(_get(mesh.loops, "vertex_index", np.int64), _get(mesh.loops, "edge_index", np.int64), nxt, poly)

    def edge_ends(self, chosen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each chosen loop's edge seen from both of its ends: key (2k,) = edge × n + end vertex, and the loop at
        that end (2k,). Loops with one key meet at that vertex across that edge."""
        lp = np.flatnonzero(chosen)
        ends = np.concatenate([lp, self.next[lp]])
        edges = np.concatenate([self.edge[lp], self.edge[lp]])
        return edges * self.vertex_count + self.vertex[ends], ends

    @property
    def vertex_count(self) -> int:
        """One more than the largest vertex index (the keys' base)."""
        return int(self.vertex.max()) + 1 if len(self.vertex) else 1


def _same_key_pairs(key: np.ndarray, loop: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (a, b) of loops that share a key (each loop with the first one of its key) and that key."""
    order = np.argsort(key, kind="stable")
    k, lp = key[order], loop[order]
    new = np.ones(len(k), dtype=bool)
    new[1:] = k[1:] != k[:-1]
    first = lp[np.flatnonzero(new)[np.cumsum(new) - 1]]
    return first[~new], lp[~new], k[~new]


def _components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) the smallest member of each element's connected component under the pairs (a, b) (label propagation
    with pointer jumping; fans around a vertex are short, so few rounds)."""
    lab = np.arange(n)
    while True:
        low = np.minimum(lab[a], lab[b])
        new = lab.copy()
        np.minimum.at(new, a, low)
        np.minimum.at(new, b, low)
        new = new[new]
        if np.array_equal(new, lab):
            return lab
        lab = new


def corner_vertices(loops: Loops, chosen: np.ndarray, seam: np.ndarray) -> np.ndarray:
    """(L,) int64: the vertex of each chosen loop in the cut mesh, -1 for loops not chosen. Two loops at one vertex
    share a cut vertex when a path of faces around the vertex joins them without crossing a marked edge (``seam``
    (E,) bool) or leaving the chosen faces (``chosen`` (L,) bool).

    Examples
    --------
    Two faces sharing an unmarked edge keep their two shared vertices; marked, those split in two.
    """
    key, end = loops.edge_ends(chosen)
    glued = ~seam[key // loops.vertex_count]
    a, b, _ = _same_key_pairs(key[glued], end[glued])
    lab = _components(len(loops.vertex), a, b)
    out = np.full(len(loops.vertex), -1, dtype=np.int64)
    _, out[chosen] = np.unique(lab[chosen], return_inverse=True)
    return out


class Triangles(NamedTuple):
    """The chosen faces of a mesh as heatparam's triangle mesh: V (n,3) float64 (world coordinates × unit factor),
    F (t,3) int64, and the loop at each triangle corner (t,3)."""

    V: np.ndarray
    F: np.ndarray
    corner_loop: np.ndarray


def marked_seams(mesh) -> np.ndarray:
    """(E,) bool: the edges the user marked as seams."""
    return _get(mesh.edges, "use_seam", bool)


def triangles(mesh, loops: Loops, chosen_polygons: np.ndarray, seam: np.ndarray, matrix: np.ndarray,
              factor: float) -> Triangles:
    """heatparam's mesh of the chosen polygons (``chosen_polygons`` (P,) bool), cut along the edges ``seam`` (E,)
    bool. ``matrix``: the object's 4×4 world matrix; ``factor``: Blender units → the pattern's unit."""
    mesh.calc_loop_triangles()
    tri_loops = _get(mesh.loop_triangles, "loops", np.int64, 3)
    tri_loops = tri_loops[chosen_polygons[_get(mesh.loop_triangles, "polygon_index", np.int64)]]
    chosen = chosen_polygons[loops.polygon]
    vert = corner_vertices(loops, chosen, seam)
    co = _get(mesh.vertices, "co", np.float32, 3).astype(np.float64)
    src = np.zeros(max(int(vert.max()) + 1, 0), dtype=np.int64)
    src[vert[chosen]] = loops.vertex[chosen]
    world = co[src] @ matrix[:3, :3].T + matrix[:3, 3]
    return Triangles(world * factor, vert[tri_loops], tri_loops)


def _side_pairs(F: np.ndarray, corner_uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two sides of each edge shared by two triangles (F (t,3) int64, corner_uv (t,3,2)): side ids i, j (side
    3·f + k runs from corner k of face f to corner k+1) and whether the UVs of the two sides agree at both ends."""
    a, b = F.ravel(), np.roll(F, -1, axis=1).ravel()
    ua, ub = corner_uv.reshape(-1, 2), np.roll(corner_uv, -1, axis=1).reshape(-1, 2)
    lower = (a < b)[:, None]
    at_lo, at_hi = np.where(lower, ua, ub), np.where(lower, ub, ua)  # each side's UV at the edge's ends, in order
    key = np.minimum(a, b) * (int(F.max()) + 1 if len(F) else 1) + np.maximum(a, b)
    i, j, _ = _same_key_pairs(key, np.arange(len(a)))
    return i, j, np.all(at_lo[i] == at_lo[j], axis=1) & np.all(at_hi[i] == at_hi[j], axis=1)


def chart_borders(loops: Loops, tris: Triangles, corner_uv: np.ndarray, n_edges: int) -> np.ndarray:
    """(E,) bool: heatparam's cuts (chart borders and holes' seams) moved onto polygon edges. Its cuts along polygon
    edges stay; a polygon that a cut runs through goes wholly to the side of its largest triangle, and its edges on
    the other side are cut instead. Cutting there and flattening again gives charts that one UV per loop can draw."""
    i, j, same = _side_pairs(tris.F, corner_uv)
    side_loop = tris.corner_loop.ravel()
    poly = loops.polygon[tris.corner_loop[:, 0]]
    out = np.zeros(n_edges, dtype=bool)
    across = poly[i // 3] != poly[j // 3]
    out[loops.edge[side_loop[i[across & ~same]]]] = True
    inside = ~across & same
    piece = _components(len(tris.F), i[inside] // 3, j[inside] // 3)  # a polygon's triangles its cuts leave together
    P = tris.V[tris.F]
    order = np.argsort(np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1), kind="stable")
    biggest = np.zeros(int(loops.polygon.max()) + 1, dtype=np.int64)
    biggest[poly[order]] = order  # the largest triangle writes last
    cl = tris.corner_loop
    on_border = loops.next[cl] == np.roll(cl, -1, axis=1)  # a triangle side that is a polygon edge
    out[loops.edge[cl[(piece != piece[biggest[poly]])[:, None] & on_border]]] = True
    return out


def polygon_edges(loops: Loops, polygons: np.ndarray, n_edges: int) -> np.ndarray:
    """(E,) bool: the edges of the polygons ``polygons`` (their ids): cutting there makes each a piece of its own,
    which heatparam lays out whole (a polygon is a disk)."""
    out = np.zeros(n_edges, dtype=bool)
    out[loops.edge[np.isin(loops.polygon, polygons)]] = True
    return out


def loop_uvs(tris: Triangles, corner_uv: np.ndarray, old: np.ndarray, tol: float = 1e-9
             ) -> tuple[np.ndarray, np.ndarray]:
    """The UV of every loop: ``corner_uv`` (t,3,2) at the triangles' loops, ``old`` (L,2) elsewhere. An n-gon loop
    in several triangles takes its first one's UV; returns also (L,) bool the loops whose triangles disagree (an
    n-gon that heatparam's charts cut through: one UV per loop cannot draw it)."""
    uv = old.copy()
    flat_loops, flat_uv = tris.corner_loop.ravel(), corner_uv.reshape(-1, 2)
    uv[flat_loops[::-1]] = flat_uv[::-1]  # the first corner of a loop wins (later writes win in NumPy)
    split = np.zeros(len(old), dtype=bool)
    split[flat_loops[np.abs(uv[flat_loops] - flat_uv).max(axis=1) > tol]] = True
    return uv, split


def uv_seams(loops: Loops, chosen: np.ndarray, uv: np.ndarray, n_edges: int) -> np.ndarray:
    """(E,) bool: edges between chosen faces whose two sides have different UVs at an end (the charts' borders)."""
    key, end = loops.edge_ends(chosen)
    a, b, k = _same_key_pairs(key, end)
    out = np.zeros(n_edges, dtype=bool)
    out[k[np.any(uv[a] != uv[b], axis=1)] // loops.vertex_count] = True
    return out


def fit_unit_square(corner_uv: np.ndarray, margin: float) -> np.ndarray:
    """``corner_uv`` (t,3,2) scaled uniformly and moved into [margin, 1 - margin]² when it is not inside [0,1]²
    already: heatparam packs an atlas into [0,1]² (``pack texture``) but leaves a single disk's map at true scale."""
    if corner_uv.size == 0 or (corner_uv.min() >= 0.0 and corner_uv.max() <= 1.0):
        return corner_uv
    lo, hi = corner_uv.reshape(-1, 2).min(axis=0), corner_uv.reshape(-1, 2).max(axis=0)
    return (corner_uv - lo) * ((1.0 - 2.0 * margin) / max(float((hi - lo).max()), 1e-300)) + margin
