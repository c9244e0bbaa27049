"""Charts of one clean component: normal-cone region growing, then merges checked by a flattening.

1. Growing (like D-Charts / xatlas): farthest-point seeds on the face graph grow together, a face joining the
   chart whose mean normal it deviates least from, while that deviation stays within ``cone`` degrees; sharp
   creases (dihedral angle above ``crease``) are never crossed, and a face joins only where the chart stays a
   topological disk (it touches the chart along one edge with its third vertex new, or along two edges).
   Faces left over seed further rounds.
2. Each region is checked by a quick flattening (LSCM at true area): a region whose map has a flipped face,
   crossing boundaries or isometric distortion above the bound is split — grown again at the same cone from
   ``SPLIT_SEEDS`` farthest seeds of its own (with half the cone when it stays one piece) — and its pieces are
   checked in turn (the paper's future work b: split where the flattening is not bijective or exceeds the bound).
3. Merging (the paper's future work turned around: a merge is kept only while the flattening stays bijective and
   within the bound): neighbouring charts are glued along one stretch of their common border (longest first;
   stretches end at cone points, vertices of large angle defect such as a cube's corners), the rest of the
   common border stays a seam inside the merged chart. A chart is therefore always a disk: a cube becomes a
   net, a cylinder's side an unrolled rectangle. A merge is tested by extending the larger chart's layout over
   the smaller one (LSCM of the smaller chart with the stretch pinned where the larger chart has it): the cost of
   a test is the smaller chart's, where flattening the whole union cost both (cow: 97k faces flattened in 556
   tests → 21k; BENCHMARKS §21); where the stretch is not one arc of both borders (a chart's own seam ends on it:
   the union would have a hole) the union is flattened whole and its disk test decides. Every chart keeps the
   layout its last test checked (``Segmentation.corner_uv``).

A chart is a set of faces plus the half-edges glued inside it (``Segmentation.glued``).
"""

from __future__ import annotations

import functools
import heapq
import math
import time
from dataclasses import dataclass

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from heatparam.atlas.repair import half_edge_opposites
from heatparam.errors import HeatparamError
from heatparam.mesh.topology import unique_ints, unique_inverse

__all__ = ["DEFAULT_CONE", "DEFAULT_CREASE", "Flattenings", "Segmentation", "Topology", "chart_iso", "chart_mesh",
           "flatten_charts", "proxy_bound", "quick_flatten", "segment"]

DEFAULT_CONE = 60.0  # degrees: normal-cone half angle of a grown region
DEFAULT_CREASE = 60.0  # degrees: dihedral angle above which an edge is a crease (never crossed while growing)
CONE_DEFECT = 0.3  # radians: vertices with a larger |angle defect| end a glued stretch (cube corners: pi/2)
RETRY_GROWTH = 1.25  # a failed merge is tried again once one side has grown by this factor
#: A region that fails its check is grown again at the same cone from this many farthest seeds of its own. Until
#: 2026-12-04 it was grown again with half the cone (one seed, leftovers seeding more), which shattered cow's two
#: largest failing regions (1275 and 1142 faces) into 53 and 48 pieces for the merge to glue back: cow 402 grown
#: regions and 551 merge tests → 220 and 313, 35 → 30 charts, seam/√A 18.37 → 16.56, iso mean 1.0255 → 1.0313;
#: 3holes 15 → 12 charts, 13.79 → 10.70 (BENCHMARKS §22)
SPLIT_SEEDS = 3
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

    def ends(self) -> tuple[np.ndarray, np.ndarray]:
        """(3m,) start and end vertex of every half-edge ``3 f + j`` (F[f, j] → F[f, (j+1) % 3]), made once."""
        if not hasattr(self, "_ends"):
            self._ends = (self.F.ravel(), self.F[:, [1, 2, 0]].ravel())
        return self._ends

    def cones(self) -> list[bool]:
        """Per vertex: a cone point (|angle defect| > CONE_DEFECT), as a list, made once."""
        if not hasattr(self, "_cones"):
            self._cones = (np.abs(self.defect) > CONE_DEFECT).tolist()
        return self._cones

    def centroids(self) -> np.ndarray:
        """(m,3) face centroids, made once."""
        if not hasattr(self, "_centroids"):
            self._centroids = self.V[self.F].mean(axis=1)
        return self._centroids

    def double_neighbours(self) -> bool:
        """Whether two faces are neighbours across two of their edges (a two-faced pocket), found once."""
        if not hasattr(self, "_double"):
            nb = np.where(self.opp >= 0, self.opp // 3, -1).reshape(-1, 3)
            p, q = nb[:, [0, 0, 1]], nb[:, [1, 2, 2]]  # each face's three pairs of neighbours
            self._double = bool(((p == q) & (p >= 0)).any())
        return self._double

    def lists(self) -> tuple[list, list, list, list, list]:
        """For the region growing's loop, as Python lists, made once: F, normals, areas, and per face its three
        neighbours across its edges (m where there is none: a sentinel row) and the same with the creases' m."""
        if not hasattr(self, "_lists"):
            m = len(self.F)
            nb = np.where(self.opp >= 0, self.opp // 3, m)
            cross = np.where(self.crease, m, nb)
            self._lists = (self.F.tolist(), self.normals.tolist(), self.areas.tolist(), nb.reshape(m, 3).tolist(),
                           cross.reshape(m, 3).tolist())
        return self._lists

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
    """chart (m,) int64 chart id per face (0..k-1); glued (3m,) bool, half-edges welded inside their chart;
    corner_uv (3m,2) each face corner's place in its chart's checked layout (row ``3 f + j``: corner j of face f);
    checked (k,) bool, the charts whose layout ``corner_uv`` is bijective and within the bound; iso (k,) its
    area-weighted isometric distortion (inf where not checked)."""

    chart: np.ndarray
    glued: np.ndarray
    stats: dict
    corner_uv: np.ndarray | None = None
    checked: np.ndarray | None = None
    iso: np.ndarray | None = None


def chart_mesh(topo: Topology, faces: np.ndarray, glued: np.ndarray, group: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chart's own mesh: corners welded across its glued half-edges only.

    group : (len(faces),) optional chart of each face: several charts at once, never welded to each other (the mesh
    has one component per chart); a face may then appear in several charts (once in each).

    Returns Vl (nl,3), Fl (k,3) local triangles (row i = faces[i]), vert (nl,) component vertex of each row.
    """
    F = topo.F
    k = len(faces)
    h = (3 * faces[:, None] + np.arange(3)).ravel()
    o = topo.opp[h]
    ok = (o >= 0) & glued[h]
    a = np.repeat(np.arange(k), 3)  # the row of each half-edge
    group = np.zeros(k, dtype=np.int64) if group is None else group
    row = np.full(len(F), -1, dtype=np.int64)
    row[faces] = np.arange(k)
    if (row[faces] == np.arange(k)).all():  # each face once: its twin's row by table, kept within its group
        b = row[np.maximum(o, 0) // 3]
        ok &= b >= 0
        ok[ok] = group[b[ok]] == group[a[ok]]
        b = np.where(ok, b, -1)
    else:  # rows found by (group, face): a face sits in several groups
        key = group * len(F) + faces
        order = np.argsort(key, kind="stable")
        q = np.repeat(group, 3) * len(F) + np.maximum(o, 0) // 3
        pos = np.minimum(np.searchsorted(key[order], q), k - 1)
        b = np.where(ok & (key[order][pos] == q), order[pos], -1)
        ok &= b >= 0
    j, kk = h[ok] % 3, o[ok] % 3
    a, b = a[ok], b[ok]
    # corners welded across a glued half-edge: corner j of row a is corner kk+1 of row b, corner j+1 is corner kk.
    # Around a vertex the welds form paths and cycles (each corner has one outgoing and one incoming half-edge:
    # at most one successor and one predecessor), labelled here by their smallest corner with pointer jumping
    # (2^t ≥ the longest fan), numbered by that corner: scipy's connected_components' labels, 3x faster here
    src = np.concatenate([3 * a + j, 3 * b + kk])
    dst = np.concatenate([3 * b + (kk + 1) % 3, 3 * a + (j + 1) % 3])
    lab = np.arange(3 * k)
    nf, nb = lab.copy(), lab.copy()
    nf[src] = dst
    nb[dst] = src
    fan = int(np.bincount(F[faces].ravel()).max()) if k else 1
    for _ in range(max(1, (fan - 1).bit_length())):
        lab = np.minimum(lab, np.minimum(lab[nf], lab[nb]))
        nf, nb = nf[nf], nb[nb]
    root = lab == np.arange(3 * k)
    first = np.flatnonzero(root)  # the first corner of each component
    lab = (np.cumsum(root) - 1)[lab]
    Fl = lab.reshape(k, 3).astype(np.int64)
    vert = F[faces].ravel()[first]
    return topo.V[vert], Fl, vert


def chart_iso(V: np.ndarray, F: np.ndarray, uv: np.ndarray, fgroup: np.ndarray, k: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """Per chart (``fgroup`` (m,) of each face, k charts): the area-weighted mean of ``metrics.true_scale_iso``
    over its positive faces (inf when it has none) and its count of flipped or collapsed faces; (k,), (k,)."""
    from heatparam.metrics import true_scale_iso

    fi, area, sa = true_scale_iso(V, F, uv)
    good = np.isfinite(fi)
    w = np.where(good, area, 0.0)
    wsum = np.bincount(fgroup, weights=w, minlength=k)
    mean = np.bincount(fgroup, weights=w * np.where(good, fi, 0.0), minlength=k) / np.maximum(wsum, 1e-300)
    return np.where(wsum > 0, mean, np.inf), np.bincount(fgroup, weights=sa <= 0, minlength=k).astype(np.int64)


@dataclass
class Flattenings:
    """Quick flattenings of k charts at once (:func:`flatten_charts`), over the union of their meshes.

    Vl (nl,3), Fl (ml,3), vert (nl,): :func:`chart_mesh` of all the charts' faces (chart i's faces are rows
    ``face_start[i]:face_start[i+1]``); uv (nl,2) the LSCM layouts at true area; vgroup (nl,) chart of each row;
    iso (k,) area-weighted mean distortion (inf when not flattened), flips (k,), crossings (k,) boundary edge pairs
    crossing (-1: not checked), disk (k,) bool.
    """

    Vl: np.ndarray
    Fl: np.ndarray
    vert: np.ndarray
    uv: np.ndarray
    vgroup: np.ndarray
    face_start: np.ndarray
    iso: np.ndarray
    flips: np.ndarray
    crossings: np.ndarray
    disk: np.ndarray

    def ok(self, bound: float) -> np.ndarray:
        """(k,) bool: a disk whose flattening is bijective and within ``bound``."""
        return self.disk & (self.flips == 0) & (self.crossings == 0) & (self.iso <= bound)

    def chart(self, i: int, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Chart i on its own: (Vl (n_i,3), Fl (m_i,3) local, vert (n_i,), its rows of ``uv`` (nl,2), default the
        LSCM layouts). The rows of every chart are found by one sort, on the first call."""
        if not hasattr(self, "_rows"):
            order = np.argsort(self.vgroup, kind="stable")
            self._rows = (order, np.searchsorted(self.vgroup[order], np.arange(len(self.face_start))))
        order, start = self._rows
        rows = order[start[i]:start[i + 1]]  # ascending: the sort is stable
        Fi = np.searchsorted(rows, self.Fl[self.face_start[i]:self.face_start[i + 1]])
        return self.Vl[rows], Fi, self.vert[rows], (self.uv if uv is None else uv)[rows]


def flatten_charts(topo: Topology, charts: list[np.ndarray], glued: np.ndarray, bound: float = np.inf,
                   want: np.ndarray | None = None) -> Flattenings:
    """LSCM (Lévy et al. 2002) of every chart (face arrays, disjoint), welded across ``glued`` inside each chart,
    all in one sparse solve (two pinned vertices per chart), each oriented like the mesh and scaled to its 3D area.
    Boundary crossings are checked only where the chart is a flip-free disk within ``bound``. want (k,) bool: the
    charts to lay out (default all; the others get their meshes and disk tests only, iso inf)."""
    faces = np.concatenate(charts)
    k = len(charts)
    sizes = np.array([len(c) for c in charts], dtype=np.int64)
    fgroup = np.repeat(np.arange(k), sizes)
    Vl, Fl, vert = chart_mesh(topo, faces, glued, fgroup)
    uv, iso, flips, cross, disk, vgroup = flatten_components(Vl, Fl, fgroup, k, bound, vert, want)
    return Flattenings(Vl, Fl, vert, uv, vgroup, np.r_[0, np.cumsum(sizes)], iso, flips, cross, disk)


def flatten_components(Vl: np.ndarray, Fl: np.ndarray, fgroup: np.ndarray, k: int, bound: float = np.inf,
                       vkey: np.ndarray | None = None, want: np.ndarray | None = None):
    """:func:`flatten_charts` on a mesh whose components are the k groups ``fgroup`` (m,) of faces: (uv (n,2),
    iso (k,), flips (k,), crossings (k,), disk (k,), vgroup (n,)). vkey (n,): a vertex key independent of the rows'
    order (the component's vertex), used to choose the pins; want (k,) bool: the groups to lay out (default all)."""
    n = len(Vl)
    vgroup = np.full(n, -1, dtype=np.int64)
    vgroup[Fl.ravel()] = np.repeat(fgroup, 3)
    a, b = Fl.ravel(), Fl[:, [1, 2, 0]].ravel()
    ue = unique_ints(np.minimum(a, b) * n + np.maximum(a, b))
    euler = (np.bincount(vgroup[vgroup >= 0], minlength=k) - np.bincount(vgroup[ue // n], minlength=k)
             + np.bincount(fgroup, minlength=k))
    disk = euler == 1
    iso, flips, cross = np.full(k, np.inf), np.zeros(k, dtype=np.int64), np.full(k, -1, dtype=np.int64)
    uv = np.zeros((n, 2))
    rev = np.sort(b * n + a)
    q = a * n + b
    bd = rev[np.minimum(np.searchsorted(rev, q), len(rev) - 1)] != q  # boundary half-edges: no twin
    # two pins per chart, far apart and independent of the row order (LSCM's map depends on its pins): the boundary
    # vertex farthest from the one of smallest key, and the one farthest from that
    bv = unique_ints(a[bd])
    gb = vgroup[bv]
    vkey = np.arange(n) if vkey is None else vkey
    p0, _ = _farthest_per_group(Vl, bv, gb, _first_per_group(bv, gb, vkey, k), vkey, k)
    p1, dmax = _farthest_per_group(Vl, bv, gb, p0, vkey, k)
    solve = disk & (p0 >= 0) & (dmax > 0) & (True if want is None else want)
    if not solve.any():
        return uv, iso, flips, cross, disk, vgroup
    sel = solve[fgroup]
    try:
        uv = _lscm(Vl, Fl[sel], p0[solve], p1[solve])
    except HeatparamError:
        if solve.sum() == 1:
            return uv, iso, flips, cross, disk, vgroup
        for i in np.flatnonzero(solve):  # a degenerate chart spoils the shared solve: solve each on its own
            s_i = fgroup == i
            try:
                uv_i = _lscm(Vl, Fl[s_i], p0[i:i + 1], p1[i:i + 1])
            except HeatparamError:
                solve[i] = False
                continue
            uv[vgroup == i] = uv_i[vgroup == i]
        sel = solve[fgroup]
    _true_area(Vl, Fl, uv, fgroup, vgroup, k)
    mean, flips = chart_iso(Vl, Fl, uv, fgroup, k)
    finite = np.bincount(fgroup, weights=~np.isfinite(uv[Fl]).all(axis=(1, 2)), minlength=k) == 0
    iso = np.where(solve & finite, mean, np.inf)
    check = solve & finite & (flips == 0) & (iso <= bound)
    cross[check] = _crossings_per_chart(uv, Fl, a, b, bd, vgroup, check, k)
    return uv, iso, flips, cross, disk, vgroup


def _first_per_group(rows: np.ndarray, grp: np.ndarray, key: np.ndarray, k: int) -> np.ndarray:
    """(k,) the row of smallest ``key`` in each group (-1 for an empty group)."""
    out = np.full(k, -1, dtype=np.int64)
    o = np.lexsort((key[rows], grp))
    first = np.r_[True, grp[o][1:] != grp[o][:-1]] if len(o) else np.zeros(0, bool)
    out[grp[o][first]] = rows[o][first]
    return out


def _farthest_per_group(V, rows, grp, src, key, k) -> tuple[np.ndarray, np.ndarray]:
    """(k,) the row of each group farthest from the group's ``src`` row (ties: smallest key), and that distance."""
    out, dist = np.full(k, -1, dtype=np.int64), np.zeros(k)
    if not len(rows):
        return out, dist
    d = np.linalg.norm(V[rows] - V[src[grp]], axis=1)
    o = np.lexsort((key[rows], -d, grp))
    first = np.r_[True, grp[o][1:] != grp[o][:-1]]
    out[grp[o][first]] = rows[o][first]
    dist[grp[o][first]] = d[o][first]
    return out, dist


def _lscm(Vl: np.ndarray, Fl: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """LSCM (``igl.lscm``: 16.7 ms vs 28.5 ms for our PARDISO LSCM, removed 2026-12-02, on cow's 34 charts at once,
    the same map to 5e-12) of the faces ``Fl`` with the pins p0 at (0,0) and p1 at (1,0); rows no face uses stay
    at 0."""
    import igl

    mark = np.zeros(len(Vl), dtype=bool)
    mark[Fl.ravel()] = True
    used = np.flatnonzero(mark)
    loc = np.full(len(Vl), -1, dtype=np.int64)
    loc[used] = np.arange(len(used))
    puv = np.zeros((len(p0) + len(p1), 2))
    puv[len(p0):, 0] = 1.0
    try:
        res = igl.lscm(Vl[used], loc[Fl], loc[np.concatenate([p0, p1])], puv)
    except (RuntimeError, ValueError) as exc:
        raise HeatparamError(f"LSCM failed: {exc}") from None
    uv = np.zeros((len(Vl), 2))
    uv[used] = np.asarray(res[0] if isinstance(res, tuple) else res, dtype=np.float64)
    if not np.isfinite(uv).all():
        raise HeatparamError("non-finite LSCM layout")
    return uv


def _true_area(Vl, Fl, uv, fgroup, vgroup, k) -> None:
    """In place: mirror each chart whose signed UV area is negative, scale each to its 3D area."""
    u1, u2 = uv[Fl[:, 1]] - uv[Fl[:, 0]], uv[Fl[:, 2]] - uv[Fl[:, 0]]
    sa = np.bincount(fgroup, weights=0.5 * (u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]), minlength=k)
    a3 = np.bincount(fgroup, weights=0.5 * np.linalg.norm(
        np.cross(Vl[Fl[:, 1]] - Vl[Fl[:, 0]], Vl[Fl[:, 2]] - Vl[Fl[:, 0]]), axis=1), minlength=k)
    used = vgroup >= 0
    gi = vgroup[used]
    uv[used, 1] *= np.where(sa < 0, -1.0, 1.0)[gi]
    uv[used] *= np.sqrt(a3 / np.maximum(np.abs(sa), 1e-300))[gi][:, None]


def _crossings_per_chart(uv, Fl, a, b, bd, vgroup, check, k) -> np.ndarray:
    """Boundary crossings of each chart in ``check``, all in one pass: the charts are first set side by side."""
    from heatparam.metrics import crossing_pairs

    E = np.column_stack([a[bd], b[bd]])
    E = E[check[vgroup[E[:, 0]]]]
    rows = unique_ints(E)
    gr = vgroup[rows]
    lo = np.full((k, 2), np.inf)
    hi = np.full((k, 2), -np.inf)
    np.minimum.at(lo, gr, uv[rows])
    np.maximum.at(hi, gr, uv[rows])
    width = np.where(check, hi[:, 0] - lo[:, 0], 0.0)
    step = 1.1 * width + 1e-9 * (float(width.max()) + 1.0)
    shift = np.cumsum(step) - step
    P = uv.copy()
    P[rows, 0] += shift[gr] - lo[gr, 0]
    pairs = crossing_pairs(P, E)
    counts = np.bincount(vgroup[E[pairs[:, 0], 0]], minlength=k) if len(pairs) else np.zeros(k, np.int64)
    return counts[check]


def quick_flatten(Vl: np.ndarray, Fl: np.ndarray) -> tuple[np.ndarray | None, float, bool]:
    """LSCM of a disk, orientation kept, scaled to true area: (uv, iso mean, bijective)."""
    uv, iso, flips, cross, disk, _ = flatten_components(Vl, Fl, np.zeros(len(Fl), dtype=np.int64), 1)
    if not np.isfinite(iso[0]):
        return None, float("inf"), False
    return uv, float(iso[0]), bool(disk[0] and flips[0] == 0 and cross[0] == 0)


@functools.lru_cache(maxsize=4096)
def _first_pick(seed: int, n: int) -> int:
    """The first draw ``np.random.default_rng(seed).integers(n)`` (a Generator costs 0.2 ms to make)."""
    return int(np.random.default_rng(seed).integers(n))


def _seeds(topo: Topology, faces: np.ndarray, k: int, seed: int) -> np.ndarray:
    """k farthest-point seed faces among ``faces`` on the face graph (centroid distances)."""
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
    else:  # f ascends (rows in face order): the CSR arrays directly
        indptr = np.zeros(len(sf) + 1, dtype=np.int32)
        np.cumsum(np.bincount(f, minlength=len(sf)), out=indptr[1:])
        G = sp.csr_matrix((w, g.astype(np.int32), indptr), shape=(len(sf), len(sf)))
    d = dijkstra(G, indices=int(loc[faces[_first_pick(seed, len(faces))]]))
    chosen = [int(np.argmax(np.where(np.isfinite(d), d, -1)))]
    dmin = np.full(len(sf), np.inf)
    while len(chosen) < k:  # (the distances from the last seed chosen are not needed)
        d = dijkstra(G, indices=chosen[-1])
        dmin = np.minimum(dmin, d)
        cand = np.where(np.isfinite(dmin), dmin, -1.0)
        nxt = int(np.argmax(cand))
        if cand[nxt] <= 0:
            break
        chosen.append(nxt)
    return sf[np.array(chosen, dtype=np.int64)]


def grow(topo: Topology, faces: np.ndarray, cone_deg: float, target_faces: int, seed: int = 0) -> list[np.ndarray]:
    """Normal-cone region growing over ``faces``; each returned face array is a topological disk.

    The loop runs on Python lists and floats (the same arithmetic, in the same order, as numpy's on 3-vectors:
    2.2x faster than on numpy scalars); each region's unit mean normal is kept from one growth to the next."""
    m = len(topo.F)
    Fl, nrm, areas, nb, cross = topo.lists()
    push, pop = heapq.heappush, heapq.heappop
    cos_cone = float(np.cos(np.radians(cone_deg)))
    order = np.sort(faces)
    lab = np.full(m + 1, -2, dtype=np.int64)  # row m: the sentinel neighbour (never a region, never free)
    lab[order] = -1  # -1: unassigned and allowed
    label = lab.tolist()
    order = order.tolist()
    nreg = 0
    nsum: list[list[float]] = []
    unit: list[list[float]] = []  # nsum[r] / |nsum[r]|
    vmark: list[set] = []
    nxt = 0  # leftovers are seeded in face order: every face before order[nxt] is assigned

    def normalized(ns: list[float]) -> list[float]:
        length = max(math.sqrt(ns[0] * ns[0] + ns[1] * ns[1] + ns[2] * ns[2]), 1e-300)
        return [ns[0] / length, ns[1] / length, ns[2] / length]

    while True:
        if not nreg:
            k = max(1, int(np.ceil(len(faces) / max(target_faces, 1))))
            seeds = _seeds(topo, faces, k, seed).tolist()
        else:  # leftovers (blocked by the disk rule or the cone): one seed each round, no distance field
            while nxt < len(order) and label[order[nxt]] != -1:
                nxt += 1
            if nxt == len(order):
                break
            seeds = [order[nxt]]
        heap: list = []
        for s in seeds:
            if label[s] != -1:
                continue
            r = nreg
            nreg += 1
            label[s] = r
            nsum.append([x * areas[s] for x in nrm[s]])
            unit.append(normalized(nsum[r]))
            vmark.append(set(Fl[s]))
            ns = nrm[s]
            for o in cross[s]:
                if label[o] == -1:
                    no = nrm[o]
                    push(heap, (1.0 - (no[0] * ns[0] + no[1] * ns[1] + no[2] * ns[2]), o, r))
        while heap:
            cost, g, r = pop(heap)
            if label[g] != -1:
                continue
            nr = unit[r]
            ng = nrm[g]
            c = 1.0 - (ng[0] * nr[0] + ng[1] * nr[1] + ng[2] * nr[2])
            if c > cost + 1e-12:  # stale priority: requeue with the current one
                push(heap, (c, g, r))
                continue
            if 1.0 - c < cos_cone:
                continue
            # disk rule: joined along two edges, or along one with its third vertex new to the region
            f0, f1, f2 = nb[g]
            on0, on1, on2 = label[f0] == r, label[f1] == r, label[f2] == r
            shared = on0 + on1 + on2
            vs = Fl[g]
            if shared == 1:
                if vs[2 if on0 else 0 if on1 else 1] in vmark[r]:  # the vertex opposite the shared edge
                    continue
            elif shared != 2:
                continue
            label[g] = r
            a = areas[g]
            ns = nsum[r]
            x, y, z = ns[0] + ng[0] * a, ns[1] + ng[1] * a, ns[2] + ng[2] * a
            nsum[r] = [x, y, z]
            length = max(math.sqrt(x * x + y * y + z * z), 1e-300)  # normalized(), inlined: the loop's hot spot
            unit[r] = [x / length, y / length, z / length]
            vmark[r].update(vs)
            for o in cross[g]:
                if label[o] == -1:
                    no = nrm[o]
                    push(heap, (1.0 - (no[0] * nr[0] + no[1] * nr[1] + no[2] * nr[2]), o, r))
    lab = np.asarray(label[:m], dtype=np.int64)
    _smooth(topo, lab, faces)
    mine = np.flatnonzero(lab >= 0)  # each region's faces ascending (a stable sort of the face order)
    by = mine[np.argsort(lab[mine], kind="stable")]
    ends = np.cumsum(np.bincount(lab[mine], minlength=nreg))
    return [r for r in np.split(by, ends[:-1]) if len(r)]


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
    if not hasattr(topo, "_vf"):
        order = np.argsort(topo.F.ravel(), kind="stable")
        starts = np.searchsorted(topo.F.ravel()[order], np.arange(len(topo.V) + 1))
        topo._vf = (order // 3, starts)
    fs, st = topo._vf
    around = fs[st[w]:st[w + 1]]
    return bool(((label[around] == r) & (around != skip)).any())


def _stretches(topo: Topology, hs: np.ndarray) -> list[np.ndarray]:
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


def _half_path(topo: Topology, st: np.ndarray) -> np.ndarray:
    """The first half (in path order) of a stretch of consistently oriented half-edges."""
    ha, hb = topo.ends()
    path, _ = _chain(ha[st], hb[st])
    return st[np.array(path[: max(1, len(path) // 2)], dtype=np.int64)]


def proxy_bound(max_distortion: float) -> float:
    """The bound an LSCM layout is held to (``PROXY_SLACK``: the polish lowers LSCM's area distortion)."""
    return 1.0 + PROXY_SLACK * (max_distortion - 1.0)


def segment(topo: Topology, max_distortion: float, max_charts: int | None = None, cone_deg: float = DEFAULT_CONE,
            seed: int = 0, target_faces: int = 2000) -> Segmentation:
    """Charts of one component (module docstring). Each chart's layout (``Segmentation.corner_uv``) is bijective
    and within the bound, except where a region would not flatten even grown at the narrowest cone
    (``Segmentation.checked``)."""
    m = len(topo.F)
    glued = np.zeros(3 * m, dtype=bool)
    bound = proxy_bound(max_distortion)
    charts: list[np.ndarray] = []
    layouts = _Layouts(m)
    stats = {"grown": 0, "regrown": 0, "merges": 0, "merge_tests": 0}
    work = [(np.arange(m), cone_deg, target_faces, False)]
    while work:  # one generation at a time: its regions checked in one flattening (one LSCM solve)
        regions, cones = [], []
        for faces, cone, target, split in work:
            grown = grow(topo, faces, cone, target, seed)
            while split and len(grown) == 1 and cone >= 2.0:  # a failed region that did not split (the border
                cone *= 0.5  # straightening can empty a tiny piece): a narrower cone
                grown = grow(topo, faces, cone, target, seed)
            regions += grown
            cones += [cone] * len(grown)
        work = []
        stats["grown"] += len(regions)
        inside = _glue_inside(topo, np.concatenate(regions))  # welded within each region only (chart_mesh's group)
        fl = flatten_charts(topo, regions, inside, bound)
        ok = fl.ok(bound)
        keep = [bool(ok[i]) or len(reg) == 1 or cone < 2.0 for i, (reg, cone) in enumerate(zip(regions, cones,
                                                                                                 strict=True))]
        kept = [i for i, k in enumerate(keep) if k]
        layouts.add(list(range(len(charts), len(charts) + len(kept))), regions, fl, kept, [ok[i] for i in kept])
        for reg, cone, k in zip(regions, cones, keep, strict=True):
            if k:
                glued |= _glue_inside(topo, reg)
                charts.append(reg)
            else:
                stats["regrown"] += 1
                work.append((reg, cone, -(-len(reg) // SPLIT_SEEDS), True))  # SPLIT_SEEDS seeds of its own
    chart = np.empty(m, dtype=np.int64)
    for i, c in enumerate(charts):
        chart[c] = i
    t = time.perf_counter()
    chart, glued, nmerge, ntest = _merge(topo, chart, glued, bound, layouts)
    stats["capped"] = False
    if max_charts is not None and chart.max() + 1 > max_charts:
        # the user's cap beats the bound: keep merging while the merged chart stays bijective
        chart, glued, n2, t2 = _merge(topo, chart, glued, np.inf, layouts, stop_at=max_charts)
        nmerge, ntest = nmerge + n2, ntest + t2
        stats["capped"] = True
    stats["merge_seconds"] = round(time.perf_counter() - t, 3)
    stats["merges"], stats["merge_tests"] = nmerge, ntest
    return Segmentation(chart=chart, glued=glued, stats=stats, corner_uv=layouts.uv,
                        checked=layouts.checked(), iso=layouts.iso())


class _Layouts:
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
        from heatparam.metrics import true_scale_iso

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


def _merge(topo: Topology, chart: np.ndarray, glued: np.ndarray, bound: float, layouts: _Layouts,
           stop_at: int | None = None):
    """Greedy merges in rounds (small unions first, then the longest common border): each round picks pairs of
    charts not picked yet in it and tests all their unions at once (:func:`_extension_tests`: the smaller chart laid
    out against the larger one's layout, the stretch's vertices pinned there); a merge is kept when the union's
    layout is bijective and within the bound; stops early at ``stop_at`` charts. A pair with a chart whose layout
    was never checked, or whose extension is undecided, and every pair under a cap, is tested by flattening the
    whole union (:func:`_union_tests`).
    (Letting a chart join up to 4 of a round's unions, one of them kept, was measured: fewer rounds, more faces
    per solve, no faster on cow or 3holes and 34-40 charts instead of 34.)"""
    opp = topo.opp
    h_all = np.flatnonzero(opp >= 0)
    failed: dict = {}  # (a, b) -> (their sizes when the merge failed, the stretch tried)
    merges = tests = 0
    members = {int(c): np.flatnonzero(chart == c) for c in np.unique(chart)}
    while stop_at is None or len(members) > stop_at:
        # candidate pairs with their common border length
        h = h_all[chart[h_all // 3] < chart[opp[h_all] // 3]]
        if not len(h):
            break
        ca, cb = chart[h // 3], chart[opp[h] // 3]
        base = int(chart.max()) + 1
        key = ca * base + cb
        uk, _, inv = unique_inverse(key)
        length = np.bincount(inv, weights=topo.hlen[h])
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
            na, nb = len(members[a]), len(members[b])
            prev = failed.get((a, b))
            tries = 0
            if prev is not None and na < RETRY_GROWTH * prev[0] and nb < RETRY_GROWTH * prev[1]:
                # failed before, and neither side has grown enough since to change the answer much; under a chart
                # cap the pair's other common stretches are tried in turn (longest first)
                if stop_at is None:
                    continue
                tries = prev[2] + 1
            stretches = _stretches(topo, h[grouped[starts[i]:starts[i + 1]]])
            if stop_at is not None:  # under a cap: also the first half of each stretch (a union that gluing a
                stretches += [_half_path(topo, st) for st in stretches if len(st) > 1]  # whole one closes up)
            if tries >= len(stretches):
                continue
            st = stretches[tries]
            picked.append((a, b, st))
            touched.update((a, b))
        if not picked:
            break
        ok = np.zeros(len(picked), dtype=bool)
        # under a cap every union is flattened whole: the last merges toward the cap need both sides free (a torus
        # capped at 2 charts stopped at 3 with extensions)
        extend = [stop_at is None and layouts.ok[a] and layouts.ok[b] for a, b, _ in picked]
        pinned = [p for p, e in enumerate(extend) if e]
        whole = [p for p, e in enumerate(extend) if not e]
        if pinned:
            ok[pinned], undecided = _extension_tests(topo, glued, layouts, members, [picked[p] for p in pinned],
                                                     bound)
            whole += [p for p, u in zip(pinned, undecided, strict=True) if u]
        if whole:
            ok[whole] = _union_tests(topo, glued, layouts, members, [picked[p] for p in whole], bound)
        tests += len(picked)
        for (a, b, st), good in zip(picked, ok, strict=True):
            if stop_at is not None and len(members) <= stop_at:
                break
            if good:
                glued[st] = True
                glued[opp[st]] = True
                chart[members[b]] = a
                members[a] = np.sort(np.concatenate([members[a], members[b]]))
                del members[b]
                merges += 1
            else:
                prev = failed.get((a, b))
                again = prev is not None and stop_at is not None and prev[:2] == (len(members[a]), len(members[b]))
                failed[(a, b)] = (len(members[a]), len(members[b]), prev[2] + 1 if again else 0)
    # relabel 0..k-1
    ids, chart = np.unique(chart, return_inverse=True)
    layouts.relabel(ids)
    return chart.astype(np.int64), glued, merges, tests


def _with_stretches(topo: Topology, glued: np.ndarray, picked: list) -> np.ndarray:
    """``glued`` (3m,) with the stretch of every picked pair (a, b, stretch) glued too, both sides (a copy)."""
    g = glued.copy()
    for _, _, st in picked:
        g[st] = True
        g[topo.opp[st]] = True
    return g


def _union_tests(topo: Topology, glued: np.ndarray, layouts: _Layouts, members: dict, picked: list,
                 bound: float) -> np.ndarray:
    """Each picked pair (a, b, stretch) tested by flattening the whole union (LSCM, :func:`flatten_charts`); the
    layouts of the unions that pass are kept under a's id (b's entries go stale with b). (k,) bool."""
    g = _with_stretches(topo, glued, picked)
    unions = [np.concatenate([members[a], members[b]]) for a, b, _ in picked]
    fl = flatten_charts(topo, unions, g, bound)
    ok = fl.ok(bound)
    passed = np.flatnonzero(ok).tolist()
    layouts.add([picked[i][0] for i in passed], unions, fl, passed, [True] * len(passed))
    return ok


def _extension_tests(topo: Topology, glued: np.ndarray, layouts: _Layouts, members: dict, picked: list,
                     bound: float) -> tuple[np.ndarray, np.ndarray]:
    """Each picked pair (a, b, stretch) of checked charts tested by extending the larger chart's layout over the
    smaller: LSCM of the smaller chart alone with the stretch's vertices pinned where the larger chart has them
    (all the round's smaller charts in one solve). The union passes when no face of the smaller chart flips, its
    area-weighted isometric distortion (both charts' faces) is within ``bound`` and no two edges of its border
    cross. Cost ∝ the smaller chart, where flattening the union costs ∝ both: the large charts at the end of the
    merging are tested against each neighbour in turn (cow: 97k faces flattened in 556 tests, 21k this way). The
    layouts of the unions that pass are kept under a's id. Returns (passed (k,) bool, undecided (k,) bool: the
    stretch is not one arc of both charts' borders — the union would not be a disk — or the shared solve failed;
    the caller flattens those unions whole)."""
    from heatparam.metrics import true_scale_iso

    opp, F = topo.opp, topo.F
    m = len(F)
    k = len(picked)
    big, small, hq = [], [], []  # per test: the larger chart, the smaller, the smaller side's stretch half-edges
    for a, b, st in picked:  # st lies in chart a, opp[st] in chart b
        if len(members[a]) >= len(members[b]):
            big.append(a), small.append(b), hq.append(opp[st])
        else:
            big.append(b), small.append(a), hq.append(st)
    qf = np.concatenate([members[c] for c in small])  # each sorted: (test, face) keys ascend
    sizes = np.array([len(members[c]) for c in small], dtype=np.int64)
    grp = np.repeat(np.arange(k), sizes)
    Vl, Fl, _ = chart_mesh(topo, qf, glued, grp)
    # pins: each stretch half-edge's two corners on the smaller side take the larger side's corner UVs
    hs = np.concatenate(hq)
    hg = np.repeat(np.arange(k), [len(x) for x in hq])
    pos = np.searchsorted(grp * m + qf, hg * m + hs // 3)
    kq, hp = hs % 3, opp[hs]
    fp, jp = hp // 3, hp % 3
    rows = np.concatenate([Fl[pos, kq], Fl[pos, (kq + 1) % 3]])
    vals = np.concatenate([layouts.uv[3 * fp + (jp + 1) % 3], layouts.uv[3 * fp + jp]])
    # the union is a disk when the stretch is one arc of both borders: n + 1 corners of each chart along its n
    # edges. A chart with an inner seam of its own ending on the stretch has two corners there (the smaller
    # chart: two rows; the larger: two places, or one row pinned at two places); gluing would close the seam's
    # mouth into a hole. Such a union is flattened whole instead (the caller's undecided: its disk test decides)
    ha, hb = topo.ends()
    pv = np.concatenate([ha[hs], hb[hs]])  # the vertex of each pin
    pg = np.concatenate([hg, hg])
    _, place = _places(pg, pv, vals)
    p_corners = np.bincount(pg[place], minlength=k)
    o = np.argsort(rows, kind="stable")
    rows, vals, pg = rows[o], vals[o], pg[o]
    again = rows[1:] == rows[:-1]
    first = np.r_[True, ~again]
    q_corners = np.bincount(pg[first], minlength=k)
    arc = np.bincount(hg, minlength=k) + 1
    ok, undecided = np.zeros(k, dtype=bool), (q_corners != arc) | (p_corners != arc)
    rows, vals = rows[first], vals[first]
    try:
        res = igl.lscm(Vl, Fl, rows, vals)
    except (RuntimeError, ValueError):
        return ok, np.ones(k, dtype=bool)  # one degenerate chart spoils the shared solve: each union whole
    uv = np.asarray(res[0] if isinstance(res, tuple) else res, dtype=np.float64)
    if not np.isfinite(uv).all():
        return ok, np.ones(k, dtype=bool)
    iso, area, sa = true_scale_iso(Vl, Fl, uv)
    flips = np.bincount(grp, weights=~(np.isfinite(iso) & (sa > 0)), minlength=k)
    isum = np.bincount(grp, weights=np.where(np.isfinite(iso), iso, 0.0) * area, minlength=k)
    asum = np.bincount(grp, weights=area, minlength=k)
    mean = (np.array([layouts.isum[c] for c in big]) + isum) / np.maximum(
        np.array([layouts.area[c] for c in big]) + asum, 1e-300)
    cand = (flips == 0) & (mean <= bound) & ~undecided
    if cand.any():
        cand[cand] = _border_crossings(topo, glued, layouts, members, picked, big, qf, grp, uv[Fl], cand) == 0
    for i in np.flatnonzero(cand):
        a = picked[i][0]
        s = slice(int(np.searchsorted(grp, i)), int(np.searchsorted(grp, i + 1)))
        layouts.uv[(3 * qf[s, None] + np.arange(3)).ravel()] = uv[Fl[s]].reshape(-1, 2)
        layouts.isum[a] = layouts.isum[big[i]] + float(isum[i])
        layouts.area[a] = layouts.area[big[i]] + float(asum[i])
        layouts.ok[a] = True  # the larger chart's corners are in place already (under a's id or b's)
    return cand, undecided


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


def _border_crossings(topo, glued, layouts, members, picked, big, qf, grp, Uq, which) -> np.ndarray:
    """Pairs of crossing border edges of each union in ``which`` (its larger chart at ``layouts``, its smaller
    chart's faces ``qf`` of group ``grp`` at the corner UVs ``Uq`` (len(qf),3,2)); (which.sum(),). The larger
    chart's border crosses nothing of its own: only pairs with a new edge can cross, so of its edges only those
    within the new edges' bounding box are checked."""
    idx = np.flatnonzero(which)
    k = len(idx)
    sel = np.isin(grp, idx)
    fb = np.concatenate([members[big[i]] for i in idx])  # the larger charts' faces (UVs in the layouts)
    gb = np.repeat(np.arange(k), [len(members[big[i]]) for i in idx])
    gq = np.searchsorted(idx, grp[sel])  # the smaller charts' faces (new UVs)
    faces = np.concatenate([fb, qf[sel]])
    fgroup = np.concatenate([gb, gq])
    new = np.r_[np.zeros(len(fb), dtype=bool), np.ones(len(gq), dtype=bool)]
    C = layouts.uv.copy()
    C[(3 * qf[sel, None] + np.arange(3)).ravel()] = Uq[sel].reshape(-1, 2)
    inner = _with_stretches(topo, glued, [picked[i] for i in idx])
    h = (3 * faces[:, None] + np.arange(3)).ravel()
    hgroup, hnew = np.repeat(fgroup, 3), np.repeat(new, 3)
    border = ~inner[h]
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
    P = pts[first]
    E = ids.reshape(2, -1).T
    pg = pgroup[first]
    return _crossings_per_chart(P, None, E[:, 0], E[:, 1], np.ones(len(E), dtype=bool), pg,
                                np.ones(k, dtype=bool), k)
