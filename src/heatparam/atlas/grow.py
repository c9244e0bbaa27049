"""Normal-cone region growing (like D-Charts / xatlas): regions of one component that are topological disks.

Farthest-point seeds on the face graph grow together, a face joining the region whose mean normal it deviates
least from, while that deviation stays within the cone; sharp creases (``Topology.crease``) are never crossed,
and a face joins only where the region stays a disk (it touches the region along one edge with its third vertex
new, or along two edges). Faces left over seed further regions. Region borders are then straightened.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.sparse as sp

from heatparam.atlas.chart_topology import Topology, glue_inside
from heatparam.compiled import compiled, warmup

__all__ = ["DEFAULT_CONE", "dijkstra", "farthest_seeds", "grow", "halves"]

DEFAULT_CONE = 60.0  # degrees: normal-cone half angle of a grown region


@compiled()
def _heap_push(heap, key, n, c, g, r):  # pragma: no cover - compiled
    """Push (c, g, r) on the binary min-heap of n entries (``heap`` (cap,) costs, ``key`` (cap,2) two integers: a
    face and its region, or a vertex and 0; ordered as the tuples (c, g, r)); returns the arrays (doubled when full)
    and n + 1."""
    if n == len(heap):
        heap = np.concatenate((heap, np.empty_like(heap)))
        key = np.concatenate((key, np.empty_like(key)))
    i = n
    while i > 0:
        p = (i - 1) // 2
        if (heap[p], key[p, 0], key[p, 1]) <= (c, g, r):
            break
        heap[i], key[i, 0], key[i, 1] = heap[p], key[p, 0], key[p, 1]
        i = p
    heap[i], key[i, 0], key[i, 1] = c, g, r
    return heap, key, n + 1


@compiled()
def _heap_pop(heap, key, n):  # pragma: no cover - compiled
    """Remove the least entry of the heap of n entries; returns its (c, g, r) and n - 1."""
    c, g, r = heap[0], key[0, 0], key[0, 1]
    n -= 1
    lc, lg, lr = heap[n], key[n, 0], key[n, 1]  # the last entry sinks from the root
    i = 0
    while True:
        j = 2 * i + 1
        if j >= n:
            break
        if j + 1 < n and (heap[j + 1], key[j + 1, 0], key[j + 1, 1]) < (heap[j], key[j, 0], key[j, 1]):
            j += 1
        if (lc, lg, lr) <= (heap[j], key[j, 0], key[j, 1]):
            break
        heap[i], key[i, 0], key[i, 1] = heap[j], key[j, 0], key[j, 1]
        i = j
    heap[i], key[i, 0], key[i, 1] = lc, lg, lr
    return c, g, r, n


@functools.lru_cache(maxsize=4096)
def _first_pick(seed: int, n: int) -> int:
    """The first draw ``np.random.default_rng(seed).integers(n)`` (a Generator costs 0.2 ms to make)."""
    return int(np.random.default_rng(seed).integers(n))


def farthest_seeds(topo: Topology, faces: np.ndarray, k: int, seed: int) -> np.ndarray:
    """k farthest-point seed faces among ``faces`` on the face graph (centroid distances)."""
    sf, G = _face_graph(topo, faces)
    return sf[_seed_rows(sf, G, faces, k, seed)]


def _seed_rows(sf: np.ndarray, G: tuple, faces: np.ndarray, k: int, seed: int) -> np.ndarray:
    """:func:`farthest_seeds` as rows of the face graph ``G`` (:func:`_face_graph`) of the faces ``sf``."""
    return _farthest(*G, int(np.searchsorted(sf, faces[_first_pick(seed, len(faces))])), k)


def _face_graph(topo: Topology, faces: np.ndarray) -> tuple[np.ndarray, tuple]:
    """The faces ascending (q,) and their graph: faces sharing an edge, at their centroids' distance, as the CSR
    arrays the compiled loops read (indptr (q+1,) and indices int64, lengths float64)."""
    sf = np.sort(faces)
    loc = np.full(len(topo.F), -1, dtype=np.int64)
    loc[sf] = np.arange(len(sf))
    h = (3 * sf[:, None] + np.arange(3)).ravel()
    o = topo.opp[h]
    ok = o >= 0
    ok[ok] = loc[o[ok] // 3] >= 0
    f, g = loc[h[ok] // 3], loc[o[ok] // 3]
    C = topo.centroids()
    w = np.linalg.norm(C[sf[f]] - C[sf[g]], axis=1) + 1e-12
    if topo.double_neighbours():  # two faces on two common edges: one entry, the weights summed (as COO → CSR)
        G = sp.csr_matrix((w, (f, g)), shape=(len(sf), len(sf)))
        return sf, (G.indptr.astype(np.int64), G.indices.astype(np.int64), G.data)
    indptr = np.zeros(len(sf) + 1, dtype=np.int64)  # f ascends (rows in face order): the CSR arrays directly
    np.cumsum(np.bincount(f, minlength=len(sf)), out=indptr[1:])
    return sf, (indptr, g, w)


@compiled(_heap_push, _heap_pop)
def dijkstra(indptr, indices, data, source, dist, prev, allowed, target):  # pragma: no cover - compiled
    """In place: ``dist`` (n,) lowered to the graph distances from ``source`` (CSR graph, edge lengths ``data``)
    where those are shorter (a vertex no shorter path reaches is not expanded: what lies beyond it keeps its
    distance, which its own distance bounds); ``prev`` (n,) each lowered vertex's predecessor (an empty array: not
    kept); only ``allowed`` (n,) vertices are entered (an empty array: all); stops once ``target`` is reached
    (-1: never)."""
    heap, key, n = np.empty(1024), np.zeros((1024, 2), dtype=np.int64), 0
    dist[source] = 0.0
    heap, key, n = _heap_push(heap, key, n, 0.0, source, 0)
    while n:
        d, v, _, n = _heap_pop(heap, key, n)
        if d > dist[v]:
            continue
        if v == target:
            return
        for i in range(indptr[v], indptr[v + 1]):
            w = indices[i]
            if len(allowed) and not allowed[w]:
                continue
            nd = d + data[i]
            if nd < dist[w]:
                dist[w] = nd
                if len(prev):
                    prev[w] = v
                heap, key, n = _heap_push(heap, key, n, nd, w, 0)


@compiled(dijkstra)
def _lower(indptr, indices, data, source, dist):  # pragma: no cover - compiled
    """In place: ``dist`` (n,) lowered to the graph distances from ``source`` where those are shorter
    (:func:`dijkstra` over every vertex)."""
    dijkstra(indptr, indices, data, source, dist, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.bool_), -1)


@compiled(_lower)
def _farthest(indptr, indices, data, first, k):  # pragma: no cover - compiled
    """Up to k farthest-point seeds on the graph (CSR, edge lengths ``data``): the vertex farthest from ``first``,
    then each time the one farthest from those chosen, while one is at a positive distance."""
    n = len(indptr) - 1
    dist = np.full(n, np.inf)
    _lower(indptr, indices, data, first, dist)
    chosen = np.empty(k, dtype=np.int64)
    chosen[0] = np.argmax(np.where(np.isfinite(dist), dist, -1.0))
    dist[:] = np.inf  # (the distances from the first vertex only chose the first seed)
    for c in range(1, k):
        _lower(indptr, indices, data, chosen[c - 1], dist)
        cand = np.where(np.isfinite(dist), dist, -1.0)
        chosen[c] = np.argmax(cand)
        if cand[chosen[c]] <= 0:
            return chosen[:c]
    return chosen


def grow(topo: Topology, faces: np.ndarray, cone_deg: float, target_faces: int, seed: int = 0) -> list[np.ndarray]:
    """Normal-cone region growing over ``faces`` (module docstring), about ``target_faces`` faces per region;
    each returned face array (ascending) is a topological disk."""
    m = len(topo.F)
    k = max(1, int(np.ceil(len(faces) / max(target_faces, 1))))
    seeds = farthest_seeds(topo, faces, k, seed)
    order = np.sort(faces)
    lab = np.full(m + 1, -2, dtype=np.int64)  # -1 free, -2 not in the set; row m: the sentinel neighbour
    lab[order] = -1
    nb, cross = topo.neighbours()
    vf, starts = topo.vertex_faces()
    regions = _grow_regions(topo.F, topo.normals, topo.areas, nb, cross, vf, starts, lab, order,
                            seeds.astype(np.int64), float(np.cos(np.radians(cone_deg))))
    lab = lab[:m]
    _smooth(topo, lab, faces)
    mine = np.flatnonzero(lab >= 0)  # each region's faces ascending (a stable sort of the face order)
    by = mine[np.argsort(lab[mine], kind="stable")]
    ends = np.cumsum(np.bincount(lab[mine], minlength=regions))
    return [r for r in np.split(by, ends[:-1]) if len(r)]


@compiled(_heap_push)
def _plant(s, r, nrm, areas, cross, label, nsum, unit, heap, key, n):  # pragma: no cover - compiled
    """Region r at the free seed face s (its normal sum and unit mean normal), its neighbours' costs (1 - cos to
    its normal) on the heap; returns the heap and its size."""
    label[s] = r
    for d in range(3):
        nsum[r, d] = nrm[s, d] * areas[s]
    x, y, z = nsum[r, 0], nsum[r, 1], nsum[r, 2]
    length = math.sqrt(x * x + y * y + z * z)
    for d in range(3):  # a zero-area seed: its own normal (a neighbour's, Topology.build) until a face with an
        unit[r, d] = nsum[r, d] / length if length > 1e-300 else nrm[s, d]  # area joins
    for j in range(3):
        o = cross[s, j]
        if label[o] == -1:
            c = 1.0 - (nrm[o, 0] * nrm[s, 0] + nrm[o, 1] * nrm[s, 1] + nrm[o, 2] * nrm[s, 2])
            heap, key, n = _heap_push(heap, key, n, c, o, r)
    return heap, key, n


@compiled()
def _disk_rule(g, r, F, nb, vf, starts, label):  # pragma: no cover - compiled
    """Whether face g may join region r: along two edges, or along one with its third vertex new to the region."""
    on = 0
    opposite = -1
    for j in range(3):
        if label[nb[g, j]] == r:
            on += 1
            opposite = F[g, (j + 2) % 3]  # the vertex opposite edge j
    if on == 2:
        return True
    if on != 1:
        return False
    for i in range(starts[opposite], starts[opposite + 1]):
        if label[vf[i]] == r:
            return False
    return True


@compiled(_heap_push, _heap_pop, _plant, _disk_rule)
def _grow_regions(F, nrm, areas, nb, cross, vf, starts, label, order, seeds, cos_cone):  # pragma: no cover
    """Grow regions from ``seeds``, then from the first free face of ``order`` while one is left, cheapest face
    first, within the cone and the disk rule; ``label`` (m+1,) filled in place. Returns the number of regions."""
    nsum = np.zeros((len(order) + 1, 3))
    unit = np.zeros((len(order) + 1, 3))  # nsum[r] / |nsum[r]|
    heap, key, n = np.empty(1024), np.empty((1024, 2), dtype=np.int64), 0
    regions, nxt, todo = 0, 0, seeds
    while len(todo):
        for s in todo:
            if label[s] == -1:
                heap, key, n = _plant(s, regions, nrm, areas, cross, label, nsum, unit, heap, key, n)
                regions += 1
        while n:
            cost, g, r, n = _heap_pop(heap, key, n)
            if label[g] != -1:
                continue
            c = 1.0 - (nrm[g, 0] * unit[r, 0] + nrm[g, 1] * unit[r, 1] + nrm[g, 2] * unit[r, 2])
            if c > cost + 1e-12:  # stale priority: requeue with the current one
                heap, key, n = _heap_push(heap, key, n, c, g, r)
                continue
            if 1.0 - c < cos_cone or not _disk_rule(g, r, F, nb, vf, starts, label):
                continue
            label[g] = r
            nr0, nr1, nr2 = unit[r, 0], unit[r, 1], unit[r, 2]  # the costs below: to the normal before g joined
            x = nsum[r, 0] + nrm[g, 0] * areas[g]
            y = nsum[r, 1] + nrm[g, 1] * areas[g]
            z = nsum[r, 2] + nrm[g, 2] * areas[g]
            nsum[r, 0], nsum[r, 1], nsum[r, 2] = x, y, z
            length = math.sqrt(x * x + y * y + z * z)
            if length > 1e-300:  # (else: zero-area faces only so far, the seed's normal stays)
                unit[r, 0], unit[r, 1], unit[r, 2] = x / length, y / length, z / length
            for j in range(3):
                o = cross[g, j]
                if label[o] == -1:
                    co = 1.0 - (nrm[o, 0] * nr0 + nrm[o, 1] * nr1 + nrm[o, 2] * nr2)
                    heap, key, n = _heap_push(heap, key, n, co, o, r)
        while nxt < len(order) and label[order[nxt]] != -1:  # what the disk rule or the cone left: one seed a
            nxt += 1  # round, in face order, no distance field
        todo = order[nxt:nxt + 1]
    return regions


def halves(topo: Topology, faces: np.ndarray, glued: np.ndarray, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The chart ``faces`` grown again from two far seeds into two halves, each welded inside: (faces, glued) per
    half; [] when it will not split. Where growing leaves one piece (a flat chart: every face costs the first seed
    nothing, and the second seed's lone face is smoothed into it), each face goes to the nearer seed on the face
    graph instead (:func:`_nearest_seed_halves`)."""
    parts = grow(topo, faces, 179.0, max(1, (len(faces) + 1) // 2), seed)  # two halves
    if len(parts) < 2:
        parts = _nearest_seed_halves(topo, faces, seed)
    return [(p, glue_inside(topo, p)) for p in parts]


def _nearest_seed_halves(topo: Topology, faces: np.ndarray, seed: int) -> list[np.ndarray]:
    """``faces`` split between two far seeds (:func:`farthest_seeds`), each face to the nearer on the face graph
    (ties to the first): two connected halves (a face's shortest path to its seed stays in its half); [] when there
    is no second seed."""
    sf, G = _face_graph(topo, faces)
    seeds = _seed_rows(sf, G, faces, 2, seed)
    if len(seeds) < 2:
        return []
    dist = [np.full(len(sf), np.inf) for _ in seeds]
    for s, d in zip(seeds, dist, strict=True):
        _lower(*G, int(s), d)
    first = dist[0] <= dist[1]
    return [sf[first], sf[~first]]


def _smooth(topo: Topology, label: np.ndarray, faces: np.ndarray, passes: int = 3) -> None:
    """Straighten region borders: a face joined to its own region by at most one edge and to another region by
    two moves there (shorter border). Both stay disks: the face was an ear of its region (the growing's disk rule
    leaves its third vertex to it alone) and it joins the other along two edges."""
    opp = topo.opp
    for _ in range(passes):
        h = (3 * faces[:, None] + np.arange(3))
        o = opp[h]
        nb = np.where(o >= 0, label[np.maximum(o, 0) // 3], -3)
        nb = np.where(topo.crease[h], -3, nb)
        own = label[faces][:, None]
        same = (nb == own).sum(axis=1)
        other = (nb >= 0) & (nb != own)
        # a region other than its own on two of its edges (as the loop's first test below, vectorized)
        pair = ((other[:, 0] & (nb[:, 0] == nb[:, 1])) | (other[:, 0] & (nb[:, 0] == nb[:, 2]))
                | (other[:, 1] & (nb[:, 1] == nb[:, 2])))
        moved = 0
        rs = np.flatnonzero((same <= 1) & pair)
        hs = h[rs]
        # each candidate's neighbours across its edges as the loop reads them (-3: border or crease), as lists
        twin = np.where((opp[hs] >= 0) & ~topo.crease[hs], opp[hs] // 3, -1).tolist()
        for f, r, nbs, tw in zip(faces[rs].tolist(), own[rs, 0].tolist(), nb[rs].tolist(), twin, strict=True):
            cl = [c for c in nbs if c >= 0 and c != r]  # (labels at the pass's start)
            if len(cl) < 2:
                continue
            tgt = max(set(cl), key=lambda c: (cl.count(c), -c))  # the most frequent (smallest on a tie)
            if cl.count(tgt) < 2:
                continue
            # re-check against the current labels (earlier moves in this pass)
            cur = [int(label[x]) if x >= 0 else -3 for x in tw]
            if cur.count(tgt) < 2 or cur.count(r) > 1:
                continue
            if r in cur:
                # the ear's third vertex (opposite its own-region edge) must not be used by other own faces
                w = int(topo.F[f, (cur.index(r) + 2) % 3])
                if _vertex_used(topo, w, label, r, f):
                    continue
            label[f] = tgt
            moved += 1
        if not moved:
            break


def _vertex_used(topo: Topology, w: int, label: np.ndarray, r: int, skip: int) -> bool:
    """Whether a face of region r other than ``skip`` uses vertex w."""
    fs, st = topo.vertex_faces()
    around = fs[st[w]:st[w + 1]]
    return bool(((label[around] == r) & (around != skip)).any())


@warmup
def _warm() -> None:
    """The compiled loops run once on two triangles (:func:`heatparam.compiled.warm_all`)."""
    F = np.array([[0, 1, 2], [2, 1, 3]], dtype=np.int64)
    nrm = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    nb = np.array([[2, 1, 2], [0, 2, 2]], dtype=np.int64)  # face 2: the sentinel
    indptr, indices = np.array([0, 1, 2], dtype=np.int64), np.array([1, 0], dtype=np.int64)
    _farthest(indptr, indices, np.ones(2), 0, 2)
    label = np.array([-1, -1, -2], dtype=np.int64)
    vf, starts = np.array([0, 0, 1, 0, 1, 1], dtype=np.int64), np.array([0, 1, 3, 5, 6], dtype=np.int64)
    _grow_regions(F, nrm, np.ones(2), nb, nb, vf, starts, label, np.arange(2), np.zeros(1, dtype=np.int64), 0.5)
