"""Charts of one clean component: normal-cone region growing, then merges checked by a flattening.

1. Growing (like D-Charts / xatlas): farthest-point seeds on the face graph grow together, a face joining the
   chart whose mean normal it deviates least from, while that deviation stays within ``cone`` degrees; sharp
   creases (dihedral angle above ``crease``) are never crossed, and a face joins only where the chart stays a
   topological disk (it touches the chart along one edge with its third vertex new, or along two edges).
   Faces left over seed further rounds.
2. Each region is checked by a quick flattening (LSCM at true area): a region whose map has a flipped face,
   crossing boundaries or isometric distortion above the bound is grown again with a narrower cone.
3. Merging (the paper's future work turned around: a merge is kept only while the flattening stays bijective and
   within the bound): neighbouring charts are glued along one stretch of their common border (longest first;
   stretches end at cone points, vertices of large angle defect such as a cube's corners), the rest of the
   common border stays a seam inside the merged chart. A chart is therefore always a disk: a cube becomes a
   net, a cylinder's side an unrolled rectangle.

A chart is a set of faces plus the half-edges glued inside it (``Segmentation.glued``).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from heatparam.atlas.repair import half_edge_opposites
from heatparam.metrics import boundary_crossings

__all__ = ["Topology", "Segmentation", "segment", "chart_mesh", "quick_flatten", "DEFAULT_CONE", "DEFAULT_CREASE"]

DEFAULT_CONE = 60.0  # degrees: normal-cone half angle of a grown region
DEFAULT_CREASE = 60.0  # degrees: dihedral angle above which an edge is a crease (never crossed while growing)
CONE_DEFECT = 0.3  # radians: vertices with a larger |angle defect| end a glued stretch (cube corners: pi/2)
RETRY_GROWTH = 1.25  # a failed merge is tried again once one side has grown by this factor
PROXY_SLACK = 1.5  # the LSCM proxy's distortion excess may exceed the bound's excess by this factor


@dataclass
class Topology:
    """Per-component adjacency: V (n,3), F (m,3), opp (3m,) opposite half-edge or -1, normals (m,3),
    areas (m,), crease (3m,) bool, defect (n,) angle defect (2pi - angle sum inside, pi - sum on the border),
    hlen (3m,) half-edge lengths."""

    V: np.ndarray
    F: np.ndarray
    opp: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    crease: np.ndarray
    defect: np.ndarray
    hlen: np.ndarray

    @classmethod
    def build(cls, V: np.ndarray, F: np.ndarray, crease_deg: float = DEFAULT_CREASE) -> Topology:
        opp = half_edge_opposites(F)
        N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        area2 = np.linalg.norm(N, axis=1)
        normals = N / np.maximum(area2, 1e-300)[:, None]
        h = np.arange(3 * len(F))
        crease = np.zeros(3 * len(F), dtype=bool)
        ok = opp >= 0
        cosang = np.einsum("ij,ij->i", normals[h[ok] // 3], normals[opp[ok] // 3])
        crease[ok] = cosang < np.cos(np.radians(crease_deg))
        a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
        hlen = np.linalg.norm(V[b] - V[a], axis=1)
        ang = np.asarray(igl.internal_angles(V, F)).ravel()
        asum = np.bincount(F.ravel(), weights=ang, minlength=len(V))
        onb = np.zeros(len(V), dtype=bool)
        onb[a[~ok]] = True
        defect = np.where(onb, np.pi, 2 * np.pi) - asum
        return cls(V, F, opp, normals, 0.5 * area2, crease, defect, hlen)


@dataclass
class Segmentation:
    """chart (m,) int64 chart id per face (0..k-1); glued (3m,) bool, half-edges welded inside their chart."""

    chart: np.ndarray
    glued: np.ndarray
    stats: dict


def chart_mesh(topo: Topology, faces: np.ndarray, glued: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chart's own mesh: corners welded across its glued half-edges only.

    Returns Vl (nl,3), Fl (k,3) local triangles (row i = faces[i]), vert (nl,) component vertex of each row.
    """
    F = topo.F
    k = len(faces)
    loc = np.full(len(F), -1, dtype=np.int64)
    loc[faces] = np.arange(k)
    h = (3 * faces[:, None] + np.arange(3)).ravel()
    o = topo.opp[h]
    ok = (o >= 0) & glued[h]
    ok[ok] &= loc[o[ok] // 3] >= 0
    h, o = h[ok], o[ok]
    a, j = loc[h // 3], h % 3
    b, kk = loc[o // 3], o % 3
    r = np.concatenate([3 * a + j, 3 * a + (j + 1) % 3])
    c = np.concatenate([3 * b + (kk + 1) % 3, 3 * b + kk])
    G = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(3 * k, 3 * k))
    _, lab = connected_components(G, directed=False)
    uniq, first, inv = np.unique(lab, return_index=True, return_inverse=True)
    Fl = inv.reshape(k, 3).astype(np.int64)
    vert = F[faces].ravel()[first]
    return topo.V[vert], Fl, vert


def _is_disk(Fl: np.ndarray, nl: int) -> bool:
    k = len(Fl)
    a, b = Fl.ravel(), Fl[:, [1, 2, 0]].ravel()
    ne = len(np.unique(np.minimum(a, b) * nl + np.maximum(a, b)))
    return nl - ne + k == 1


def _iso(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> tuple[float, int]:
    """Area-weighted mean of max(s1, 1/s2) at the given scale, and the count of non-positive UV triangles."""
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    l1 = np.linalg.norm(e1, axis=1)
    x2 = np.einsum("ij,ij->i", e1, e2) / np.maximum(l1, 1e-300)
    y2 = np.sqrt(np.maximum(np.einsum("ij,ij->i", e2, e2) - x2 ** 2, 0))
    area = 0.5 * l1 * y2
    u1, u2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    det = u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]
    flips = int((det <= 0).sum())
    # J maps the local frame (e1 along x) to uv: J = [u1 u2] @ inv([[l1, x2],[0, y2]])
    inv11 = 1 / np.maximum(l1, 1e-300)
    inv22 = 1 / np.maximum(y2, 1e-300)
    inv12 = -x2 * inv11 * inv22
    J = np.empty((len(F), 2, 2))
    J[:, :, 0] = u1 * inv11[:, None]
    J[:, :, 1] = u1 * inv12[:, None] + u2 * inv22[:, None]
    s = np.linalg.svd(J, compute_uv=False)
    iso = np.maximum(s[:, 0], 1 / np.maximum(s[:, 1], 1e-300))
    good = det > 0
    w = area * good
    return (float(np.dot(w, iso) / w.sum()) if w.sum() > 0 else float("inf")), flips


def quick_flatten(Vl: np.ndarray, Fl: np.ndarray) -> tuple[np.ndarray | None, float, bool]:
    """LSCM of a disk, orientation kept, scaled to true area: (uv, iso mean, bijective)."""
    if len(Fl) == 1:
        e1, e2 = Vl[Fl[0, 1]] - Vl[Fl[0, 0]], Vl[Fl[0, 2]] - Vl[Fl[0, 0]]
        l1 = np.linalg.norm(e1)
        x2 = e1 @ e2 / l1
        uv = np.array([[0, 0], [l1, 0], [x2, np.sqrt(max(e2 @ e2 - x2 ** 2, 0))]])
        return uv, 1.0, bool(uv[2, 1] > 0)
    bnd = np.asarray(igl.boundary_loop(Fl), dtype=np.int64)
    if len(bnd) < 2:
        return None, float("inf"), False
    a = int(bnd[0])
    b = int(bnd[np.argmax(np.linalg.norm(Vl[bnd] - Vl[a], axis=1))])
    try:
        uv = igl.lscm(Vl, Fl, np.array([a, b]), np.array([[0.0, 0.0], [1.0, 0.0]]))
        uv = np.asarray(uv[0] if isinstance(uv, tuple) else uv, dtype=np.float64)
    except Exception:  # noqa: BLE001 - a degenerate chart: not flattenable by the proxy
        return None, float("inf"), False
    if not np.isfinite(uv).all():
        return None, float("inf"), False
    u1, u2 = uv[Fl[:, 1]] - uv[Fl[:, 0]], uv[Fl[:, 2]] - uv[Fl[:, 0]]
    sa = 0.5 * (u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0])
    if sa.sum() < 0:
        uv[:, 1] *= -1
        sa = -sa
    a3 = 0.5 * np.linalg.norm(np.cross(Vl[Fl[:, 1]] - Vl[Fl[:, 0]], Vl[Fl[:, 2]] - Vl[Fl[:, 0]]), axis=1)
    uv *= np.sqrt(a3.sum() / max(abs(sa.sum()), 1e-300))
    iso, flips = _iso(Vl, Fl, uv)
    bij = flips == 0 and boundary_crossings(uv, Fl) == 0
    return uv, iso, bij


def _seeds(topo: Topology, faces: np.ndarray, k: int, seed: int) -> np.ndarray:
    """k farthest-point seed faces among ``faces`` on the face graph (centroid distances)."""
    F = topo.F
    m = len(F)
    sub = np.zeros(m, dtype=bool)
    sub[faces] = True
    h = np.flatnonzero(topo.opp >= 0)
    f, g = h // 3, topo.opp[h] // 3
    ok = sub[f] & sub[g]
    C = topo.V[F].mean(axis=1)
    w = np.linalg.norm(C[f[ok]] - C[g[ok]], axis=1) + 1e-12
    G = sp.csr_matrix((w, (f[ok], g[ok])), shape=(m, m))
    rng = np.random.default_rng(seed)
    chosen = [int(faces[rng.integers(len(faces))])]
    d = dijkstra(G, indices=chosen[0])
    d0 = np.where(sub, d, -1.0)
    chosen = [int(np.argmax(np.where(np.isfinite(d0), d0, -1)))]
    dmin = np.full(m, np.inf)
    for _ in range(k):
        d = dijkstra(G, indices=chosen[-1])
        dmin = np.minimum(dmin, d)
        if len(chosen) >= k:
            break
        cand = np.where(sub & np.isfinite(dmin), dmin, -1.0)
        nxt = int(np.argmax(cand))
        if cand[nxt] <= 0:
            break
        chosen.append(nxt)
    return np.array(chosen, dtype=np.int64)


def grow(topo: Topology, faces: np.ndarray, cone_deg: float, target_faces: int, seed: int = 0) -> list[np.ndarray]:
    """Normal-cone region growing over ``faces``; each returned face array is a topological disk."""
    F, opp, normals, areas = topo.F, topo.opp, topo.normals, topo.areas
    m = len(F)
    cos_cone = np.cos(np.radians(cone_deg))
    label = np.full(m, -2, dtype=np.int64)
    label[faces] = -1  # -1: unassigned and allowed
    regions: list[list[int]] = []
    nsum: list[np.ndarray] = []
    vmark: list[set] = []
    left = faces
    round_ = 0
    while len(left):
        if round_ == 0:
            k = max(1, int(np.ceil(len(left) / max(target_faces, 1))))
            seeds = _seeds(topo, left, k, seed)
        else:  # leftovers (blocked by the disk rule or the cone): one seed each round, no distance field
            seeds = left[:1]
        heap: list = []
        for s in seeds:
            if label[s] != -1:
                continue
            r = len(regions)
            label[s] = r
            regions.append([int(s)])
            nsum.append(normals[s] * areas[s])
            vmark.append(set(F[s].tolist()))
            for j in range(3):
                o = opp[3 * s + j]
                if o >= 0 and label[o // 3] == -1 and not topo.crease[3 * s + j]:
                    heapq.heappush(heap, (1.0 - float(normals[o // 3] @ normals[s]), int(o // 3), r))
        while heap:
            cost, g, r = heapq.heappop(heap)
            if label[g] != -1:
                continue
            nr = nsum[r] / max(np.linalg.norm(nsum[r]), 1e-300)
            c = 1.0 - float(normals[g] @ nr)
            if c > cost + 1e-12:  # stale priority: requeue with the current one
                heapq.heappush(heap, (c, g, r))
                continue
            if 1.0 - c < cos_cone:
                continue
            # disk rule
            shared = 0
            for j in range(3):
                o = opp[3 * g + j]
                if o >= 0 and label[o // 3] == r and not topo.crease[3 * g + j]:
                    shared += 1
                elif o >= 0 and label[o // 3] == r:
                    shared += 1
            vs = F[g]
            if shared == 1:
                # third vertex: the one not on the shared edge
                for j in range(3):
                    o = opp[3 * g + j]
                    if o >= 0 and label[o // 3] == r:
                        w = int(vs[(j + 2) % 3])
                if w in vmark[r]:
                    continue
            elif shared != 2:
                continue
            label[g] = r
            regions[r].append(int(g))
            nsum[r] = nsum[r] + normals[g] * areas[g]
            vmark[r].update(vs.tolist())
            for j in range(3):
                o = opp[3 * g + j]
                if o >= 0 and label[o // 3] == -1 and not topo.crease[3 * g + j]:
                    heapq.heappush(heap, (1.0 - float(normals[o // 3] @ nr), int(o // 3), r))
        left = np.flatnonzero(label == -1)
        round_ += 1
    _smooth(topo, label, faces)
    out = [np.flatnonzero(label == r) for r in range(len(regions))]
    return [r for r in out if len(r)]


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
        moved = 0
        for r in np.flatnonzero(same <= 1):
            f = faces[r]
            cand = nb[r][(nb[r] >= 0) & (nb[r] != label[f])]
            if len(cand) < 2:
                continue
            vals, cnt = np.unique(cand, return_counts=True)
            if cnt.max() < 2:
                continue
            # re-check against the current labels (earlier moves in this pass)
            cur = [label[opp[3 * f + j] // 3] if opp[3 * f + j] >= 0 and not topo.crease[3 * f + j] else -3
                   for j in range(3)]
            tgt = int(vals[np.argmax(cnt)])
            if sum(c == tgt for c in cur) < 2 or sum(c == label[f] for c in cur) > 1:
                continue
            if sum(c == label[f] for c in cur) == 1:
                # the ear's third vertex (opposite its own-region edge) must not be used by other own faces
                j = [c == label[f] for c in cur].index(True)
                w = topo.F[f, (j + 2) % 3]
                if _vertex_used(topo, w, label, label[f], f):
                    continue
            label[f] = tgt
            moved += 1
        if not moved:
            break


def _vertex_used(topo: Topology, w: int, label: np.ndarray, r: int, skip: int) -> bool:
    if not hasattr(topo, "_vf"):
        order = np.argsort(topo.F.ravel(), kind="stable")
        starts = np.searchsorted(topo.F.ravel()[order], np.arange(len(topo.V) + 1))
        topo._vf = (order // 3, starts)
    fs, st = topo._vf
    around = fs[st[w]:st[w + 1]]
    return bool(((label[around] == r) & (around != skip)).any())


def _stretches(topo: Topology, hs: np.ndarray) -> list[np.ndarray]:
    """Split a set of border half-edges (one side) into simple paths that end at cone points; longest first."""
    F = topo.F
    a, b = F.ravel()[hs], F[:, [1, 2, 0]].ravel()[hs]
    cone = np.abs(topo.defect) > CONE_DEFECT
    # edges connect at a vertex that is not a cone point and where exactly two of them meet
    verts = np.concatenate([a, b])
    uv_, cnt = np.unique(verts, return_counts=True)
    deg = dict(zip(uv_.tolist(), cnt.tolist(), strict=True))
    by_vertex: dict[int, list[int]] = {}
    for i, (x, y) in enumerate(zip(a.tolist(), b.tolist(), strict=True)):
        by_vertex.setdefault(x, []).append(i)
        by_vertex.setdefault(y, []).append(i)
    r, c = [], []
    for v, es in by_vertex.items():
        if len(es) == 2 and deg[v] == 2 and not cone[v]:
            r.append(es[0])
            c.append(es[1])
    n = len(hs)
    G = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n))
    nc, lab = connected_components(G, directed=False)
    groups = [hs[lab == i] for i in range(nc)]
    # a closed loop: drop one edge so that it is a path
    out = []
    for g in groups:
        ga, gb = F.ravel()[g], F[:, [1, 2, 0]].ravel()[g]
        if len(np.unique(np.concatenate([ga, gb]))) == len(g):  # cycle
            g = g[1:]
        if len(g):
            out.append(g)
    out.sort(key=lambda g: -float(topo.hlen[g].sum()))
    return out


def segment(topo: Topology, max_distortion: float, max_charts: int | None = None, cone_deg: float = DEFAULT_CONE,
            seed: int = 0, target_faces: int = 2000) -> Segmentation:
    """Charts of one component (module docstring). Each chart passes :func:`quick_flatten` within the bound."""
    m = len(topo.F)
    glued = np.zeros(3 * m, dtype=bool)
    bound = 1.0 + PROXY_SLACK * (max_distortion - 1.0)
    charts: list[np.ndarray] = []
    iso_of: list[float] = []
    stats = {"grown": 0, "regrown": 0, "merges": 0, "merge_tests": 0}
    work = [(np.arange(m), cone_deg)]
    while work:
        faces, cone = work.pop()
        for reg in grow(topo, faces, cone, target_faces, seed):
            stats["grown"] += 1
            g = _glue_inside(topo, reg)
            Vl, Fl, _ = chart_mesh(topo, reg, g)
            _, iso, bij = quick_flatten(Vl, Fl)
            if (bij and iso <= bound) or len(reg) == 1 or cone < 2.0:
                glued |= g
                charts.append(reg)
                iso_of.append(iso)
            else:
                stats["regrown"] += 1
                work.append((reg, cone * 0.5))
    chart = np.empty(m, dtype=np.int64)
    for i, c in enumerate(charts):
        chart[c] = i
    import time

    t = time.perf_counter()
    chart, glued, nmerge, ntest = _merge(topo, chart, glued, bound)
    stats["capped"] = False
    if max_charts is not None and chart.max() + 1 > max_charts:
        # the user's cap beats the bound: keep merging while the merged chart stays bijective
        chart, glued, n2, t2 = _merge(topo, chart, glued, np.inf, stop_at=max_charts)
        nmerge, ntest = nmerge + n2, ntest + t2
        stats["capped"] = True
    stats["merge_seconds"] = round(time.perf_counter() - t, 3)
    stats["merges"], stats["merge_tests"] = nmerge, ntest
    return Segmentation(chart=chart, glued=glued, stats=stats)


def _glue_inside(topo: Topology, faces: np.ndarray) -> np.ndarray:
    m = len(topo.F)
    inside = np.zeros(m, dtype=bool)
    inside[faces] = True
    g = np.zeros(3 * m, dtype=bool)
    h = (3 * faces[:, None] + np.arange(3)).ravel()
    o = topo.opp[h]
    ok = o >= 0
    ok[ok] = inside[o[ok] // 3]
    g[h[ok]] = True
    return g


def _merge(topo: Topology, chart: np.ndarray, glued: np.ndarray, bound: float, stop_at: int | None = None):
    """Greedy merges (small unions first, then the longest common border), each kept while the merged chart's
    quick flattening is bijective and within the bound; stops early at ``stop_at`` charts."""
    opp = topo.opp
    h_all = np.flatnonzero(opp >= 0)
    failed: dict = {}  # (a, b) -> their sizes when the merge failed
    merges = tests = 0
    members = {int(c): np.flatnonzero(chart == c) for c in np.unique(chart)}
    while True:
        # candidate pairs with their common border length; one pass merges every pair whose charts are untouched
        h = h_all[chart[h_all // 3] < chart[opp[h_all] // 3]]
        if not len(h):
            break
        ca, cb = chart[h // 3], chart[opp[h] // 3]
        base = int(chart.max()) + 1
        key = ca * base + cb
        uk, inv = np.unique(key, return_inverse=True)
        length = np.bincount(inv, weights=topo.hlen[h])
        size = np.array([len(members[int(x)]) for x in (uk // base)]) + np.array(
            [len(members[int(x)]) for x in (uk % base)])
        # cheap tests first (small unions), longest common border first among equals: the big charts are
        # flattened once they have absorbed their small neighbours
        order = np.lexsort((-length, np.ceil(np.log2(size))))
        grouped = np.argsort(inv, kind="stable")
        starts = np.r_[0, np.cumsum(np.bincount(inv, minlength=len(uk)))]
        touched: set = set()
        merged_any = False
        for i in order:
            if stop_at is not None and len(members) <= stop_at:
                break
            a, b = divmod(int(uk[i]), base)
            if a in touched or b in touched:
                continue
            na, nb = len(members[a]), len(members[b])
            prev = failed.get((a, b))
            if prev is not None and na < RETRY_GROWTH * prev[0] and nb < RETRY_GROWTH * prev[1]:
                continue  # failed before, and neither side has grown enough since to change the answer much
            hs = h[grouped[starts[i]:starts[i + 1]]]
            st = _stretches(topo, hs)[0]
            faces = np.concatenate([members[a], members[b]])
            g = glued.copy()
            g[st] = True
            g[opp[st]] = True
            Vl, Fl, _ = chart_mesh(topo, faces, g)
            tests += 1
            ok = _is_disk(Fl, len(Vl))
            if ok:
                _, iso, bij = quick_flatten(Vl, Fl)
                ok = bij and iso <= bound
            if ok:
                glued = g
                chart[members[b]] = a
                members[a] = np.sort(faces)
                del members[b]
                merges += 1
                touched.update((a, b))
                merged_any = True
            else:
                failed[(a, b)] = (na, nb)
        if not merged_any or (stop_at is not None and len(members) <= stop_at):
            break
    # relabel 0..k-1 by size
    ids, chart = np.unique(chart, return_inverse=True)
    return chart.astype(np.int64), glued, merges, tests
