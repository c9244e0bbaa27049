"""The common border of two charts split into stretches: simple paths of half-edges that end at cone points.

A merge glues two charts along one stretch (the rest of their common border stays a seam inside the merged chart),
so the union stays a disk.
"""

from __future__ import annotations

import numpy as np

from heatparam.atlas.chart_topology import Topology

__all__ = ["border_stretches", "half_path"]


def border_stretches(topo: Topology, hs: np.ndarray) -> list[np.ndarray]:
    """Split a set of border half-edges (one side) into simple paths that end at cone points; longest first.
    In Python over lists: a common border has a few dozen edges, where numpy's per-call costs dominate."""
    ha, hb = topo.ends()
    al, bl = ha[hs].tolist(), hb[hs].tolist()
    n = len(al)
    cone = topo.cones()
    cnt: dict[int, int] = {}
    for v in al + bl:
        cnt[v] = cnt.get(v, 0) + 1
    # edges connect at a vertex that is not a cone point and where exactly two of them meet
    join = {v for v, c in cnt.items() if c == 2 and not cone[v]}
    if len(cnt) - len(join) == 2 and max(cnt.values()) <= 2:  # one simple path (the common case) needs no graph
        path, heads = _chain(al, bl)
        if heads == 1 and len(path) == n:
            return [hs]
    first: dict[int, int] = {}
    r, c = [], []
    for i in range(n):
        for v in (al[i], bl[i]):
            if v in join:
                if v in first:
                    r.append(first[v])
                    c.append(i)
                else:
                    first[v] = i
    lab = _chain_labels(n, r, c).tolist()
    groups: dict[int, list[int]] = {}
    for i, g in enumerate(lab):
        groups.setdefault(g, []).append(i)
    out = []
    for g in groups.values():  # in label order: labels are numbered by first appearance
        if len({al[i] for i in g} | {bl[i] for i in g}) == len(g):  # a closed loop: make it a path
            g = g[1:]
        if g:
            out.append(hs[np.array(g, dtype=np.int64)])
    out.sort(key=lambda g: -float(topo.hlen[g].sum()))
    return out


def _chain_labels(n: int, r: list[int], c: list[int]) -> np.ndarray:
    """Connected components (n,) of n items joined pairwise (r[i], c[i]), numbered by their smallest item (the
    numbering of ``scipy.sparse.csgraph.connected_components``); a Python union-find: these graphs are a chart
    border's few edges, where scipy's set-up costs more than the work."""
    parent = list(range(n))

    def root(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for x, y in zip(r, c, strict=True):
        rx, ry = root(x), root(y)
        if rx != ry:
            parent[max(rx, ry)] = min(rx, ry)
    roots = [root(x) for x in range(n)]
    ids: dict[int, int] = {}
    return np.array([ids.setdefault(t, len(ids)) for t in roots], dtype=np.int64)


def _chain(a, b) -> tuple[list[int], int]:
    """The directed edges a[i] → b[i] (arrays or lists) in path order from the smallest head (a start that is no
    edge's end; edge 0 when there is none), at most one pass; and the number of heads."""
    al, bl = (a.tolist(), b.tolist()) if isinstance(a, np.ndarray) else (a, b)
    nxt = {v: i for i, v in enumerate(al)}
    heads = set(al) - set(bl)
    cur = nxt[min(heads)] if heads else 0
    path: list[int] = []
    while cur is not None and len(path) < len(al):
        path.append(cur)
        cur = nxt.get(bl[cur])
    return path, len(heads)


def half_path(topo: Topology, st: np.ndarray) -> np.ndarray:
    """The first half (in path order) of a stretch of consistently oriented half-edges."""
    ha, hb = topo.ends()
    path, _ = _chain(ha[st], hb[st])
    return st[np.array(path[: max(1, len(path) // 2)], dtype=np.int64)]
