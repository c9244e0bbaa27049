"""Seams: the shortest surface paths that join every hole to the border, and the mesh cut open along them.

Cutting a disk with holes along :func:`hole_seams` leaves a disk (one boundary loop); the pipeline's seams stage
(``heatparam.pipeline.seams``) decides when a map is better cut.
"""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse as sp

from heatparam.mesh.topology import edge_graph, unique_edges


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
