"""Quick flattenings of charts, and the checks that make them a chart's proof of bijectivity.

LSCM (Lévy et al. 2002) of many charts in one sparse solve (two far boundary vertices pinned per chart: LSCM's map
depends on its pins, so they come from the geometry, not the row order), each mirrored to the mesh's orientation
and scaled to its 3D area; then per chart its isometric distortion, flipped faces, disk test (Euler
characteristic 1) and crossing boundary edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from heatparam.atlas.chart_topology import Topology, chart_mesh
from heatparam.errors import HeatparamError
from heatparam.mesh.topology import degenerate_faces, unique_ints
from heatparam.metrics import angle_sums, crossing_pairs, true_scale_iso, wrapped
from heatparam.refine.energy import surface_gradients

__all__ = ["Flattenings", "chart_iso", "crossings_per_chart", "flatten_charts", "flatten_components", "lscm",
           "lscm_groups", "quick_flatten", "segment_layout", "triangle_layout"]


def chart_iso(V: np.ndarray, F: np.ndarray, uv: np.ndarray, fgroup: np.ndarray, k: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """Per chart (``fgroup`` (m,) of each face, k charts): the area-weighted mean of ``metrics.true_scale_iso``
    over its positive faces (inf when it has none) and its count of flipped or collapsed faces; (k,), (k,)."""
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
    uv, iso, flips, cross, disk, vgroup = flatten_components(Vl, Fl, fgroup, k, bound, vert, want,
                                                             topo.degenerate[faces])
    return Flattenings(Vl, Fl, vert, uv, vgroup, np.r_[0, np.cumsum(sizes)], iso, flips, cross, disk)


def flatten_components(Vl: np.ndarray, Fl: np.ndarray, fgroup: np.ndarray, k: int, bound: float = np.inf,
                       vkey: np.ndarray | None = None, want: np.ndarray | None = None,
                       degenerate: np.ndarray | None = None):
    """:func:`flatten_charts` on a mesh whose components are the k groups ``fgroup`` (m,) of faces: (uv (n,2),
    iso (k,), flips (k,), crossings (k,), disk (k,), vgroup (n,)). vkey (n,): a vertex key independent of the rows'
    order (the component's vertex), used to choose the pins; want (k,) bool: the groups to lay out (default all);
    degenerate (m,) bool: the zero-area faces, where the caller knows them (found by :func:`lscm` otherwise)."""
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
    uv = _layouts(Vl, Fl, fgroup, vgroup, solve, p0, p1,
                  degenerate_faces(Vl, Fl) if degenerate is None else degenerate)
    _true_area(Vl, Fl, uv, fgroup, vgroup, k)
    mean, flips = chart_iso(Vl, Fl, uv, fgroup, k)
    finite = np.bincount(fgroup, weights=~np.isfinite(uv[Fl]).all(axis=(1, 2)), minlength=k) == 0
    iso = np.where(solve & finite, mean, np.inf)
    check = solve & finite & (flips == 0) & (iso <= bound)
    cross[check] = crossings_per_chart(uv, Fl, a, b, bd, vgroup, check, k) + _wraps(uv, Fl, check[fgroup], bv,
                                                                                    vgroup, k)[check]
    return uv, iso, flips, cross, disk, vgroup


def _layouts(Vl: np.ndarray, Fl: np.ndarray, fgroup: np.ndarray, vgroup: np.ndarray, solve: np.ndarray,
             p0: np.ndarray, p1: np.ndarray, degenerate: np.ndarray) -> np.ndarray:
    """(n,2) the LSCM layouts of the charts ``solve`` (k,) bool, pinned at p0 and p1 (k,) (:func:`_lscm`: the
    charts with a zero-area face, ``degenerate`` (m,), mollified apart). Where a shared solve fails, each chart is
    solved on its own, and one whose solve fails is taken out of ``solve`` (in place), its rows left at 0."""
    sel = solve[fgroup]
    try:
        return _lscm(Vl, Fl[sel], fgroup[sel], p0[solve], p1[solve], degenerate[sel])
    except HeatparamError:  # one chart spoils a shared solve: each on its own
        uv = np.zeros((len(Vl), 2))
        for i in np.flatnonzero(solve):
            s_i = fgroup == i
            try:
                res = _lscm(Vl, Fl[s_i], fgroup[s_i], p0[i:i + 1], p1[i:i + 1], degenerate[s_i])
            except HeatparamError:
                solve[i] = False
                continue
            uv[vgroup == i] = res[vgroup == i]
        return uv


def _wraps(uv: np.ndarray, Fl: np.ndarray, sel: np.ndarray, bv: np.ndarray, vgroup: np.ndarray, k: int
           ) -> np.ndarray:
    """(k,) per chart its border rows ``bv`` where the faces ``sel`` have 2π or more of corner angles: the border
    touches or passes itself there (:func:`heatparam.metrics.wrapped`), which the edge-pair test skips (the edges
    share the vertex)."""
    return np.bincount(vgroup[bv[wrapped(angle_sums(uv, Fl[sel])[bv])]], minlength=k)


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


def _lscm(Vl: np.ndarray, Fl: np.ndarray, fgroup: np.ndarray, p0: np.ndarray, p1: np.ndarray, zero: np.ndarray
          ) -> np.ndarray:
    """LSCM (``igl.lscm``: faster than a PARDISO LSCM on cow's charts, the same map to 5e-12) of the charts' faces
    ``Fl`` (chart ``fgroup`` (m,), zero-area ``zero`` (m,): :func:`lscm_groups`), each with its pin p0 at (0,0) and
    p1 at (1,0); rows no face uses stay at 0. Raises HeatparamError where it fails or is not finite."""
    puv = np.zeros((len(p0) + len(p1), 2))
    puv[len(p0):, 0] = 1.0
    try:
        uv = lscm_groups(Vl, Fl, fgroup, np.concatenate([p0, p1]), puv, zero)
    except (RuntimeError, ValueError) as exc:
        raise HeatparamError(f"LSCM failed: {exc}") from None
    if not np.isfinite(uv).all():
        raise HeatparamError("non-finite LSCM layout")
    return uv


def lscm_groups(V: np.ndarray, F: np.ndarray, fgroup: np.ndarray, b: np.ndarray, bc: np.ndarray, zero: np.ndarray
                ) -> np.ndarray:
    """:func:`lscm` of (V, F) with the rows ``b`` pinned at ``bc`` (k,2), whose faces fall in groups ``fgroup`` (m,)
    that share no row (charts side by side, each pinned): the groups with a zero-area face (``zero`` (m,) bool) on
    mollified triangles, in a solve apart from the others (mollified with them, a CAD part's slivers came out at iso
    7-41). (n,2), rows no face uses at 0; raises as :func:`lscm` does."""
    has_zero = np.zeros(int(fgroup.max()) + 1 if len(fgroup) else 0, dtype=bool)
    has_zero[fgroup[zero]] = True
    uv = np.zeros((len(V), 2))
    for part, mollify in ((~has_zero[fgroup], False), (has_zero[fgroup], True)):
        if not part.any():
            continue
        used = unique_ints(F[part])
        loc = np.full(len(V), -1, dtype=np.int64)
        loc[used] = np.arange(len(used))
        pinned = loc[b] >= 0
        uv[used] = lscm(V[used], loc[F[part]], loc[b[pinned]], bc[pinned], mollify)
    return uv


def lscm(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, degenerate: bool | None = None) -> np.ndarray:
    """LSCM of (V, F) with the rows ``b`` pinned at ``bc`` (k,2): (n,2), every row used by a face. ``igl.lscm``;
    where F has zero-area faces, the least-squares conformal map of the intrinsically mollified triangles (the
    polish's, ``refine.energy.surface_gradients``): igl's cotangents are NaN on a zero-area face, and the mollified
    one is laid out as a thin triangle of the right orientation, a start the polish can take. ``degenerate``:
    whether F has zero-area faces, where the caller knows (``Topology.degenerate``); found here otherwise. Raises
    RuntimeError (singular system) as igl does."""
    if not (degenerate_faces(V, F).any() if degenerate is None else degenerate):
        res = igl.lscm(V, F, b, bc)
        return np.asarray(res[0] if isinstance(res, tuple) else res, dtype=np.float64)
    n, m = len(V), len(F)
    g, area = surface_gradients(V, F)
    gx, gy = (g[:, :, c] * np.sqrt(area)[:, None] for c in (0, 1))
    # per face the Cauchy-Riemann residuals u_x - v_y and u_y + v_x over the unknowns [u; v], area-weighted
    rows = np.repeat(np.arange(2 * m), 6)
    cols = np.concatenate([F, F + n], axis=1)
    vals = np.stack([np.concatenate([gx, -gy], axis=1), np.concatenate([gy, gx], axis=1)])
    M = sp.csc_matrix((vals.ravel(), (rows, np.concatenate([cols, cols]).ravel())), shape=(2 * m, 2 * n))
    fixed = np.concatenate([b, b + n])
    free = np.setdiff1d(np.arange(2 * n), fixed)
    x = np.zeros(2 * n)
    x[fixed] = np.concatenate([bc[:, 0], bc[:, 1]])
    Mf = M[:, free]
    x[free] = spla.splu((Mf.T @ Mf).tocsc()).solve(-(Mf.T @ (M[:, fixed] @ x[fixed])))
    return np.column_stack([x[:n], x[n:]])


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


def crossings_per_chart(uv, Fl, a, b, bd, vgroup, check, k) -> np.ndarray:
    """Boundary crossings of each chart in ``check``, all in one pass: the charts are first set side by side."""
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


def triangle_layout(Vl: np.ndarray, Fl: np.ndarray) -> np.ndarray:
    """A chart of one face laid out exactly: (n,2), its longest edge on +x from the origin, the third corner above
    it at the height 2·area / that edge (counter-clockwise), rows no face uses at 0. Lengths and area are the 3D
    ones to rounding, also for a sliver whose LSCM solve has no finite layout."""
    f = Fl[0]
    E = Vl[np.roll(f, -1)] - Vl[f]  # edge k runs from corner k to corner k + 1
    k = int(np.argmax(np.einsum("ij,ij->i", E, E)))
    a, b, c = f[k], f[(k + 1) % 3], f[(k + 2) % 3]
    e1, e2 = Vl[b] - Vl[a], Vl[c] - Vl[a]
    base = float(np.linalg.norm(e1))
    uv = np.zeros((len(Vl), 2))
    if base > 0.0:
        uv[b] = [base, 0.0]
        uv[c] = [float(e1 @ e2) / base, float(np.linalg.norm(np.cross(e1, e2))) / base]
    return uv


def segment_layout(Vl: np.ndarray, Fl: np.ndarray) -> np.ndarray | None:
    """A chart of zero-area faces only, laid out exactly: (n,2) each vertex at its place along the line the chart
    lies on (triangles joined by edges of nonzero length that each have zero area lie on one line), so every length
    is kept and every face is a segment, zero area both ways, flipping nothing; rows no face uses at 0. None when
    the vertices are not on one line (within 1e-7 of its length)."""
    used = unique_ints(Fl)
    E = Vl[used] - Vl[used[0]]
    far = int(np.argmax(np.einsum("ij,ij->i", E, E)))
    length = float(np.linalg.norm(E[far]))
    uv = np.zeros((len(Vl), 2))
    if length == 0.0:
        return uv
    t = E @ (E[far] / length)
    if np.linalg.norm(E - np.outer(t, E[far] / length), axis=1).max() > 1e-7 * length:
        return None
    uv[used, 0] = t
    return uv
