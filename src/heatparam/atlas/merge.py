"""Merging charts while the merged chart's quick flattening stays bijective and within the bound.

The segmentation's step 3 (``atlas.segment``): the paper's future work turned around, a union of two neighbouring
charts is kept only while its layout stays bijective and within the bound. Two charts are glued along one stretch of
their common border (``atlas.stretches``: longest first, ending at cone points), so a chart stays a disk. A merge
is tested by extending the larger chart's layout over the smaller one (LSCM of the smaller chart with the stretch
pinned where the larger one has it: the cost is the smaller chart's); where that cannot decide (the stretch is not
one arc of both borders) the union is flattened whole and its disk test decides. Each chart keeps the layout its
last passed test checked (:class:`Layouts`), the joint polish's start.
"""

from __future__ import annotations

import numpy as np

from heatparam.atlas.chart_topology import Topology, chart_mesh
from heatparam.atlas.flatten import Flattenings, crossings_per_chart, flatten_charts, lscm_groups
from heatparam.atlas.stretches import border_stretches, half_path
from heatparam.mesh.topology import unique_ints, unique_inverse
from heatparam.metrics import corner_angles, true_scale_iso, wrapped

__all__ = ["Layouts", "RETRY_GROWTH", "extension_sums", "merge", "neighbour_pins", "new_edge_crossings"]

RETRY_GROWTH = 1.25  # a failed merge is tried again once one side has grown by this factor


class Layouts:
    """Every chart's checked layout during the segmentation, kept per face corner (``uv`` (3m,2), row ``3 f + j``),
    with its sums for the isometric distortion (Σ area · iso over its faces, Σ area) and whether it was checked
    (bijective and within the bound); chart ids as in :func:`_merge`."""

    def __init__(self, m: int):
        self.uv = np.zeros((3 * m, 2))
        self.isum: dict[int, float] = {}
        self.area: dict[int, float] = {}
        self.ok: dict[int, bool] = {}

    def add(self, ids: list[int], charts: list[np.ndarray], fl: Flattenings, which: list[int], ok: list[bool]
            ) -> None:
        """Charts ``ids`` (faces ``charts[i]`` for i in ``which``) laid out as charts ``which`` of the flattenings
        ``fl`` (of all of ``charts``); ``ok``: each was checked."""
        iso, area, _ = true_scale_iso(fl.Vl, fl.Fl, fl.uv)  # a checked chart has no flipped face: all finite
        fg = np.repeat(np.arange(len(charts)), np.diff(fl.face_start))
        isum = np.bincount(fg, weights=np.where(np.isfinite(iso), iso, 0.0) * area, minlength=len(charts))
        asum = np.bincount(fg, weights=area, minlength=len(charts))
        for c, i, o in zip(ids, which, ok, strict=True):
            corners = (3 * charts[i][:, None] + np.arange(3)).ravel()
            self.uv[corners] = fl.uv[fl.Fl[fl.face_start[i]:fl.face_start[i + 1]]].reshape(-1, 2)
            self.isum[c], self.area[c], self.ok[c] = float(isum[i]) if o else np.inf, float(asum[i]), bool(o)

    def relabel(self, ids: np.ndarray) -> None:
        """The charts renumbered: chart i is the one that was ``ids[i]``."""
        for d in (self.isum, self.area, self.ok):
            old = dict(d)
            d.clear()
            d.update((i, old[int(c)]) for i, c in enumerate(ids))

    def checked(self) -> np.ndarray:
        """(k,) bool per chart: its layout was checked."""
        return np.array([self.ok[c] for c in range(len(self.ok))], dtype=bool)

    def iso(self) -> np.ndarray:
        """(k,) per chart: the area-weighted isometric distortion of its layout (inf where not checked)."""
        return np.array([self.isum[c] / self.area[c] if self.ok[c] else np.inf for c in range(len(self.ok))])


def merge(topo: Topology, chart: np.ndarray, glued: np.ndarray, bound: float, layouts: Layouts,
          stop_at: int | None = None) -> tuple[np.ndarray, np.ndarray, int, int]:
    """:class:`Merging` run to its end: (chart (m,) relabelled 0..k-1, glued (3m,) (the same array, the kept
    stretches glued), merges kept, merges tested)."""
    return Merging(topo, chart, glued, layouts, bound, stop_at=stop_at).run()


class Merging:
    """Greedy merges in rounds (small unions first, then the longest common border): each round picks pairs of
    charts not picked yet in it and tests all their unions at once (:meth:`extension_tests`: the smaller chart laid
    out against the larger one's layout, the stretch's vertices pinned there); a merge is kept when the union's
    layout is bijective and within ``bound``; stops early at ``stop_at`` charts. A pair with a chart whose layout
    was never checked, or whose extension is undecided, and every pair under a cap, is tested by flattening the
    whole union (:meth:`union_tests`). ``chart`` (m,) and ``glued`` (3m,) are updated in place, ``layouts`` too.

    (Letting a chart join up to 4 of a round's unions, one of them kept, was measured: fewer rounds, more faces
    per solve, no faster on cow or 3holes and 34-40 charts instead of 34.)"""

    def __init__(self, topo: Topology, chart: np.ndarray, glued: np.ndarray, layouts: Layouts, bound: float, *,
                 stop_at: int | None = None):
        self.topo, self.chart, self.glued, self.layouts = topo, chart, glued, layouts
        self.bound, self.stop_at = bound, stop_at
        self.members = {int(c): np.flatnonzero(chart == c) for c in np.unique(chart)}
        self.failed: dict = {}  # (a, b) -> (their sizes when the merge failed, the stretch tried)
        self.merges = self.tests = 0

    def run(self) -> tuple[np.ndarray, np.ndarray, int, int]:
        """Rounds until no pair is left to test (or ``stop_at`` is reached); the result as :func:`merge`'s."""
        h_all = np.flatnonzero(self.topo.opp >= 0)
        while self.stop_at is None or len(self.members) > self.stop_at:
            picked = self._pick(h_all)
            if not picked:
                break
            ok = self._test(picked)
            self.tests += len(picked)
            self._apply(picked, ok)
        ids, chart = np.unique(self.chart, return_inverse=True)  # relabel 0..k-1
        self.layouts.relabel(ids)
        return chart.astype(np.int64), self.glued, self.merges, self.tests

    def _pick(self, h_all: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
        """A round's pairs (a, b, the stretch of a's half-edges to glue), each chart in one pair at most."""
        chart, opp, members = self.chart, self.topo.opp, self.members
        h = h_all[chart[h_all // 3] < chart[opp[h_all] // 3]]  # candidate pairs with their common border length
        if not len(h):
            return []
        ca, cb = chart[h // 3], chart[opp[h] // 3]
        base = int(chart.max()) + 1
        uk, _, inv = unique_inverse(ca * base + cb)
        length = np.bincount(inv, weights=self.topo.hlen[h])
        size = np.array([len(members[int(x)]) for x in (uk // base)]) + np.array(
            [len(members[int(x)]) for x in (uk % base)])
        # cheap tests first (small unions), longest common border first among equals: the big charts are
        # flattened once they have absorbed their small neighbours
        order = np.lexsort((-length, np.ceil(np.log2(size))))
        grouped = np.argsort(inv, kind="stable")
        starts = np.r_[0, np.cumsum(np.bincount(inv, minlength=len(uk)))]
        touched: set = set()
        picked = []
        for i in order:
            a, b = divmod(int(uk[i]), base)
            if a in touched or b in touched:
                continue
            st = self._stretch(a, b, h[grouped[starts[i]:starts[i + 1]]])
            if st is not None:
                picked.append((a, b, st))
                touched.update((a, b))
        return picked

    def _stretch(self, a: int, b: int, common: np.ndarray) -> np.ndarray | None:
        """The stretch of the common border ``common`` to try gluing a and b along, or None (not now)."""
        prev = self.failed.get((a, b))
        tries = 0
        if (prev is not None and len(self.members[a]) < RETRY_GROWTH * prev[0]
                and len(self.members[b]) < RETRY_GROWTH * prev[1]):
            # failed before, and neither side has grown enough since to change the answer much; under a chart
            # cap the pair's other common stretches are tried in turn (longest first)
            if self.stop_at is None:
                return None
            tries = prev[2] + 1
        stretches = border_stretches(self.topo, common)
        if self.stop_at is not None:  # under a cap: also the first half of each stretch (a union that gluing a
            stretches += [half_path(self.topo, st) for st in stretches if len(st) > 1]  # whole one closes up)
        return stretches[tries] if tries < len(stretches) else None

    def _test(self, picked: list) -> np.ndarray:
        """(k,) bool: each picked union passes, by extension where both charts were checked, else whole."""
        ok = np.zeros(len(picked), dtype=bool)
        # under a cap every union is flattened whole: the last merges toward the cap need both sides free (a torus
        # capped at 2 charts stopped at 3 with extensions)
        ready = self.layouts.ok
        extend = [self.stop_at is None and ready[a] and ready[b] for a, b, _ in picked]
        pinned = [p for p, e in enumerate(extend) if e]
        whole = [p for p, e in enumerate(extend) if not e]
        if pinned:
            ok[pinned], undecided = self.extension_tests([picked[p] for p in pinned])
            whole += [p for p, u in zip(pinned, undecided, strict=True) if u]
        if whole:
            ok[whole] = self.union_tests([picked[p] for p in whole])
        return ok

    def _apply(self, picked: list, ok: np.ndarray) -> None:
        """Keep the passed merges (b joins a, the stretch glued); remember the failed ones."""
        opp, members, failed = self.topo.opp, self.members, self.failed
        for (a, b, st), good in zip(picked, ok, strict=True):
            if self.stop_at is not None and len(members) <= self.stop_at:
                break
            if good:
                self.glued[st] = True
                self.glued[opp[st]] = True
                self.chart[members[b]] = a
                members[a] = np.sort(np.concatenate([members[a], members[b]]))
                del members[b]
                self.merges += 1
            else:
                prev = failed.get((a, b))
                again = prev is not None and self.stop_at is not None and prev[:2] == (len(members[a]),
                                                                                        len(members[b]))
                failed[(a, b)] = (len(members[a]), len(members[b]), prev[2] + 1 if again else 0)

    def union_tests(self, picked: list) -> np.ndarray:
        """Each picked pair (a, b, stretch) tested by flattening the whole union (LSCM, :func:`flatten_charts`); the
        layouts of the unions that pass are kept under a's id (b's entries go stale with b). (k,) bool."""
        g = _with_stretches(self.topo, self.glued, picked)
        unions = [np.concatenate([self.members[a], self.members[b]]) for a, b, _ in picked]
        fl = flatten_charts(self.topo, unions, g, self.bound)
        ok = fl.ok(self.bound)
        passed = np.flatnonzero(ok).tolist()
        self.layouts.add([picked[i][0] for i in passed], unions, fl, passed, [True] * len(passed))
        return ok

    def extension_tests(self, picked: list) -> tuple[np.ndarray, np.ndarray]:
        """Each picked pair (a, b, stretch) of checked charts tested by extending the larger chart's layout over
        the smaller: LSCM of the smaller chart alone with the stretch's vertices pinned where the larger chart has
        them (all the round's smaller charts in one solve). The union passes when no face of the smaller chart
        flips, its area-weighted isometric distortion (both charts' faces) is within the bound and no two edges of
        its border cross. Cost ∝ the smaller chart, where flattening the union costs ∝ both (docs/history.md §21). The
        layouts of the unions that pass are kept under a's id. Returns (passed (k,) bool, undecided (k,) bool: the
        stretch is not one arc of both charts' borders — the union would not be a disk — or the shared solve
        failed; :meth:`_test` flattens those unions whole)."""
        ext = _Extensions(self.topo, self.glued, self.layouts, self.members, picked)
        k = len(picked)
        ok = np.zeros(k, dtype=bool)
        try:
            uv = lscm_groups(ext.Vl, ext.Fl, ext.grp, ext.rows, ext.vals, self.topo.degenerate[ext.qf])
        except (RuntimeError, ValueError):
            return ok, np.ones(k, dtype=bool)  # one degenerate chart spoils the shared solve: each union whole
        if not np.isfinite(uv).all():
            return ok, np.ones(k, dtype=bool)
        grp = ext.grp
        flips, isum, asum = extension_sums(self.topo, ext.Vl, ext.Fl, uv, ext.qf, grp, k)
        lay = self.layouts
        mean = (np.array([lay.isum[c] for c in ext.big]) + isum) / np.maximum(
            np.array([lay.area[c] for c in ext.big]) + asum, 1e-300)
        cand = (flips == 0) & (mean <= self.bound) & ~ext.undecided
        if cand.any():
            cand[cand] = self._border_crossings(ext, uv[ext.Fl], cand) == 0
        for i in np.flatnonzero(cand):
            a = picked[i][0]
            s = slice(int(np.searchsorted(grp, i)), int(np.searchsorted(grp, i + 1)))
            lay.uv[(3 * ext.qf[s, None] + np.arange(3)).ravel()] = uv[ext.Fl[s]].reshape(-1, 2)
            lay.isum[a] = lay.isum[ext.big[i]] + float(isum[i])
            lay.area[a] = lay.area[ext.big[i]] + float(asum[i])
            lay.ok[a] = True  # the larger chart's corners are in place already (under a's id or b's)
        return cand, ext.undecided

    def _border_crossings(self, ext: _Extensions, Uq: np.ndarray, which: np.ndarray) -> np.ndarray:
        """Pairs of crossing border edges of each union in ``which`` (its larger chart at ``layouts``, its smaller
        chart's faces ``ext.qf`` at the corner UVs ``Uq`` (len(qf),3,2)); (which.sum(),). The larger chart's
        border crosses nothing of its own: only pairs with a new edge can cross, so of its edges only those within
        the new edges' bounding box are checked."""
        idx = np.flatnonzero(which)
        k = len(idx)
        sel = np.isin(ext.grp, idx)
        big = [self.members[ext.big[i]] for i in idx]
        fb = np.concatenate(big)  # the larger charts' faces (UVs in the layouts)
        gb = np.repeat(np.arange(k), [len(f) for f in big])
        gq = np.searchsorted(idx, ext.grp[sel])  # the smaller charts' faces (new UVs)
        faces = np.concatenate([fb, ext.qf[sel]])
        fgroup = np.concatenate([gb, gq])
        new = np.r_[np.zeros(len(fb), dtype=bool), np.ones(len(gq), dtype=bool)]
        C = self.layouts.uv.copy()
        C[(3 * ext.qf[sel, None] + np.arange(3)).ravel()] = Uq[sel].reshape(-1, 2)
        inner = _with_stretches(self.topo, self.glued, [ext.picked[i] for i in idx])
        h = (3 * faces[:, None] + np.arange(3)).ravel()
        hgroup, hnew = np.repeat(fgroup, 3), np.repeat(new, 3)
        return new_edge_crossings(self.topo, C, h, hgroup, hnew, ~inner[h], k)


class _Extensions:
    """The shared LSCM problem of a round's extension tests: the smaller charts' meshes side by side (``Vl``,
    ``Fl``; faces ``qf`` of test ``grp``), the pins (``rows`` at ``vals``: the stretch corners where the larger
    chart has them), the larger chart of each test (``big``) and the tests left undecided (the stretch is not one
    arc of both borders)."""

    def __init__(self, topo: Topology, glued: np.ndarray, layouts: Layouts, members: dict, picked: list):
        opp = topo.opp
        k = len(picked)
        self.picked = picked
        self.big, small, hq = [], [], []  # per test: the larger chart, the smaller, the smaller side's stretch
        for a, b, st in picked:  # st lies in chart a, opp[st] in chart b
            if len(members[a]) >= len(members[b]):
                self.big.append(a), small.append(b), hq.append(opp[st])
            else:
                self.big.append(b), small.append(a), hq.append(st)
        self.qf = np.concatenate([members[c] for c in small])  # each sorted: (test, face) keys ascend
        self.grp = np.repeat(np.arange(k), np.array([len(members[c]) for c in small], dtype=np.int64))
        self.Vl, self.Fl, _ = chart_mesh(topo, self.qf, glued, self.grp)
        self._pins(topo, layouts, hq, k)

    def _pins(self, topo: Topology, layouts: Layouts, hq: list, k: int) -> None:
        """Each stretch half-edge's two corners on the smaller side take the larger side's corner UVs."""
        hs = np.concatenate(hq)
        hg = np.repeat(np.arange(k), [len(x) for x in hq])
        pos = np.searchsorted(self.grp * len(topo.F) + self.qf, hg * len(topo.F) + hs // 3)
        rows, vals = neighbour_pins(topo, self.Fl, pos, hs, layouts.uv)
        # the union is a disk when the stretch is one arc of both borders: n + 1 corners of each chart along its n
        # edges. A chart with an inner seam of its own ending on the stretch has two corners there (the smaller
        # chart: two rows; the larger: two places, or one row pinned at two places); gluing would close the seam's
        # mouth into a hole. Such a union is flattened whole instead (undecided: its disk test decides)
        ha, hb = topo.ends()
        pv = np.concatenate([ha[hs], hb[hs]])  # the vertex of each pin
        pg = np.concatenate([hg, hg])
        _, place = _places(pg, pv, vals)
        p_corners = np.bincount(pg[place], minlength=k)
        o = np.argsort(rows, kind="stable")
        rows, vals, pg = rows[o], vals[o], pg[o]
        first = np.r_[True, rows[1:] != rows[:-1]]
        q_corners = np.bincount(pg[first], minlength=k)
        arc = np.bincount(hg, minlength=k) + 1
        self.undecided = (q_corners != arc) | (p_corners != arc)
        self.rows, self.vals = rows[first], vals[first]


def neighbour_pins(topo: Topology, Fl: np.ndarray, pos: np.ndarray, hs: np.ndarray, corner_uv: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The pins of an extension: each half-edge ``hs`` (k,) of a face laid out as row ``pos`` (k,) of ``Fl`` meets
    a face whose corners lie at ``corner_uv`` (3m,2, row ``3 f + j``); its two corners' rows (2k,) take that face's
    UVs there (2k,2): corner j of the face is corner jp + 1 of the one across half-edge jp, corner j + 1 is jp."""
    kq, hp = hs % 3, topo.opp[hs]
    fp, jp = hp // 3, hp % 3
    rows = np.concatenate([Fl[pos, kq], Fl[pos, (kq + 1) % 3]])
    vals = np.concatenate([corner_uv[3 * fp + (jp + 1) % 3], corner_uv[3 * fp + jp]])
    return rows, vals


def extension_sums(topo: Topology, Vl: np.ndarray, Fl: np.ndarray, uv: np.ndarray, qf: np.ndarray,
                   grp: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per group of an extension's faces (mesh faces ``qf`` (q,) laid out as the rows of ``Fl`` at ``uv``, group
    ``grp`` (q,) of k): (flipped faces, Σ area · iso over the others, Σ area), each (k,). A zero-area face has no
    finite iso: it is flipped only where its (thin) UV triangle is."""
    iso, area, sa = true_scale_iso(Vl, Fl, uv)
    flips = np.bincount(grp, weights=~np.isfinite(iso) & ((sa <= 0) | ~topo.degenerate[qf]), minlength=k)
    isum = np.bincount(grp, weights=np.where(np.isfinite(iso), iso, 0.0) * area, minlength=k)
    return flips, isum, np.bincount(grp, weights=area, minlength=k)


def _with_stretches(topo: Topology, glued: np.ndarray, picked: list) -> np.ndarray:
    """``glued`` (3m,) with the stretch of every picked pair (a, b, stretch) glued too, both sides (a copy)."""
    g = glued.copy()
    for _, _, st in picked:
        g[st] = True
        g[topo.opp[st]] = True
    return g


def _places(group: np.ndarray, vertex: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners (group (N,), mesh vertex (N,), UV (N,2)) told apart by where they are: corners welded in one chart
    carry bit-identical UVs, so (group, vertex, UV bits) names a chart row. Returns each corner's place id (N,),
    numbered in (group, vertex, UV bits) order, and the first corner of each place."""
    bits = np.ascontiguousarray(uv).view(np.int64).reshape(-1, 2)
    o = np.lexsort((bits[:, 1], bits[:, 0], vertex, group))
    change = np.r_[True, (group[o][1:] != group[o][:-1]) | (vertex[o][1:] != vertex[o][:-1])
                   | (bits[o][1:] != bits[o][:-1]).any(axis=1)]
    ids = np.empty(len(o), dtype=np.int64)
    ids[o] = np.cumsum(change) - 1
    return ids, o[change]


def new_edge_crossings(topo: Topology, C: np.ndarray, h: np.ndarray, hgroup: np.ndarray, hnew: np.ndarray,
                       border: np.ndarray, k: int) -> np.ndarray:
    """(k,) per union: pairs of crossing border edges, plus border vertices where it touches itself. Its faces'
    half-edges ``h`` (union ``hgroup``, ``hnew``: of its new faces, ``border``: on its border) at the corner UVs
    ``C`` (3m,2); edges of the rest are kept only within the bounding box of the union's new edges, vertices only
    where a new face has a corner."""
    wraps = _new_wraps(topo, C, h, hgroup, hnew, border, k)
    h, hgroup, hnew = h[border], hgroup[border], hnew[border]
    tail = h - h % 3 + (h % 3 + 1) % 3
    A, B = C[h], C[tail]
    lo, hi = np.full((k, 2), np.inf), np.full((k, 2), -np.inf)
    np.minimum.at(lo, hgroup[hnew], np.minimum(A, B)[hnew])
    np.maximum.at(hi, hgroup[hnew], np.maximum(A, B)[hnew])
    near = hnew | ((np.maximum(A, B) >= lo[hgroup]) & (np.minimum(A, B) <= hi[hgroup])).all(axis=1)
    h, hgroup, A, B = h[near], hgroup[near], A[near], B[near]
    ha, hb = topo.ends()
    # endpoints: one index per (union, vertex, place): welded corners have bit-identical UVs
    pts = np.concatenate([A, B])
    pgroup = np.concatenate([hgroup, hgroup])
    ids, first = _places(pgroup, np.concatenate([ha[h], hb[h]]), pts)
    E = ids.reshape(2, -1).T
    return wraps + crossings_per_chart(pts[first], None, E[:, 0], E[:, 1], np.ones(len(E), dtype=bool),
                                       pgroup[first], np.ones(k, dtype=bool), k)


def _new_wraps(topo: Topology, C: np.ndarray, h: np.ndarray, hgroup: np.ndarray, hnew: np.ndarray,
               border: np.ndarray, k: int) -> np.ndarray:
    """(k,) border vertices of each union, of those where a new face has a corner, with 2π or more of corner angles:
    its border touches or passes itself there (:func:`heatparam.metrics.wrapped`). Every face of the union there
    counts, summed per place (corners welded in one chart carry bit-identical UVs)."""
    ha = topo.ends()[0]  # corner h is at the vertex its half-edge leaves
    key = hgroup * len(topo.V) + ha[h]
    near = np.isin(key, unique_ints(key[hnew]))
    h, hgroup, border = h[near], hgroup[near], border[near]
    T = np.stack([C[h], C[h - h % 3 + (h % 3 + 1) % 3], C[h - h % 3 + (h % 3 + 2) % 3]], axis=1)
    ids, first = _places(hgroup, ha[h], C[h])
    s = np.bincount(ids, weights=corner_angles(T)[:, 0])
    on_border = np.zeros(len(s), dtype=bool)
    on_border[ids[border]] = True
    return np.bincount(hgroup[first][on_border & wrapped(s)], minlength=k)
