"""Mesh topology: edges, the edge graph, its components, boundary loops (one walker), vertex compaction, face areas.

Plain functions over ``F (m,3) int64`` (and ``V (n,3) float64`` where lengths matter). Every module that needs a
boundary loop, a unique edge list or the referenced vertices calls these.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from heatparam.compiled import COMPILED_MIN_FACES, compiled, warmup

#: A face is degenerate (zero area) when |2 · area| <= this × (its longest edge)² (scale-free), or within the
#: rounding of its coordinates (``ROUNDING_AREA``); the validation's count, the metrics' exclusion and the fill's
#: triangle checks use the same test (:func:`zero_area`).
DEGENERATE_AREA_REL = 1e-14
#: ... or when |2 · area| <= this × machine epsilon × (its largest coordinate) × (its longest edge): the area that
#: rounding its corners to doubles can make or unmake (each coordinate off by half an ulp moves 2 · area by up to
#: 2√3 of that). Three corners collinear in a file's decimals read as a triangle of that order (laikago's chassis:
#: 2 · area 4e-21 at edges of 6e-4 and coordinates of 0.26).
ROUNDING_AREA = 8.0


def unique_ints(x: np.ndarray) -> np.ndarray:
    """Sorted unique values of an integer array (a sort and a mask). NumPy 2.4's ``np.unique`` takes a hash path
    that is 20-60× slower on millions of distinct keys (3M int64: 3.3 s vs 0.06 s for the sort)."""
    x = np.sort(x, axis=None)
    keep = np.ones(len(x), dtype=bool)
    keep[1:] = x[1:] != x[:-1]
    return x[keep]


def sort_with_order(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x sorted, ``np.argsort(x, kind="stable")``) of a 1-D integer array. Where (range of x) × 2^⌈log₂ len(x)⌉
    fits in int64, each value carries its index in its low bits and one ``np.sort`` (a SIMD quicksort) orders them:
    3.3M keys 0.07 vs 0.11 s for the stable argsort alone; else the stable argsort."""
    x = np.asarray(x).ravel()
    n = len(x)
    if n == 0:
        return x.copy(), np.zeros(0, dtype=np.int64)
    lo, hi = int(x.min()), int(x.max())
    shift = (n - 1).bit_length()  # the index in the low bits: shifts and masks, not divisions
    if (hi - lo + 1) << shift >= 2**63:
        order = np.argsort(x, kind="stable")
        return x[order], order
    s = (x.astype(np.int64) - lo) << shift
    s |= np.arange(n, dtype=np.int64)
    s.sort()
    keys = s >> shift
    if lo:
        keys += lo
    return keys.astype(x.dtype, copy=False), s & ((1 << shift) - 1)


def stable_argsort(x: np.ndarray) -> np.ndarray:
    """``np.argsort(x, kind="stable")`` of a 1-D integer array, the same permutation, faster
    (:func:`sort_with_order`)."""
    return sort_with_order(x)[1]


def unique_inverse(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``np.unique(x, return_index=True, return_inverse=True)`` for a 1-D integer array by one stable sort (see
    :func:`unique_ints`, :func:`sort_with_order`): (sorted unique values (u,), the first index of each (u,), the
    inverse (len(x),))."""
    xs, order = sort_with_order(x)
    new = np.ones(len(xs), dtype=bool)
    new[1:] = xs[1:] != xs[:-1]
    inv = np.empty(len(xs), dtype=np.int64)
    inv[order] = np.cumsum(new) - 1
    return xs[new], order[new], inv


#: From this many nodes :func:`connected_labels` runs a compiled union-find: on a 286k-face scan's corner graph (859k
#: nodes, 1.7M links) 0.02-0.06 s against scipy's 0.10-0.46 s. The corners of ``COMPILED_MIN_FACES`` faces.
COMPILED_MIN_NODES = 3 * COMPILED_MIN_FACES


def connected_labels(n: int, r: np.ndarray, c: np.ndarray) -> tuple[int, np.ndarray]:
    """The connected components of the undirected graph on n nodes with the links (r[i], c[i]): (their count,
    (n,) int64 the component of each node, numbered by their smallest node). The labels of
    ``scipy.sparse.csgraph.connected_components``, which serves below ``COMPILED_MIN_NODES``."""
    r, c = np.asarray(r, dtype=np.int64).ravel(), np.asarray(c, dtype=np.int64).ravel()
    if n < COMPILED_MIN_NODES:
        from scipy.sparse.csgraph import connected_components

        graph = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n))
        count, labels = connected_components(graph, directed=False)
        return int(count), labels.astype(np.int64, copy=False)
    labels = np.empty(n, dtype=np.int64)
    return int(_union_find(r, c, labels)), labels


@compiled()
def _union_find(r, c, labels):  # pragma: no cover - compiled
    """:func:`connected_labels` into ``labels`` (n,); returns the count. Each set's root is its smallest node (a
    union keeps the smaller root), so numbering roots in node order numbers the components as scipy does."""
    parent = np.arange(len(labels))
    for i in range(len(r)):
        a, b = r[i], c[i]
        while parent[a] != a:  # path halving
            parent[a] = parent[parent[a]]
            a = parent[a]
        while parent[b] != b:
            parent[b] = parent[parent[b]]
            b = parent[b]
        if a < b:
            parent[b] = a
        elif b < a:
            parent[a] = b
    count = 0
    for v in range(len(labels)):
        p = parent[v]
        while parent[p] != p:
            p = parent[p]
        if p == v:
            labels[v] = count
            count += 1
        else:  # p < v: labelled already
            labels[v] = labels[p]
    return count


@warmup
def _warm() -> None:
    """The compiled loop run once on two nodes (:func:`heatparam.compiled.warm_all`)."""
    _union_find(np.zeros(1, dtype=np.int64), np.ones(1, dtype=np.int64), np.empty(2, dtype=np.int64))


def face_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Triangle areas, (m,) float64."""
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def degenerate_faces(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m,) bool: zero-area faces (:func:`zero_area`; a point-like face too)."""
    E = V[F[:, [1, 2, 0]]] - V[F]
    longest2 = np.einsum("ijk,ijk->ij", E, E).max(axis=1)
    return zero_area(2 * face_areas(V, F), longest2, V, F)


def zero_area(area2: np.ndarray, longest2: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m,) bool: faces (``F`` over ``V``) of twice the area ``area2`` (m,) and squared longest edge ``longest2``
    (m,) that have zero area: ``DEGENERATE_AREA_REL`` of longest2, or within the rounding of their coordinates
    (``ROUNDING_AREA``)."""
    coord = np.abs(V[F]).max(axis=(1, 2))
    rounding = ROUNDING_AREA * np.finfo(np.float64).eps * coord * np.sqrt(longest2)
    return area2 <= np.maximum(DEGENERATE_AREA_REL * longest2, rounding)


def repeated_vertex_faces(F: np.ndarray) -> np.ndarray:
    """(m,) bool: faces that name a vertex twice (a segment or a point, not a triangle)."""
    return (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])


def _half_edges(F: np.ndarray) -> np.ndarray:
    return np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])

#: The boundary edges of the last few meshes asked, keyed by the faces' content (SHA-256 of F: 4 ms at 300k faces,
#: the edges 50 ms): the start checks, the crossing checks of every candidate and prolongation, and the loops ask
#: again for the same faces (a 262k-face part: 23 calls, 1.1 s)
_BOUNDARY_MEMO_SIZE = 4
_boundary_memo: OrderedDict[tuple, np.ndarray] = OrderedDict()
_boundary_lock = threading.Lock()


def boundary_edges(F: np.ndarray) -> np.ndarray:
    """Edges used by exactly one face.

    Parameters
    ----------
    F : (m, 3) int64

    Returns
    -------
    (b, 2) int64
        Vertex pairs, oriented as in their face (a new array).
    """
    F = np.ascontiguousarray(F, dtype=np.int64)
    if F.size == 0:
        return np.zeros((0, 2), np.int64)
    key = (F.shape, hashlib.sha256(memoryview(F)).digest())
    with _boundary_lock:
        edges = _boundary_memo.get(key)
        if edges is not None:
            _boundary_memo.move_to_end(key)
            return edges.copy()
    edges = _boundary_edges(F)
    with _boundary_lock:
        _boundary_memo[key] = edges
        while len(_boundary_memo) > _BOUNDARY_MEMO_SIZE:
            _boundary_memo.popitem(last=False)
    return edges.copy()


def _boundary_edges(F: np.ndarray) -> np.ndarray:
    he = _half_edges(F)
    lo = he.min(axis=1)
    hi = he.max(axis=1)
    key = lo * (int(F.max()) + 1) + hi
    ks, order = sort_with_order(key)
    differs = ks[1:] != ks[:-1]
    single = np.ones(len(ks), dtype=bool)
    single[1:] &= differs
    single[:-1] &= differs
    return he[np.sort(order[single])]

def _walk_loops(he: np.ndarray) -> list[np.ndarray]:
    """Chain directed boundary half-edges into loops (open chains if the boundary is not a 1-manifold)."""
    nb = len(he)
    if nb == 0:
        return []
    src, dst = he[:, 0], he[:, 1]
    order = np.argsort(src, kind="stable")
    verts, first = np.unique(src[order], return_index=True)
    last = np.append(first[1:], nb)
    start_of = dict(zip(verts.tolist(), zip(first.tolist(), last.tolist(), strict=True), strict=True))
    order_l = order.tolist()
    src_l, dst_l = src.tolist(), dst.tolist()
    used = [False] * nb
    ptr = {v: s for v, (s, _) in start_of.items()}  # next unused slot per source vertex
    loops = []
    for e0 in order_l:
        if used[e0]:
            continue
        used[e0] = True
        v0 = src_l[e0]
        loop = [v0]
        cur = dst_l[e0]
        while cur != v0:
            slot = start_of.get(cur)
            if slot is None:
                break
            k, end = ptr[cur], slot[1]
            while k < end and used[order_l[k]]:
                k += 1
            ptr[cur] = k
            if k == end:
                break
            e = order_l[k]
            used[e] = True
            loop.append(cur)
            cur = dst_l[e]
        else:
            loops.append(np.asarray(loop, dtype=np.int64))
            continue
        loop.append(cur)  # open chain: keep its last vertex
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops

def boundary_loops(F: np.ndarray) -> list[np.ndarray]:
    """Ordered boundary loops of a triangle mesh.

    Chains the boundary edges (edges in exactly one face) in face orientation. Where the boundary is not
    a 1-manifold (a vertex with several boundary edges, as at a bow-tie) every edge still lands in exactly
    one loop; inconsistently oriented faces can yield open chains. ``igl.boundary_loop_all`` is not used:
    it mishandles bow-ties and builds full face adjacency (tens of seconds on a high-valence fan).
    For the UV boundary of a map with seams pass ``Fuv`` (after :func:`weld_uv` if corners are
    duplicated).

    Parameters
    ----------
    F : (m, 3) int64

    Returns
    -------
    list of (k_i,) int64
        Vertex indices of each loop, in order (the last vertex connects back to the first).
    """
    return _walk_loops(boundary_edges(F))


def loops_outer_first(V: np.ndarray, F: np.ndarray) -> list[np.ndarray]:
    """Boundary loops (:func:`boundary_loops`) sorted by 3D length, the longest (the outer border) first."""
    loops = boundary_loops(F)
    lengths = [loop_length(V, lp) for lp in loops]
    order = np.argsort(lengths)[::-1]
    return [loops[i] for i in order]


def loop_length(V: np.ndarray, loop: np.ndarray) -> float:
    """Length of a closed vertex loop in 3D."""
    return float(np.linalg.norm(V[loop] - V[np.roll(loop, -1)], axis=1).sum())


def vertex_corners(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The corners of F (m,3) around each of n vertices: (corners (3m,), starts (n+1,)); vertex w's are
    ``corners[starts[w]:starts[w+1]]`` in face order, corner k being face k // 3's (k % 3)-th vertex."""
    ids, corners = sort_with_order(np.asarray(F).ravel())
    return corners, np.searchsorted(ids, np.arange(n + 1))


def unique_edges(F: np.ndarray) -> np.ndarray:
    """(e,2) int64: every edge of the triangles once, as (smaller, larger) vertex index, sorted (by
    :func:`unique_ints` on one key per edge: ``np.unique(axis=0)`` took 3.4 s on beetle upsampled's 1.9M half-edges,
    this 0.1 s)."""
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]).astype(np.int64), axis=1)
    if not len(E):
        return E.reshape(0, 2)
    n = int(E.max()) + 1
    key = unique_ints(E[:, 0] * n + E[:, 1])
    return np.column_stack([key // n, key % n])

# ----------------------------------------------------------------------------------------------------------
# seams: cutting holes open to the border
# ----------------------------------------------------------------------------------------------------------
def edge_graph(F: np.ndarray, lengths: np.ndarray, n: int) -> sp.csr_matrix:
    """The mesh's edge graph as a sparse (n, n) matrix of edge lengths, one direction per half-edge (use
    ``directed=False`` in ``scipy.sparse.csgraph``). lengths : (m,3), column c the edge opposite corner c."""
    E = np.concatenate([F[:, [1, 2]], F[:, [2, 0]], F[:, [0, 1]]])
    return sp.csr_matrix((np.asarray(lengths).T.ravel(), (E[:, 0], E[:, 1])), shape=(n, n))


class Compaction(NamedTuple):
    """The referenced vertices of a mesh renumbered 0..k-1: ``keep`` (k,) input ids, ``remap`` (n,) new id or -1."""

    keep: np.ndarray
    remap: np.ndarray

    def faces(self, F: np.ndarray) -> np.ndarray:
        """F (m,3) in the compacted numbering."""
        return self.remap[F]


def compact(referenced: np.ndarray) -> Compaction:
    """Renumber the vertices flagged in ``referenced`` (n,) bool to 0..k-1 (order kept)."""
    keep = np.flatnonzero(referenced)
    remap = np.full(len(referenced), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return Compaction(keep, remap)


def pairs_in_groups(edges: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """(p,2) all pairs (edges[p], edges[q]), p < q, within each group ``edges[starts[g] : starts[g] + counts[g]]``."""
    if len(counts) == 0:
        return np.zeros((0, 2), np.int64)
    # members of group g sit at starts[g] .. starts[g] + counts[g] - 1; member p pairs with p+1 .. end-1
    local = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    gpos = np.repeat(starts, counts) + local
    end = np.repeat(starts + counts, counts)
    npart = end - gpos - 1
    tot = int(npart.sum())
    if tot == 0:
        return np.zeros((0, 2), np.int64)
    first = np.repeat(gpos, npart)
    second = first + 1 + (np.arange(tot) - np.repeat(np.cumsum(npart) - npart, npart))
    return np.column_stack([edges[first], edges[second]])
