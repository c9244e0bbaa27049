"""Straightening the seams between charts: each seam replaced by the shortest path between its ends through the
two charts it divides, where both charts' flattening stays bijective and within the bound.

The segmentation's step 4 (``atlas.segment``). A region's border follows where the normals turn (the growing's
cone), which on a smooth surface is a wandering line: on beetle the seams between charts were 1.6× their shortest
paths. A seam here is a chain of edges between two charts whose inner vertices touch those two charts only; its
ends (where a third chart, the mesh border or an inner seam meets it) stay where they are. The shortest edge path
between the ends, through vertices inside the two charts or on the seam itself (Dijkstra on the mesh's edges),
divides their union in two again; the new pair is kept when both layouts stay bijective and within the bound, as
every chart of the segmentation is: the faces that keep their chart keep its layout, the faces that change chart
are laid out as their extension (:class:`_Moves`). A seam along a sharp crease (``Topology.crease``: a CAD part's
feature line) is left where it is, and so is a path shorter by less than the seam's mean edge: the same seam at
the mesh's resolution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from heatparam.atlas.chart_topology import Topology, chart_mesh
from heatparam.atlas.flatten import lscm_groups
from heatparam.atlas.grow import dijkstra
from heatparam.atlas.merge import Layouts, extension_sums, neighbour_pins, new_edge_crossings
from heatparam.mesh.topology import edge_graph
from heatparam.metrics import true_scale_iso

__all__ = ["straighten"]


@dataclass
class _Seam:
    """A seam between charts a < b: its half-edges ``h`` (one side, in chart a or b), inner vertices, ends s, t and
    length."""

    a: int
    b: int
    h: np.ndarray
    inner: np.ndarray
    s: int
    t: int
    length: float


def straighten(topo: Topology, chart: np.ndarray, glued: np.ndarray, bound: float, layouts: Layouts) -> dict:
    """:class:`Straightening` run to its end; ``chart`` (m,), ``glued`` (3m,) and ``layouts`` updated in place.
    Returns its statistics (seams straightened, tried; seam length before and after)."""
    return Straightening(topo, chart, glued, layouts, bound).run()


class Straightening:
    """Rounds of seam straightenings, each chart in one per round (a straightening moves both of its charts'
    borders); a seam is tried once (its charts and ends)."""

    def __init__(self, topo: Topology, chart: np.ndarray, glued: np.ndarray, layouts: Layouts, bound: float):
        self.topo, self.chart, self.glued, self.layouts, self.bound = topo, chart, glued, layouts, bound
        self.ha, self.hb = topo.ends()
        # half-edge j of a face runs from corner j to j + 1: the edge opposite corner j + 2 (edge_graph's columns)
        G = edge_graph(topo.F, topo.hlen.reshape(-1, 3)[:, [1, 2, 0]], len(topo.V))
        G = G.maximum(G.T).tocsr()  # border edges have one half-edge: both directions
        self.indptr, self.indices, self.weights = (G.indptr.astype(np.int64), G.indices.astype(np.int64),
                                                   G.data.astype(np.float64))
        self.tried: set = set()
        self.paths: dict = {}  # seam key -> (path, length), until one of its charts changes
        self.stats = {"straightened": 0, "tried": 0}

    def run(self) -> dict:
        """Rounds until no seam is left to try; returns the statistics."""
        before = self._seam_length()
        while True:
            picked = self._pick()
            if not picked:
                break
            self._test(picked)
        self.stats["seam_length"] = [round(before, 6), round(self._seam_length(), 6)]
        return self.stats

    def _seam_length(self) -> float:
        h = np.flatnonzero((self.topo.opp >= 0) & ~self.glued)
        return float(self.topo.hlen[h].sum() / 2)

    def _pick(self) -> list[tuple[_Seam, np.ndarray]]:
        """A round's seams with their shorter paths, longest excess first, each chart in one at most."""
        self._vertices()
        cand = []
        for seam in self._seams():
            if self._key(seam) in self.tried or not (self.layouts.ok[seam.a] and self.layouts.ok[seam.b]):
                continue  # tried, or a chart without a checked layout to extend
            if self._key(seam) not in self.paths:
                self.paths[self._key(seam)] = self._path(seam)
            path, dist = self.paths[self._key(seam)]
            if path is not None and seam.length - dist > seam.length / len(seam.h):
                cand.append((seam.length - dist, seam, path))
            else:
                self.tried.add(self._key(seam))
        cand.sort(key=lambda c: -c[0])
        touched: set = set()
        picked = []
        for _, seam, path in cand:
            if seam.a not in touched and seam.b not in touched:
                self.tried.add(self._key(seam))
                picked.append((seam, path))
                touched.update((seam.a, seam.b))
        return picked

    @staticmethod
    def _key(seam: _Seam) -> tuple:
        return seam.a, seam.b, seam.s, seam.t, len(seam.h)

    def _vertices(self) -> None:
        """Per vertex, for this round: ``owner`` (the chart all its faces are in, with no cut edge or mesh border at
        it; else -1) and ``interior`` (inside a seam: two cut edges meet there, its faces lie in two charts)."""
        topo, opp = self.topo, self.topo.opp
        n = len(topo.V)
        cut = (opp < 0) | ~self.glued  # half-edges on a seam or the mesh border
        one = cut & ((opp < 0) | (np.arange(len(opp)) < opp))  # each cut edge once
        deg = np.bincount(np.concatenate([self.ha[one], self.hb[one]]), minlength=n)
        fv, fc = topo.F.ravel(), np.repeat(self.chart, 3)
        lo, hi = np.full(n, np.iinfo(np.int64).max), np.full(n, -1)
        np.minimum.at(lo, fv, fc)
        np.maximum.at(hi, fv, fc)
        third = np.zeros(n, dtype=bool)
        np.logical_or.at(third, fv, (fc != lo[fv]) & (fc != hi[fv]))
        onb = np.zeros(n, dtype=bool)
        onb[self.ha[opp < 0]] = True
        self.owner = np.where((lo == hi) & (deg == 0), lo, -1)
        self.interior = (deg == 2) & (lo != hi) & ~third & ~onb

    def _seams(self) -> list[_Seam]:
        """The seams between two charts (open chains; a closed one has no ends to keep)."""
        topo, chart, opp = self.topo, self.chart, self.topo.opp
        hh = np.arange(len(opp))
        between = (opp > hh) & (chart[hh // 3] != chart[np.maximum(opp, 0) // 3])
        h = np.flatnonzero(between)
        if not len(h):
            return []
        # seam edges joined at interior vertices: connected components over the edges
        ev = np.concatenate([self.ha[h], self.hb[h]])
        ei = np.tile(np.arange(len(h)), 2)
        keep = self.interior[ev]
        o = np.argsort(ev[keep], kind="stable")
        pairs = ei[keep][o].reshape(-1, 2)
        E = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(h), len(h)))
        nc, lab = connected_components(E, directed=False)
        order = np.argsort(lab, kind="stable")
        starts = np.searchsorted(lab[order], np.arange(nc + 1))
        seams = []
        for c in range(nc):
            hc = h[order[starts[c]:starts[c + 1]]]
            vs = np.concatenate([self.ha[hc], self.hb[hc]])
            ends = np.flatnonzero(np.bincount(vs) == 1)
            if len(ends) != 2 or topo.crease[hc].any():
                continue  # a closed seam, or one along a crease
            a, b = sorted((int(chart[hc[0] // 3]), int(chart[opp[hc[0]] // 3])))
            seams.append(_Seam(a, b, hc, np.unique(vs[self.interior[vs]]), int(ends[0]), int(ends[1]),
                               float(topo.hlen[hc].sum())))
        return seams

    def _path(self, seam: _Seam) -> tuple[np.ndarray | None, float]:
        """The shortest edge path from the seam's one end to the other through the inside of its two charts and
        the seam itself, and its length; (None, inf) where none."""
        allowed = (self.owner == seam.a) | (self.owner == seam.b)
        allowed[seam.inner] = True
        allowed[[seam.s, seam.t]] = True
        path = _shortest_path(self.indptr, self.indices, self.weights, allowed, seam.s, seam.t)
        if len(path) < 2:
            return None, np.inf
        return path, float(np.linalg.norm(self.topo.V[path[1:]] - self.topo.V[path[:-1]], axis=1).sum())

    def _split(self, seam: _Seam, path: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The two charts' faces cut apart along ``path`` instead of the seam: (faces of the new a, of the new b,
        the union's half-edges, which of them are glued), or None when the path does not divide them in two."""
        topo, opp, chart = self.topo, self.topo.opp, self.chart
        n = len(topo.V)
        U = np.flatnonzero((chart == seam.a) | (chart == seam.b))
        h = (3 * U[:, None] + np.arange(3)).ravel()
        o = opp[h]
        inU = o >= 0
        inU[inU] = (chart[o[inU] // 3] == seam.a) | (chart[o[inU] // 3] == seam.b)
        on_seam = np.zeros(len(opp), dtype=bool)
        on_seam[seam.h] = True
        on_seam[opp[seam.h]] = True
        pk = np.sort(np.column_stack([path[:-1], path[1:]]), axis=1)
        pkey = pk[:, 0] * n + pk[:, 1]
        ek = np.minimum(self.ha[h], self.hb[h]) * n + np.maximum(self.ha[h], self.hb[h])
        on_path = np.isin(ek, pkey)
        if on_path.sum() < 2 * (len(path) - 1) or (on_path & ~inU).any():
            return None  # a path edge outside the two charts (or on the mesh border)
        join = inU & (self.glued[h] | on_seam[h]) & ~on_path
        row = np.full(len(chart), -1, dtype=np.int64)
        row[U] = np.arange(len(U))
        a_row = np.repeat(np.arange(len(U)), 3)[join]
        b_row = row[o[join] // 3]
        G = sp.coo_matrix((np.ones(len(a_row)), (a_row, b_row)), shape=(len(U), len(U)))
        nc, lab = connected_components(G, directed=False)
        if nc != 2:
            return None
        was_a = chart[U] == seam.a
        first_is_a = (was_a & (lab == 0)).sum() >= (was_a & (lab == 1)).sum()
        fa, fb = (U[lab == 0], U[lab == 1]) if first_is_a else (U[lab == 1], U[lab == 0])
        if np.array_equal(fa, np.flatnonzero(chart == seam.a)):
            return None  # the path is the seam
        g = np.zeros(len(h), dtype=bool)
        g[join] = True
        return fa, fb, h, g

    def _test(self, picked: list[tuple[_Seam, np.ndarray]]) -> None:
        """Split every picked pair along its path and keep those whose both charts stay bijective and within the
        bound (:class:`_Moves`); the charts, glued half-edges and layouts of the kept ones updated."""
        props = []
        glued = self.glued.copy()
        for seam, path in picked:
            split = self._split(seam, path)
            if split is not None:
                glued[split[2]] = split[3]
                props.append((seam, *split))
        self.stats["tried"] += len(props)
        if not props:
            return
        moves = _Moves(self.topo, self.chart, glued, self.layouts, props)
        ok = moves.passed(self.bound).reshape(-1, 2).all(axis=1)
        for i in np.flatnonzero(ok):
            seam, fa, fb, h, g = props[i]
            self.chart[fa], self.chart[fb] = seam.a, seam.b
            self.glued[h] = g
            self.paths = {k: v for k, v in self.paths.items() if not {k[0], k[1]} & {seam.a, seam.b}}
        moves.keep(ok)
        self.stats["straightened"] += int(ok.sum())


class _Moves:
    """The faces that change chart in a round's straightenings, laid out as the extension of the faces that keep
    their chart (LSCM with the corners they share pinned at the kept faces' UVs: the merges' extension test), and
    what each new chart is then: group 2 i is the new chart a of proposal i, 2 i + 1 its new chart b. Only the moved
    faces are solved and only pairs of border edges with a moved face's edge can cross (the kept faces' layout is a
    part of a bijective one); the union of two disks glued along one arc of both borders is a disk, and a path from
    border to border through its inside cuts it into two disks (:meth:`Straightening._split` checks there are two),
    so no disk test is needed."""

    def __init__(self, topo: Topology, chart: np.ndarray, glued: np.ndarray, layouts: Layouts, props: list):
        self.topo, self.chart, self.glued, self.layouts = topo, chart, glued, layouts
        self.ids = np.array([c for p in props for c in (p[0].a, p[0].b)], dtype=np.int64)  # the chart of each group
        self.sides = [f for p in props for f in (p[1], p[2])]  # the faces of each group
        moved = [f[chart[f] != c] for f, c in zip(self.sides, self.ids, strict=True)]
        self.qf = np.concatenate(moved)
        self.grp = np.repeat(np.arange(len(moved)), [len(f) for f in moved])
        self.Vl, self.Fl, _ = chart_mesh(topo, self.qf, glued, self.grp)
        self.uv = self._extension()

    def _extension(self) -> np.ndarray | None:
        """(rows, 2) the moved faces' layout, or None where the shared solve failed."""
        topo, qf = self.topo, self.qf
        m = len(topo.F)
        mask = np.zeros(m, dtype=bool)
        mask[qf] = True
        hq = (3 * qf[:, None] + np.arange(3)).ravel()
        o = topo.opp[hq]
        shared = self.glued[hq] & (o >= 0)  # glued to a face of the same new chart that keeps its chart
        shared[shared] = ~mask[o[shared] // 3]
        rows, vals = neighbour_pins(topo, self.Fl, np.repeat(np.arange(len(qf)), 3)[shared], hq[shared],
                                    self.layouts.uv)
        rows, first = np.unique(rows, return_index=True)
        try:
            uv = lscm_groups(self.Vl, self.Fl, self.grp, rows, vals[first], self.topo.degenerate[self.qf])
        except (RuntimeError, ValueError):
            return None
        return uv if np.isfinite(uv).all() else None

    def passed(self, bound: float) -> np.ndarray:
        """(groups,) bool: the new chart's moved faces do not flip, its area-weighted iso mean is within ``bound``
        and no two of its border edges cross."""
        k = len(self.ids)
        if self.uv is None:
            return np.zeros(k, dtype=bool)
        lay, grp = self.layouts, self.grp
        flips, self.isum, self.asum = extension_sums(self.topo, self.Vl, self.Fl, self.uv, self.qf, grp, k)
        # what the moved faces took from the chart they left (group 2 i's faces left chart b, 2 i + 1's chart a)
        old, old_area = self._old_iso()
        other = grp ^ 1
        self.isum_out = np.bincount(other, weights=np.where(np.isfinite(old), old, 0.0) * old_area, minlength=k)
        self.asum_out = np.bincount(other, weights=old_area, minlength=k)
        isum0 = np.array([lay.isum[c] for c in self.ids])
        area0 = np.array([lay.area[c] for c in self.ids])
        mean = (isum0 - self.isum_out + self.isum) / np.maximum(area0 - self.asum_out + self.asum, 1e-300)
        ok = (flips == 0) & (mean <= bound)
        gained = ok & (np.bincount(grp, minlength=k) > 0)  # a chart that only gave faces away: no new edge
        if gained.any():
            ok[gained] = self._crossings(np.flatnonzero(gained)) == 0
        return ok

    def _old_iso(self) -> tuple[np.ndarray, np.ndarray]:
        """Per moved face: its iso and area in the layout of the chart it leaves."""
        qf = self.qf
        corners = self.layouts.uv[(3 * qf[:, None] + np.arange(3)).ravel()]
        iso, area, _ = true_scale_iso(self.topo.V, self.topo.F[qf], corners, np.arange(3 * len(qf)).reshape(-1, 3))
        return iso, area

    def _crossings(self, which: np.ndarray) -> np.ndarray:
        """Crossing pairs of border edges, with a moved face's edge among them, and border vertices touching
        themselves where a moved face has a corner, of the new charts ``which`` (:func:`merge.new_edge_crossings`)."""
        C = self.layouts.uv.copy()
        C[(3 * self.qf[:, None] + np.arange(3)).ravel()] = self.uv[self.Fl].reshape(-1, 2)
        faces = np.concatenate([self.sides[i] for i in which])
        fgroup = np.repeat(np.arange(len(which)), [len(self.sides[i]) for i in which])
        h = (3 * faces[:, None] + np.arange(3)).ravel()
        hgroup = np.repeat(fgroup, 3)
        moved = np.zeros(len(self.topo.F), dtype=bool)
        moved[self.qf] = True
        return new_edge_crossings(self.topo, C, h, hgroup, np.repeat(moved[faces], 3), ~self.glued[h], len(which))

    def keep(self, ok: np.ndarray) -> None:
        """The layouts of the proposals ``ok`` (per proposal) kept: the moved faces' corners, the new sums."""
        lay = self.layouts
        for i in np.flatnonzero(ok):
            for g in (2 * i, 2 * i + 1):
                s = self.grp == g
                lay.uv[(3 * self.qf[s, None] + np.arange(3)).ravel()] = self.uv[self.Fl[s]].reshape(-1, 2)
                c = int(self.ids[g])
                lay.isum[c] += float(self.isum[g] - self.isum_out[g])
                lay.area[c] += float(self.asum[g] - self.asum_out[g])


def _shortest_path(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, allowed: np.ndarray, s: int, t: int
                   ) -> np.ndarray:
    """The vertices of a shortest path from s to t through ``allowed`` vertices (CSR graph, edge lengths ``data``;
    the compiled ``grow.dijkstra``), s first; empty when t cannot be reached."""
    n = len(indptr) - 1
    dist, prev = np.full(n, np.inf), np.full(n, -1, dtype=np.int64)
    dijkstra(indptr, indices, data, s, dist, prev, allowed, t)
    if not np.isfinite(dist[t]):
        return np.zeros(0, dtype=np.int64)
    path = [t]
    while path[-1] != s:
        path.append(int(prev[path[-1]]))
    return np.array(path[::-1], dtype=np.int64)
