"""STEP output: a map's charts as trimmed B-spline faces (OpenCascade 8, through the ``OCP`` bindings of the
``cadquery-ocp-novtk`` wheel; ``cadquery-ocp`` provides the same module with VTK besides).

The contract (issue 45): every face's surface within the fit tolerance of the mesh both ways — the mesh vertices
to the surface and the surface to the mesh, everywhere inside the trim — or a warning saying which face, where and
by how much, and the achieved deviation of every face in the report. Measured by ``bench/bench_step.py`` (the file
read back, tessellated and compared with the mesh both ways).

1. **Faces.** Each chart's triangles, connected through shared uv edges, cut along its creases (:func:`_creases`:
   dihedral angle >= 60°, or >= 20° where the triangles beside the edge are too large for a smooth surface to turn
   within the tolerance); pieces under 16 triangles join a neighbour; slits are cut (4.). Each piece is one STEP
   face.
2. **Fit.** Per face, a clamped bicubic B-spline surface ``S(u,v)`` over the face's padded uv rectangle, fitted by
   penalized least squares to the mesh at its vertices, edge midpoints and centroids (the map is piecewise linear:
   the mesh's point at any uv is the barycentric one), plus a small second-difference penalty on the control net
   (it extends the surface smoothly where there is no data). The knot grid starts at min(32, √triangles / 2)
   intervals on the longer side; each round, knot intervals holding a data point off by more than 0.9 tolerance
   are halved (never below 1/8 of the triangles); when the data are met, the surface is checked between them, at
   rows of points in every triangle as dense as the knots (:func:`_check_samples`), and the triangles where a
   check point is off join the data with all their check points. The border's points are held to 0.25 tolerance
   (weight 10), so that neighbouring faces meet within half the tolerance. The penalty weight (1e-2 of the data
   term's mean diagonal) was measured: at 1e-4 camelhead's face was 1.5% larger than the mesh (ripples between
   the data), at 1e-1 the developable part needed twice the control points.
3. **Where the fit misses.** A face still off the tolerance is split (:func:`_split`): its failing triangles and
   two rings around them carved out as faces of their own, then halves, up to 12 deep; a single triangle is a
   plane, which the fit meets exactly. What still misses is written as it is, with a :class:`StepToleranceWarning`.
4. **Topology.** Faces share their border edges (:func:`_chains`): the border of every face is cut at its corners
   (mesh vertices where the neighbour changes, :func:`_border_corners`) into runs of mesh edges, and each run is
   one edge used by the faces on both sides (opposite ways round): its 3D curve the mesh's border polyline, one
   uv polyline per face as its pcurve (degree-1 B-splines of one parameter), one vertex per mesh vertex, its
   tolerance 1.5 x the largest gap measured between the polyline and each surface (:func:`_border_gaps`). No
   sewing: sewing each face's own border (its vertices on its own surface, up to a tolerance apart across a
   border) cut the cow's edges into slivers 0.01 tolerances long, left 91 free edges and read back invalid.
   A region holding both sides of a chart's seam (a slit) is cut across first (:func:`_unslit`): a face bounded by
   both sides needs a seam edge, which BRepCheck rejects on a surface that is not closed.
5. **Assemble and write.** One shell per connected set of faces, a closed one (no edge with one face) a solid,
   outward; kept when ``BRepCheck_Analyzer`` calls it valid before and after the round trip (else the faces with
   edges of their own, unjoined, with a warning). The file declares the largest edge tolerance as its uncertainty.
   ``STEPControl_Writer`` writes to a temporary file beside the output, renamed over it on success. The
   coordinates are written unchanged and the file declares ``units``; the header's time stamp is fixed (same
   input, same file).
"""

from __future__ import annotations

import contextlib
import functools
import os
import tempfile
import time
import warnings as _warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from heatparam.errors import HeatparamError
from heatparam.formats.files import file_mode
from heatparam.mesh.planar import polygon_area
from heatparam.mesh.topology import boundary_loops

DEGREE = 3
# file unit names: ours -> OpenCascade's ``write.step.unit`` / ``xstep.cascade.unit`` values; mm per unit
UNITS = {"mm": ("MM", 1.0), "cm": ("CM", 10.0), "m": ("M", 1000.0), "in": ("INCH", 25.4), "ft": ("FT", 304.8)}
TIME_STAMP = "2000-01-01T00:00:00"  # fixed: deterministic output
MAX_CONTROL_POINTS = 1_000_000  # per chart (a 1000 x 1000 net); beyond it the fit stops and warns
_PENALTY = 1e-2  # weight of the control-net smoothness term, relative to the mean diagonal of the data term
_START_INTERVALS = 32  # knot intervals along the longer side of the parameter rectangle at the first fit (at most)
_SPLIT_AT = 0.9  # knot intervals holding a vertex deviating by more than this x tolerance are halved
_MAX_ROUNDS = 20
_CHECK_LEVEL = 4  # the fit is checked in every triangle at least at the points (i, j, k)/4 (12 besides the corners)
_FINEST = 8  # knot intervals are not halved below 1/8 of the (10th percentile) triangle's uv diameter
# up to n * bandwidth^2 flops a banded Cholesky (LAPACK, no ordering): 8 ms vs CHOLMOD's 33 ms at 2.6k unknowns,
# 73 vs 314 ms at 12k
_BANDED_FLOPS = 3e9
_CHUNK = 200_000  # points evaluated at once when checking
CREASE_ANGLE = 60.0  # degrees: a dihedral angle from which an edge is a crease, a STEP face border (see _creases)
_SOFT_CREASE_ANGLE = 20.0  # degrees: from here, a crease where the triangles beside it are too large to round it
_MIN_REGION = 16  # triangles: a smaller piece between creases joins its neighbour
_MAX_SPLITS = 12  # a face whose fit misses the tolerance is split (see _split), at most this deep
_CARVE_RINGS = 2  # rings of neighbours carved out with the triangles off the tolerance
_BORDER = 0.25  # x tolerance: a face's border is held closer to the mesh, so that its neighbours meet it closely
_BORDER_WEIGHT = 10.0  # the weight of the border's points in the least squares
_EDGE_SAMPLES = 33  # points along each border edge where its gap to the surface is measured (the edge tolerance)
# edge tolerance / the gap measured: BRepCheck found 0.254 tol between 17 samples whose max was 0.218 (a cow face)
_EDGE_MARGIN = 1.5


def _require_ocp():
    try:
        import OCP  # noqa: F401
    except ImportError as e:  # pragma: no cover - OCP is a dependency
        raise HeatparamError("STEP output needs OpenCascade's Python bindings: pip install cadquery-ocp-novtk") from e


# --------------------------------------------------------------------------------------------------- B-spline fit
def _clamped(breaks: np.ndarray) -> np.ndarray:
    """Full clamped knot vector of degree DEGREE from the distinct breakpoints (b,)."""
    return np.concatenate([[breaks[0]] * DEGREE, breaks, [breaks[-1]] * DEGREE])


def _basis(x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The DEGREE + 1 nonzero B-splines of the clamped knot vector t at the points x (N,), clipped into its range:
    (the index of the first (N,), their values (N, DEGREE + 1)). De Boor's triangle (Piegl & Tiller A2.2) on all
    points at once: 10x faster than ``BSpline.design_matrix`` and a sparse matrix per call."""
    k = DEGREE
    x = np.clip(x, t[k], t[-k - 1])
    span = np.clip(np.searchsorted(t, x, side="right") - 1, k, len(t) - k - 2)
    N = np.zeros((len(x), k + 1))
    N[:, 0] = 1.0
    left, right = np.empty((k + 1, len(x))), np.empty((k + 1, len(x)))
    for j in range(1, k + 1):
        left[j] = x - t[span + 1 - j]
        right[j] = t[span + j] - x
        saved = np.zeros(len(x))
        for r in range(j):
            temp = N[:, r] / (right[r + 1] + left[j - r])
            N[:, r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        N[:, j] = saved
    return span - k, N


def _design(uv: np.ndarray, tu: np.ndarray, tv: np.ndarray) -> sp.csr_matrix:
    """(N, nu*nv) tensor-product B-spline basis values at the points uv (N,2); column = i*nv + j."""
    iu, bu = _basis(uv[:, 0], tu)
    iv, bv = _basis(uv[:, 1], tv)
    nu, nv = len(tu) - DEGREE - 1, len(tv) - DEGREE - 1
    a = np.arange(DEGREE + 1)
    cols = ((iu[:, None] + a)[:, :, None] * nv + (iv[:, None] + a)[:, None, :]).reshape(-1)  # sorted in each row
    vals = (bu[:, :, None] * bv[:, None, :]).reshape(-1)
    return sp.csr_matrix((vals, cols, np.arange(0, len(cols) + 1, (DEGREE + 1) ** 2)), shape=(len(uv), nu * nv))


def _surface_points(C: np.ndarray, tu: np.ndarray, tv: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """S(uv) (N,3) of the surface of control points C (nu*nv,3), without a design matrix: scipy's compiled
    ``NdBSpline`` (scipy >= 1.12; 2.7x faster on 1.2M points) or the 16 nonzero terms of each point summed."""
    nu, nv = len(tu) - DEGREE - 1, len(tv) - DEGREE - 1
    uv = np.column_stack([np.clip(uv[:, 0], tu[0], tu[-1]), np.clip(uv[:, 1], tv[0], tv[-1])])
    try:
        from scipy.interpolate import NdBSpline
    except ImportError:  # pragma: no cover - scipy 1.11
        NdBSpline = None
    if NdBSpline is not None:
        return NdBSpline((tu, tv), C.reshape(nu, nv, 3), DEGREE)(uv)
    iu, bu = _basis(uv[:, 0], tu)
    iv, bv = _basis(uv[:, 1], tv)
    out = np.zeros((len(uv), 3))
    for a in range(DEGREE + 1):
        row = (iu + a) * nv + iv
        for b in range(DEGREE + 1):
            out += (bu[:, a] * bv[:, b])[:, None] * C[row + b]
    return out


@functools.lru_cache(maxsize=16)
def _smoothness(nu: int, nv: int) -> sp.csr_matrix:
    """Second differences of the control net (uu, 2 uv, vv), squared: (nu*nv, nu*nv) PSD."""

    def d2(n):
        return sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(max(n - 2, 0), n))

    def d1(n):
        return sp.diags([-1.0, 1.0], [0, 1], shape=(n - 1, n))

    Duu = sp.kron(d2(nu), sp.identity(nv))
    Dvv = sp.kron(sp.identity(nu), d2(nv))
    Duv = sp.kron(d1(nu), d1(nv))
    return (Duu.T @ Duu + Dvv.T @ Dvv + 2.0 * Duv.T @ Duv).tocsr()


def _halve(breaks: np.ndarray, x: np.ndarray, shortest: float = 0.0) -> np.ndarray:
    """Breakpoints (b,) with every interval that contains one of x (k,) halved, unless its halves would be shorter
    than ``shortest``."""
    i = np.unique(np.clip(np.searchsorted(breaks, x, side="right") - 1, 0, len(breaks) - 2))
    i = i[breaks[i + 1] - breaks[i] >= 2 * shortest]
    return np.sort(np.concatenate([breaks, 0.5 * (breaks[i] + breaks[i + 1])]))


def _shortest_in(breaks: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The shortest knot interval of ``breaks`` overlapping each range [lo, hi] (t,): a sparse table of minima."""
    length = np.diff(breaks)
    i0 = np.clip(np.searchsorted(breaks, lo, side="right") - 1, 0, len(length) - 1)
    i1 = np.clip(np.searchsorted(breaks, hi, side="left") - 1, i0, len(length) - 1)
    table = [length]
    while 2 ** len(table) <= len(length):
        prev, w = table[-1], 2 ** (len(table) - 1)
        table.append(np.minimum(prev[:-w], prev[w:]))
    k = np.floor(np.log2(i1 - i0 + 1)).astype(int)
    out = np.empty(len(lo))
    for lev in np.unique(k):
        sel = k == lev
        t = table[lev]
        out[sel] = np.minimum(t[i0[sel]], t[i1[sel] - 2**lev + 1])
    return out


def _lattice(level: int) -> np.ndarray:
    """Barycentric coordinates (p,3) of the points (i, j, k)/level of a triangle, its corners left out."""
    ijk = [(i, j, level - i - j) for i in range(level + 1) for j in range(level + 1 - i)]
    return np.array([w for w in ijk if max(w) < level], dtype=np.float64) / level


_FIT_POINTS = np.vstack([_lattice(2), [[1 / 3, 1 / 3, 1 / 3]]])  # edge midpoints, centroid: fitted with the vertices


class _Samples:
    """Points of the mesh inside its triangles: uv (p,2), the mesh's 3D point there X (p,3) (barycentric, the map
    being piecewise linear), the triangle of each (p,) and whether it lies on a border edge (p,). Made from the
    triangles Fc (m,3) (rows of uv and X_row), the barycentric weights W (w,3) in each and ``border`` (m,3), whether
    the edge opposite each corner is a border edge (a point with weight 0 at corner k lies on that edge)."""

    def __init__(self, uv: np.ndarray, X_row: np.ndarray, Fc: np.ndarray, W: np.ndarray, border: np.ndarray,
                 face: np.ndarray | None = None):
        self.uv = np.einsum("wk,fkd->fwd", W, uv[Fc]).reshape(-1, 2)
        self.X = np.einsum("wk,fkd->fwd", W, X_row[Fc]).reshape(-1, 3)
        self.face = np.repeat(np.arange(len(Fc)) if face is None else face, len(W))
        self.border = ((W[None, :, :] == 0) & border[:, None, :]).any(axis=2).reshape(-1)

    @classmethod
    def joined(cls, parts: list[_Samples]) -> _Samples:
        """The samples of all the parts, in order."""
        out = cls.__new__(cls)
        for name in ("uv", "X", "face", "border"):
            setattr(out, name, np.concatenate([getattr(p, name) for p in parts]))
        return out


def _subset(s: _Samples, keep: np.ndarray) -> _Samples:
    """The samples ``keep`` (a mask or indices) of s."""
    out = _Samples.__new__(_Samples)
    for name in ("uv", "X", "face", "border"):
        setattr(out, name, getattr(s, name)[keep])
    return out


def _check_samples(uv: np.ndarray, X_row: np.ndarray, Fc: np.ndarray, border: np.ndarray, bu: np.ndarray,
                   bv: np.ndarray, faces: np.ndarray | None = None) -> _Samples:
    """The check samples of the triangles ``faces`` (all by default) of Fc: in each, rows of points parallel to its
    shortest edge (:func:`_strip_weights`), at most about half the shortest knot interval over the triangle apart
    along and across it, so that a surface cannot ripple between them unseen (the cow's small faces, their knots
    finer than their triangles, were up to 6.8 tolerances off the mesh between 4-level checks that met it; with the
    knot interval at the centroid instead of the shortest, 5.1), and at least a lattice (i, j, k)/4. No cap on the
    density: the knots are never refined below 1/``_FINEST`` of the face's 10th-percentile triangle, and a sliver
    or a large triangle beside small ones spans many such intervals (a CAD export's 3-triangle face across a 90°
    crease was checked within the tolerance by a 16-lattice and read back 7 tolerances off between its points)."""
    faces = np.arange(len(Fc)) if faces is None else faces
    T = uv[Fc[faces]]  # (f,3,2)
    opposite = np.linalg.norm(np.roll(T, -1, axis=1) - np.roll(T, 1, axis=1), axis=2)  # the edge opposite corner k
    turn = (np.argmin(opposite, axis=1)[:, None] + np.arange(3)) % 3  # the corner opposite the shortest edge first
    Fr, Br = np.take_along_axis(Fc[faces], turn, axis=1), np.take_along_axis(border[faces], turn, axis=1)
    short, long_ = opposite.min(axis=1), np.maximum(opposite.max(axis=1), 1e-300)
    lo, hi = T.min(axis=1), T.max(axis=1)
    knot = np.maximum(np.minimum(_shortest_in(bu, lo[:, 0], hi[:, 0]), _shortest_in(bv, lo[:, 1], hi[:, 1])), 1e-300)
    rows = np.maximum(np.ceil(2.0 * long_ / knot), _CHECK_LEVEL)
    across = np.clip(np.maximum(np.ceil(2.0 * short / knot), np.ceil(rows * short / long_)), 1, rows)
    pairs, group = np.unique(np.stack([rows, across], 1).astype(np.int64), axis=0, return_inverse=True)
    order = np.argsort(group.reshape(-1), kind="stable")  # the triangles of each (rows, across) pair: one slice
    ends = np.cumsum(np.bincount(group.reshape(-1), minlength=len(pairs)))
    slices = [order[e - n: e] for e, n in zip(ends, np.diff(ends, prepend=0), strict=True)]
    parts = [_Samples(uv, X_row, Fr[sl], _strip_weights(int(a), int(b)), Br[sl], faces[sl])
             for (a, b), sl in zip(pairs, slices, strict=True)]
    return _Samples.joined(parts)


def _strip_weights(rows: int, across: int) -> np.ndarray:
    """Barycentric weights (p,3), corners left out, of the points of a triangle in ``rows`` rows parallel to the
    edge opposite its first corner: row i (of rows + 1, the first the corner) at i/rows of the way to that edge,
    ceil(i across / rows) intervals along it. rows = across gives the lattice (i, j, k)/rows."""
    s = np.arange(rows + 1) / rows
    m = np.ceil(np.arange(rows + 1) * across / rows).astype(np.int64)
    i = np.repeat(np.arange(rows + 1), m + 1)
    j = np.arange(len(i)) - np.repeat(np.cumsum(m + 1) - (m + 1), m + 1)
    t = j / np.maximum(m[i], 1)
    W = np.column_stack([1 - s[i], s[i] * (1 - t), s[i] * t])
    return W[~np.isclose(W, 1.0).any(axis=1)]


def _deviations(C: np.ndarray, tu: np.ndarray, tv: np.ndarray, uv: np.ndarray, X: np.ndarray) -> np.ndarray:
    """|S(uv) - X| (p,) for the surface of control points C (nu*nv,3), in chunks of ``_CHUNK`` points."""
    out = np.empty(len(uv))
    for i in range(0, len(uv), _CHUNK):
        sl = slice(i, i + _CHUNK)
        out[sl] = np.linalg.norm(_surface_points(C, tu, tv, uv[sl]) - X[sl], axis=1)
    return out


def _fit_surface(uv_v: np.ndarray, X_v: np.ndarray, border_v: np.ndarray, fit: _Samples, checks, tol: float,
                 intervals: int) -> dict:
    """Fit a clamped bicubic B-spline to points X_v (k,3) at uv_v (k,2) (the vertices) and to the mesh at the
    ``fit`` samples (edge midpoints and centroids) until the surface is within ``tol`` of the mesh at the vertices,
    at the fit samples and at the check samples ``checks(bu, bv)`` (:func:`_check_samples`: a lattice in every
    triangle, between the data, as dense as the knots), starting from ``intervals`` knot intervals along the longer
    side (:class:`_SurfaceFit`).

    Returns dict: poles (nu,nv,3), bu (a,) and bv (b,) distinct breakpoints, dev (k,) vertex deviations, dev_fit
    and dev_check the deviations at the fit and the (last) check samples, check (those samples), dev_border (the
    max on the border), rounds, within (bool).
    """
    return _SurfaceFit(uv_v, X_v, border_v, fit, checks, tol).run(intervals)


class _SurfaceFit:
    """:func:`_fit_surface` in rounds. Each round solves the penalized least squares (:meth:`solve`); where a fitted
    point deviates by more than ``_SPLIT_AT`` tol, its knot intervals are halved; when none does, the check samples
    are measured (:meth:`check`), and the triangles where one deviates join the data with all their check samples.
    No knot is added for a check sample: a surface with knots finer than its data ripples between them (halving the
    knots at the check samples made the developable part's deviation grow from 1.7 to 44 tolerances in 7 rounds).
    The fit ends when no check sample deviates. Points on the border are held to ``_BORDER`` tol and weigh
    ``_BORDER_WEIGHT``: adjacent faces then meet within 2 ``_BORDER`` tol, and so do their shared edges."""

    def __init__(self, uv_v, X_v, border_v, fit: _Samples, checks, tol: float):
        self.uv_v, self.X_v, self.border_v, self.fit, self.checks, self.tol = uv_v, X_v, border_v, fit, checks, tol
        T = fit.uv.reshape(-1, len(_FIT_POINTS), 2)  # (the fit samples' triangles, from their edge midpoints)
        diam = 2 * np.linalg.norm(T[:, :3] - np.roll(T[:, :3], 1, axis=1), axis=2).max(axis=1)
        self.shortest = float(np.percentile(diam, 10)) / _FINEST if len(diam) else 0.0
        self.extra = []  # check samples fitted as data
        self.level = {}  # triangle -> the number of check samples it has in the data
        self.last = None  # (bu, bv, rows, B, W B, B^T W B) of the last solve (:meth:`normal`)

    def knots(self, intervals: int) -> tuple[np.ndarray, np.ndarray]:
        """The first breakpoints: a uniform grid over the padded parameter rectangle."""
        lo, hi = self.uv_v.min(0), self.uv_v.max(0)
        size = hi - lo
        pad = 0.01 * max(size.max(), 1e-300)
        lo, hi, size = lo - pad, hi + pad, size + 2 * pad
        h = size.max() / intervals
        return (np.linspace(lo[0], hi[0], max(1, int(np.ceil(size[0] / h))) + 1),
                np.linspace(lo[1], hi[1], max(1, int(np.ceil(size[1] / h))) + 1))

    def run(self, intervals: int) -> dict:
        bu, bv = self.knots(intervals)
        best = None
        for rounds in range(1, _MAX_ROUNDS + 1):
            best, bad_uv, border = self.solve(bu, bv, rounds)
            refined = self.halved(bu, bv, bad_uv)
            if len(refined[0]) + len(refined[1]) == len(bu) + len(bv):  # met, or at the finest knots: check between
                done, bad_uv = self.check(best)
                if done:
                    break
                if bad_uv is None:  # check samples joined the data: fit again on the same knots
                    continue
                refined = self.halved(bu, bv, bad_uv)
                if len(refined[0]) + len(refined[1]) == len(bu) + len(bv):
                    break  # at the finest knots already
            if (len(refined[0]) + DEGREE - 1) * (len(refined[1]) + DEGREE - 1) > MAX_CONTROL_POINTS:
                break
            bu, bv = refined
        return self.finished(best)

    def halved(self, bu, bv, bad_uv):
        return _halve(bu, bad_uv[:, 0], self.shortest), _halve(bv, bad_uv[:, 1], self.shortest)

    def solve(self, bu: np.ndarray, bv: np.ndarray, rounds: int) -> tuple[dict, np.ndarray, np.ndarray]:
        """The fit on breakpoints (bu, bv) to the vertices, the fit samples and the check samples joined so far:
        (the fit's dict, the data points deviating by more than ``_SPLIT_AT`` of their bound, the border mask)."""
        data = _Samples.joined([self.fit, *self.extra])
        uvd = np.concatenate([self.uv_v, data.uv])
        X = np.concatenate([self.X_v, data.X])
        border = np.concatenate([self.border_v, data.border])
        tu, tv = _clamped(bu), _clamped(bv)
        nu, nv = len(bu) + DEGREE - 1, len(bv) + DEGREE - 1
        B, Bw, A = self.normal(uvd, border, bu, bv)
        M = A + (_PENALTY * A.diagonal().mean()) * _smoothness(nu, nv)
        C = self.factored(M, nu, nv, np.asarray(Bw.T @ X))
        dev_d = np.linalg.norm(B @ C - X, axis=1)
        k, f = len(self.uv_v), len(self.fit.uv)
        best = {"poles": C.reshape(nu, nv, 3), "bu": bu, "bv": bv, "dev": dev_d[:k], "dev_fit": dev_d[k: k + f],
                "dev_check": None, "check": None, "rounds": rounds, "tu": tu, "tv": tv,
                "dev_border": dev_d[: k + f][np.concatenate([self.border_v, self.fit.border])]}
        return best, uvd[dev_d > _SPLIT_AT * np.where(border, _BORDER * self.tol, self.tol)], border

    def normal(self, uv: np.ndarray, border: np.ndarray, bu: np.ndarray, bv: np.ndarray) -> tuple:
        """(B, W B, B^T W B) of the data at uv (N,2) on the breakpoints (bu, bv), W the weights (``border``). On the
        knots of the last call the data only grew (check samples joined): its rows are reused, the new ones added."""
        tu, tv = _clamped(bu), _clamped(bv)
        last = self.last
        k = 0 if last is None or not (np.array_equal(last[0], bu) and np.array_equal(last[1], bv)) else last[2]
        B = _design(uv[k:], tu, tv)
        Bw = B.copy()  # W B, W the weights: B^T W B
        Bw.data *= np.repeat(np.where(border[k:], _BORDER_WEIGHT, 1.0), (DEGREE + 1) ** 2)
        A = (Bw.T @ B).tocsr()
        if k:
            B, Bw, A = sp.vstack([last[3], B], format="csr"), sp.vstack([last[4], Bw], format="csr"), last[5] + A
        self.last = (bu, bv, len(uv), B, Bw, A)
        return B, Bw, A

    def factored(self, M: sp.csr_matrix, nu: int, nv: int, rhs: np.ndarray) -> np.ndarray:
        """M^-1 rhs, M (nu*nv, nu*nv) SPD with the bandwidth of the control net: banded Cholesky where it costs
        under ``_BANDED_FLOPS``, else sparse."""
        from heatparam.solvers import Factor, large_system_backend

        n, band = nu * nv, DEGREE * min(nu, nv) + DEGREE
        if n * band**2 <= _BANDED_FLOPS:
            from scipy.linalg import cho_solve_banded, cholesky_banded

            # unknowns numbered along the longer side of the net: the band is 3 rows of the shorter one
            order = np.arange(n) if nv <= nu else np.arange(n).reshape(nu, nv).T.reshape(-1)
            U = sp.triu(M[order][:, order]).tocoo()
            ab = np.zeros((band + 1, n))
            ab[band + U.row - U.col, U.col] = U.data
            out = np.empty_like(rhs)
            out[order] = cho_solve_banded((cholesky_banded(ab, check_finite=False), False), rhs[order],
                                          check_finite=False)
            return out
        # PARDISO where installed from 10k control points (camelhead's 35k: 3.2 s vs CHOLMOD's 7.8 s, loaded machine)
        return Factor(M.tocsc(), large_system_backend(n, "auto", min_unknowns=10_000)).solve(rhs)

    def check(self, best: dict) -> tuple[bool, np.ndarray | None]:
        """Measure the check samples of ``best``: (no sample deviates?, the deviating samples' uv when none of
        their triangles could join the data, else None: they joined it)."""
        tol, check = self.tol, self.checks(best["bu"], best["bv"])
        dev_c = _deviations(best["poles"].reshape(-1, 3), best["tu"], best["tv"], check.uv, check.X)
        best["dev_check"], best["check"] = dev_c, check
        bad = dev_c > _SPLIT_AT * np.where(check.border, _BORDER * tol, tol)
        if not bad.any():
            return True, None
        faces = np.unique(check.face[bad])
        n = np.bincount(check.face, minlength=faces.max() + 1)[faces]
        new = np.array([self.level.get(int(t), 0) < m for t, m in zip(faces, n, strict=True)], dtype=bool)
        if new.any():  # those triangles' check samples join the data
            self.extra.append(_subset(check, np.isin(check.face, faces[new])))
            self.level.update({int(t): int(m) for t, m in zip(faces[new], n[new], strict=True)})
            return False, None
        return False, check.uv[bad]

    def finished(self, best: dict) -> dict:
        """``best`` with its check deviations (measured now if the last round did not), ``within`` and the
        border's max deviation."""
        if best["dev_check"] is None:
            best["check"] = self.checks(best["bu"], best["bv"])
            best["dev_check"] = _deviations(best["poles"].reshape(-1, 3), best["tu"], best["tv"], best["check"].uv,
                                            best["check"].X)
        worst = max(best["dev"].max(), best["dev_fit"].max(initial=0.0), best["dev_check"].max(initial=0.0))
        best["within"] = bool(worst <= self.tol)
        best["dev_border"] = float(max(best["dev_border"].max(initial=0.0),
                                       best["dev_check"][best["check"].border].max(initial=0.0)))
        return best


# ------------------------------------------------------------------------------------------------------ topology
def _adjacent(Fuv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of faces sharing an uv edge (the uv rows of both its ends): (a (e,), b (e,), the edge's uv rows (e,2))."""
    m = len(Fuv)
    he = np.concatenate([Fuv[:, [0, 1]], Fuv[:, [1, 2]], Fuv[:, [2, 0]]])
    key = np.sort(he, axis=1)
    face = np.tile(np.arange(m), 3)
    order = np.lexsort((key[:, 1], key[:, 0]))
    k, f = key[order], face[order]
    same = (k[1:] == k[:-1]).all(axis=1)
    return f[:-1][same], f[1:][same], k[:-1][same]


def _regions(V: np.ndarray, F: np.ndarray, Fuv: np.ndarray, uv_vertex: np.ndarray, chart: np.ndarray,
             tol: float) -> tuple[np.ndarray, int]:
    """The STEP face of every triangle (m,) and the number of crease edges: connected pieces of each chart (through
    shared uv edges) cut along its creases (:func:`_creases`), pieces under ``_MIN_REGION`` triangles merged back
    into the neighbour they share most edges with."""
    a, b, _ = _adjacent(Fuv)
    keep = chart[a] == chart[b]
    a, b = a[keep], b[keep]
    sharp = _creases(V, F, a, b, tol)
    m = len(F)
    lab = _components(m, a[~sharp], b[~sharp])
    for _ in range(8):  # a small piece between creases joins a neighbour (a crease fragment, not a CAD face)
        size = np.bincount(lab)
        la, lb = lab[a], lab[b]
        cross = la != lb
        src, dst = np.concatenate([la[cross], lb[cross]]), np.concatenate([lb[cross], la[cross]])
        small = size[src] < _MIN_REGION
        if not small.any():
            break
        # each small piece joins the neighbour it shares most edges with; the next round re-checks the sizes
        pairs, counts = np.unique(np.stack([src[small], dst[small]], 1), axis=0, return_counts=True)
        pairs = pairs[np.lexsort((-counts, pairs[:, 0]))]
        first = np.concatenate([[True], pairs[1:, 0] != pairs[:-1, 0]])
        target = np.arange(len(size))
        target[pairs[first, 0]] = pairs[first, 1]
        join = (la == lb) | (target[la] == lb) | (target[lb] == la)
        lab = _components(m, a[join], b[join])
    return lab, int(sharp.sum())


def _unslit(region: np.ndarray, Fuv: np.ndarray, uv: np.ndarray, uv_vertex: np.ndarray) -> tuple[np.ndarray, int]:
    """The regions (m,) cut until none holds both sides of a slit (a seam of the chart cut into it: a mesh edge
    on its border twice), and the number of cuts. A face bounded by both sides would need a seam edge on a surface
    that is not closed, which OpenCascade's BRepCheck rejects (18 of the cow's faces). Each cut is the
    perpendicular bisector, in uv, of the two triangles beside one slit edge: they end up in different pieces."""
    out = region.copy()
    todo, nxt, cuts = list(range(int(region.max()) + 1)), int(region.max()) + 1, 0
    while todo:
        r = todo.pop()
        fr = np.flatnonzero(out == r)
        pair = _slit_pair(Fuv[fr], uv_vertex)
        if pair is None:
            continue
        c = uv[Fuv[fr]].mean(axis=1)
        c1, c2 = c[pair[0]], c[pair[1]]
        side = (c - 0.5 * (c1 + c2)) @ (c2 - c1) > 0
        a, b, _ = _adjacent(Fuv[fr])
        lab = _components(len(fr), a[side[a] == side[b]], b[side[a] == side[b]])
        for k in range(1, lab.max() + 1):
            out[fr[lab == k]] = nxt
            todo.append(nxt)
            nxt += 1
        todo.append(r)
        cuts += 1
    return out, cuts


def _slit_pair(Fr: np.ndarray, uv_vertex: np.ndarray) -> tuple[int, int] | None:
    """The two triangles of Fr (mr,3), rows of uv, on both sides of a slit edge (a mesh edge that is a border edge
    of Fr twice), or None."""
    he = np.concatenate([Fr[:, [0, 1]], Fr[:, [1, 2]], Fr[:, [2, 0]]])
    tri = np.tile(np.arange(len(Fr)), 3)
    _, inv, counts = np.unique(np.sort(he, axis=1), axis=0, return_inverse=True, return_counts=True)
    border = counts[inv.reshape(-1)] == 1
    mesh = np.sort(uv_vertex[he[border]], axis=1)
    _, inv, counts = np.unique(mesh, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    twice = np.flatnonzero(counts[inv] >= 2)
    if not len(twice):
        return None
    i, j = twice[0], twice[inv[twice] == inv[twice[0]]][1]
    return int(tri[border][i]), int(tri[border][j])


def _components(m: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Labels (m,) of the connected components of the graph of m nodes and edges (a, b)."""
    G = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m))
    return connected_components(G, directed=False)[1]


def _creases(V: np.ndarray, F: np.ndarray, a: np.ndarray, b: np.ndarray, tol: float) -> np.ndarray:
    """Which of the adjacent face pairs (a, b) meet at a crease (bool (e,)).

    The dihedral angle θ (between the face normals) is a crease from ``CREASE_ANGLE`` (60°) on, whatever the mesh;
    from ``_SOFT_CREASE_ANGLE`` (20°) on where a smooth surface cannot turn by θ within the tolerance over the two
    triangles: a surface rounding a corner of angle θ over a width d departs from the corner by about d·θ/4
    (a circular arc tangent to both sides at d from the corner), so it needs d <= 4 tol/θ; where the triangles'
    heights h beside the edge are larger (h θ > 4 tol) the knots would have to be finer than the triangles, where
    the fit has no data and ripples. Below 20° a coarse mesh of a smooth surface would fall apart into faces of a
    few triangles; the fit follows those edges (and warns where it cannot)."""
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area2 = np.linalg.norm(n, axis=1)
    n = n / np.maximum(area2, 1e-300)[:, None]
    theta = np.arccos(np.clip(np.einsum("ij,ij->i", n[a], n[b]), -1.0, 1.0))
    # the height of each face over the shared edge: 2 area / |edge|, the edge's length from the faces' common corners
    common = (F[a][:, :, None] == F[b][:, None, :]).any(axis=2)  # (e,3) which corners of a are in b
    ends = np.where(common, F[a], -1)
    ends = np.sort(ends, axis=1)[:, 1:]  # the two shared corners (a non-manifold pair: the last two)
    length = np.linalg.norm(V[ends[:, 0]] - V[ends[:, 1]], axis=1)
    h = 0.5 * (area2[a] + area2[b]) / np.maximum(length, 1e-300)
    hard = theta >= np.deg2rad(CREASE_ANGLE)
    soft = (theta >= np.deg2rad(_SOFT_CREASE_ANGLE)) & (h * theta > 4.0 * tol)
    return hard | soft


class _Piece(NamedTuple):
    """A fitted STEP face before its topology: its surface, its boundary loops (rows of uv, outer first, ordered as
    on the surface: the outer counter-clockwise), whether the face is reversed (a mirrored map) and, per loop and
    border edge, the surface's largest distance from the mesh edge (:func:`_border_gaps`)."""

    surface: object
    loops: list[np.ndarray]
    reverse: bool
    gaps: list[np.ndarray]


class _Chain:
    """One OpenCascade edge: a run of border edges between two corners (:func:`_border_corners`), its mesh
    vertices ``seq`` and the faces along it, each (piece, its uv rows in the order of seq, forward?)."""

    def __init__(self, seq: list[int]):
        self.seq, self.sides, self.gap, self.edge = seq, [], 0.0, None

    def joins(self, seq: list[int], p: int, pieces: list[_Piece]) -> bool | None:
        """Whether the border ``seq`` of piece p runs along this chain the other way round on the surface (so that
        both faces keep the mesh's orientation): None when it cannot share the chain, else its orientation."""
        if len(self.sides) != 1 or seq not in (self.seq, self.seq[::-1]):
            return None
        q, _, fwd = self.sides[0]
        forward = seq == self.seq
        # a slit (both sides on one face) needs a seam edge, which BRepCheck rejects on an open surface: _unslit
        if q == p or (forward ^ pieces[p].reverse) == (fwd ^ pieces[q].reverse):
            return None
        return forward


def _border_gaps(fit: dict, uv: np.ndarray, X_row: np.ndarray, loops: list[np.ndarray]) -> list[np.ndarray]:
    """Per loop (rows of uv), per border edge: the largest distance of the surface over the edge from the mesh
    edge, sampled ``_EDGE_SAMPLES`` times (the edge's tolerance in the STEP file)."""
    a = np.concatenate(loops)
    b = np.concatenate([np.roll(lp, -1) for lp in loops])
    s = np.linspace(0.0, 1.0, _EDGE_SAMPLES)[None, :, None]
    P = ((1 - s) * uv[a][:, None] + s * uv[b][:, None]).reshape(-1, 2)
    X = ((1 - s) * X_row[a][:, None] + s * X_row[b][:, None]).reshape(-1, 3)
    d = _deviations(fit["poles"].reshape(-1, 3), fit["tu"], fit["tv"], P, X).reshape(len(a), -1).max(axis=1)
    return np.split(d, np.cumsum([len(lp) for lp in loops])[:-1])


def _border_corners(pieces: list[_Piece], uv_vertex: np.ndarray) -> set[int]:
    """The mesh vertices where a chain of border edges ends: where a face's border turns to another neighbour (or
    to none), where more than two border edges meet and, on a loop without such a vertex, its lowest and highest
    mesh vertex (both faces along a closed border then cut it at the same vertices)."""
    faces_of: dict = {}
    for p, piece in enumerate(pieces):
        for lp in piece.loops:
            m = uv_vertex[lp].tolist()
            for a, b in zip(m, m[1:] + m[:1], strict=True):
                faces_of.setdefault((min(a, b), max(a, b)), []).append(p)
    at: dict = {}
    for key in faces_of:
        for v in key:
            at.setdefault(v, []).append(key)
    corners = {v for v, keys in at.items()
               if len(keys) != 2 or sorted(faces_of[keys[0]]) != sorted(faces_of[keys[1]])}
    for piece in pieces:
        for lp in piece.loops:
            m = uv_vertex[lp]
            if corners.isdisjoint(m.tolist()):
                corners.update((int(m.min()), int(m.max())))
    return corners


def _chain_positions(m: list[int], corners: set[int]) -> list[list[int]]:
    """A loop's positions (m: their mesh vertices) cut at the corners: per chain, its consecutive positions from
    one corner to the next, round the loop (one corner: the whole loop, back to it)."""
    n = len(m)
    cuts = [i for i, v in enumerate(m) if v in corners]
    out = []
    for j, i in enumerate(cuts):
        span = (cuts[(j + 1) % len(cuts)] - i) % n or n
        out.append([(i + s) % n for s in range(span + 1)])
    return out


def _chains(pieces: list[_Piece], uv_vertex: np.ndarray, share: bool) -> tuple[list[_Chain], list[list[list]]]:
    """The border chains of all pieces and, per piece and loop, its chains in order, each (chain, forward?). With
    ``share``, the faces on both sides of a chain use the same one (opposite ways round); else each its own."""
    corners = _border_corners(pieces, uv_vertex)
    chains: list[_Chain] = []
    index: dict = {}
    wires = []
    for p, piece in enumerate(pieces):
        wires.append([])
        for lp, gaps in zip(piece.loops, piece.gaps, strict=True):
            m = uv_vertex[lp].tolist()
            wire = []
            for pos in _chain_positions(m, corners):
                seq = [m[i] for i in pos]
                key = tuple(sorted(seq))
                chain = index.get(key) if share else None
                forward = None if chain is None else chain.joins(seq, p, pieces)
                if forward is None:
                    chain, forward = _Chain(seq), True
                    chains.append(chain)
                    index.setdefault(key, chain)
                chain.sides.append((p, lp[pos] if forward else lp[pos][::-1], forward))
                chain.gap = max(chain.gap, float(gaps[pos[:-1]].max()))
                wire.append((chain, forward))
            wires[-1].append(wire)
    return chains, wires


# ---------------------------------------------------------------------------------------------- OpenCascade part
def _occ_surface(fit: dict):
    # OCP 8 (OpenCascade 8.0): the NCollection arrays are OCP.collections' templates
    from OCP.collections import Array1_double as TColStd_Array1OfReal
    from OCP.collections import Array1_int as TColStd_Array1OfInteger
    from OCP.collections import Array2_gp_Pnt as TColgp_Array2OfPnt
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    P = fit["poles"]
    nu, nv = P.shape[:2]
    poles = TColgp_Array2OfPnt(1, nu, 1, nv)
    for i in range(nu):
        for j in range(nv):
            x, y, z = P[i, j]
            poles.SetValue(i + 1, j + 1, gp_Pnt(float(x), float(y), float(z)))

    def knots(b):
        kn, mu = TColStd_Array1OfReal(1, len(b)), TColStd_Array1OfInteger(1, len(b))
        for i, t in enumerate(b):
            kn.SetValue(i + 1, float(t))
            mu.SetValue(i + 1, DEGREE + 1 if i in (0, len(b) - 1) else 1)
        return kn, mu

    uk, um = knots(fit["bu"])
    vk, vm = knots(fit["bv"])
    return Geom_BSplineSurface(poles, uk, vk, um, vm, DEGREE, DEGREE)


def _polyline(points: np.ndarray, d: int):
    """A degree-1 B-spline curve (3D for d = 3, 2D for d = 2) through the points (k,d), parameter 0..k-1."""
    from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_gp_Pnt2d, Array1_int
    from OCP.Geom import Geom_BSplineCurve
    from OCP.Geom2d import Geom2d_BSplineCurve
    from OCP.gp import gp_Pnt, gp_Pnt2d

    k = len(points)
    poles = Array1_gp_Pnt(1, k) if d == 3 else Array1_gp_Pnt2d(1, k)
    make = gp_Pnt if d == 3 else gp_Pnt2d
    knots, mults = Array1_double(1, k), Array1_int(1, k)
    for i, p in enumerate(points.tolist()):
        poles.SetValue(i + 1, make(*p))
        knots.SetValue(i + 1, float(i))
        mults.SetValue(i + 1, 2 if i in (0, k - 1) else 1)
    return (Geom_BSplineCurve if d == 3 else Geom2d_BSplineCurve)(poles, knots, mults, 1)


def _occ_edges(chains: list[_Chain], pieces: list[_Piece], uv: np.ndarray, X_row: np.ndarray, floor: float) -> float:
    """Make every chain's edge (``chain.edge``): its 3D curve the mesh's border polyline, one pcurve per face (the
    uv polyline on its surface), its tolerance the largest gap between them (x ``_EDGE_MARGIN``, at least
    ``floor``); the vertices, one per mesh vertex, as tolerant as their edges. Returns the largest edge
    tolerance."""
    from OCP.BRep import BRep_Builder
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS_Edge, TopoDS_Vertex

    bld, loc = BRep_Builder(), TopLoc_Location()
    verts: dict = {}
    vtol: dict = {}
    for chain in chains:
        tol = max(_EDGE_MARGIN * chain.gap, floor)
        rows = chain.sides[0][1]
        for v, r in ((chain.seq[0], rows[0]), (chain.seq[-1], rows[-1])):
            if v not in verts:
                verts[v] = TopoDS_Vertex()
                bld.MakeVertex(verts[v], gp_Pnt(*X_row[r].tolist()), tol)
            vtol[v] = max(vtol.get(v, 0.0), tol)
        edge = TopoDS_Edge()
        bld.MakeEdge(edge, _polyline(X_row[rows], 3), tol)
        bld.Add(edge, verts[chain.seq[0]].Oriented(TopAbs_FORWARD))
        bld.Add(edge, verts[chain.seq[-1]].Oriented(TopAbs_REVERSED))
        for p, r, _ in chain.sides:
            bld.UpdateEdge(edge, _polyline(uv[r], 2), pieces[p].surface, loc, tol)
        bld.Range(edge, 0.0, float(len(rows) - 1))
        bld.SameParameter(edge, True)
        bld.SameRange(edge, True)
        chain.edge = edge
    for v, t in vtol.items():
        bld.UpdateVertex(verts[v], t)
    return max(max(_EDGE_MARGIN * c.gap, floor) for c in chains)


def _occ_faces(pieces: list[_Piece], wires: list[list[list]], floor: float) -> list:
    """The face of every piece: its surface bounded by its loops' wires of chain edges, reversed for a mirrored
    map (its normal then follows the mesh's)."""
    from OCP.BRep import BRep_Builder
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Wire

    bld = BRep_Builder()
    faces = []
    for piece, loops in zip(pieces, wires, strict=True):
        face = TopoDS_Face()
        bld.MakeFace(face, piece.surface, TopLoc_Location(), floor)
        for loop in loops:
            wire = TopoDS_Wire()
            bld.MakeWire(wire)
            for chain, forward in loop:
                bld.Add(wire, chain.edge if forward else chain.edge.Reversed())
            wire.Closed(True)
            bld.Add(face, wire)
        faces.append(TopoDS.Face(face.Reversed()) if piece.reverse else face)
    return faces


def _joined(faces: list, chains: list[_Chain]):
    """The faces as shells, one per connected set (faces sharing chains); a closed one (every chain with two
    sides) as a solid, outward. One part: itself, else a compound of them."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.TopoDS import TopoDS_Shell, TopoDS_Solid

    bld = BRep_Builder()
    pairs = np.array([(c.sides[0][0], c.sides[1][0]) for c in chains if len(c.sides) == 2], dtype=np.int64)
    lab = _components(len(faces), *pairs.reshape(-1, 2).T)
    open_ = {c.sides[0][0] for c in chains if len(c.sides) == 1}
    parts = []
    for k in range(lab.max() + 1):
        shell = TopoDS_Shell()
        bld.MakeShell(shell)
        members = np.flatnonzero(lab == k)
        for p in members:
            bld.Add(shell, faces[p])
        if open_.isdisjoint(members.tolist()):
            shell.Closed(True)
            solid = TopoDS_Solid()
            bld.MakeSolid(solid)
            bld.Add(solid, shell)
            props = GProp_GProps()
            BRepGProp.VolumeProperties_s(solid, props)
            if props.Mass() < 0:  # the shell faces inwards (a mesh oriented inwards): turned round
                solid = TopoDS_Solid()
                bld.MakeSolid(solid)
                bld.Add(solid, shell.Reversed())
            parts.append(solid)
        else:
            parts.append(shell)
    return parts[0] if len(parts) == 1 else _compound(parts)


def _valid(shape) -> bool:
    from OCP.BRepCheck import BRepCheck_Analyzer

    return bool(BRepCheck_Analyzer(shape).IsValid())


def _area(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    # adaptive, to a relative 1e-4: the fixed Gauss rule was 14% short on a face bounded by long polyline edges
    BRepGProp.SurfaceProperties_s(shape, props, 1e-4)
    return float(props.Mass())


@contextlib.contextmanager
def _quiet_and_units(unit: str | None, precision: float | None = None):
    """Silence OpenCascade's console messages, set the STEP length units and the uncertainty the file declares
    (``precision``, in the model units; None = OpenCascade's default, the shape's least tolerance); all restored
    afterwards (they are process-wide)."""
    from OCP.Interface import Interface_Static
    from OCP.Message import Message, Message_Gravity
    from OCP.STEPControl import STEPControl_Controller

    STEPControl_Controller.Init_s()
    printers = Message.DefaultMessenger_s().Printers()
    levels = [printers.Value(i).GetTraceLevel() for i in range(1, printers.Length() + 1)]
    keys = ("write.step.unit", "xstep.cascade.unit")
    old = {k: Interface_Static.CVal_s(k) for k in keys}
    old_precision = Interface_Static.IVal_s("write.precision.mode"), Interface_Static.RVal_s("write.precision.val")
    try:
        for i in range(1, printers.Length() + 1):
            printers.Value(i).SetTraceLevel(Message_Gravity.Message_Fail)
        if unit is not None:
            for k in keys:
                Interface_Static.SetCVal_s(k, unit)
        if precision is not None:
            Interface_Static.SetIVal_s("write.precision.mode", 2)  # 2: write.precision.val
            Interface_Static.SetRVal_s("write.precision.val", float(precision))
        yield
    finally:
        Interface_Static.SetIVal_s("write.precision.mode", old_precision[0])
        Interface_Static.SetRVal_s("write.precision.val", old_precision[1])
        for k, v in old.items():
            if v:
                Interface_Static.SetCVal_s(k, v)
        for i, lev in enumerate(levels, start=1):
            printers.Value(i).SetTraceLevel(lev)


def _write_shape(shape, path: Path, unit: str, name: str | None = None, precision: float | None = None) -> None:
    from OCP.APIHeaderSection import APIHeaderSection_MakeHeader
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.StepBasic import StepBasic_Product
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
    from OCP.TCollection import TCollection_HAsciiString

    if not path.parent.exists():
        raise HeatparamError(f"cannot write {path}: folder {path.parent} does not exist (create it first)")
    shown = Path(name) if name else path  # the file's own name in its header (not a temporary's)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp.step", dir=path.parent)
    os.close(fd)
    try:
        with _quiet_and_units(unit, precision):
            w = STEPControl_Writer()
            if w.Transfer(shape, STEPControl_AsIs) != IFSelect_RetDone:
                raise HeatparamError(f"cannot write {path}: OpenCascade could not translate the faces to STEP")
            model = w.Model()
            for i in range(1, model.NbEntities() + 1):  # OpenCascade numbers the products it writes in a process
                ent = model.Value(i)
                if isinstance(ent, StepBasic_Product):
                    ent.SetName(TCollection_HAsciiString(shown.stem or "heatparam"))
                    ent.SetId(TCollection_HAsciiString(shown.stem or "heatparam"))
            hdr = APIHeaderSection_MakeHeader(model)
            hdr.SetTimeStamp(TCollection_HAsciiString(TIME_STAMP))
            hdr.SetOriginatingSystem(TCollection_HAsciiString("heatparam"))
            hdr.SetName(TCollection_HAsciiString(shown.name))
            if w.Write(tmp) != IFSelect_RetDone:
                raise HeatparamError(f"cannot write {path}: the STEP writer failed")
        os.chmod(tmp, file_mode())  # mkstemp's 0600 -> what a plain open() would have given
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# ------------------------------------------------------------------------------------------------------ public API
def write_step(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray | None = None,
               uv_vertex: np.ndarray | None = None, chart: np.ndarray | None = None, tolerance: float | None = None,
               units: str = "mm", name: str | None = None) -> dict:
    """Write a map as a STEP file of trimmed bicubic B-spline faces, one per chart (see the module docstring).

    Parameters
    ----------
    path : output ``.step``/``.stp``; written atomically (temporary file beside it, renamed on success).
    name : the file name recorded in the STEP header and product (default: ``path``'s); the writing contract
        writes to a temporary and passes the final name, so the same map gives the same bytes.
    V : (n,3) float64 vertices. F : (m,3) int64 triangles. uv : (k,2) float64 the map (``Result.uv``). Fuv : (m,3)
        rows of uv at each face's corners (None = F). uv_vertex : (k,) the vertex of each uv row (None = arange(k)).
    chart : (m,) int chart id per face, or None (one chart).
    tolerance : max deviation of the surface from the mesh, both ways, in model units; None = 0.1% of the bounding
        box diagonal of V.
    units : length unit the coordinates are in and the file declares: ``mm``, ``cm``, ``m``, ``in``, ``ft``.

    Returns
    -------
    dict, the fit report (docs/formats.md, "STEP"): ``tolerance``, ``faces``, ``sewn`` (joined by shared edges),
    ``valid`` (as read back), ``shells``, ``solids``, ``free_edges``, ``area_mesh``, ``area_faces``, ``creases``,
    ``slit_cuts``, ``tolerance_splits``; the achieved
    deviations both ways, ``max_vertex_deviation`` (``|S(uv_i) - V_i|``) and ``max_surface_deviation`` (``|S(uv) -
    X(uv)|`` at points inside every triangle; both upper bounds of the distances), ``max_deviation``,
    ``rms_deviation``, ``within_tolerance``; ``step_faces`` (per face: chart, size, deviations, ``worst_at``,
    ``within_tolerance``, ``valid``), ``charts``; ``warnings``: one line per face off the tolerance (where, by how
    much), invalid face or shape, free edges of a closed mesh, faces left unjoined, each also issued as a
    :class:`StepToleranceWarning` (a caller that prints the list itself can filter that category).
    """
    t0 = time.perf_counter()
    _require_ocp()
    V, F, uv, Fuv, uv_vertex, chart, tol = _checked_inputs(V, F, uv, Fuv, uv_vertex, chart, tolerance, units)
    region, creases = _regions(V, F, Fuv, uv_vertex, chart, tol)
    region, slit_cuts = _unslit(region, Fuv, uv, uv_vertex)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    fitted = _fitted_faces(region, chart, Fuv, uv, V[uv_vertex], tol, diag, units)
    reports, notes = fitted.reports, fitted.notes
    shape, sewn, valid = _written(fitted, uv, uv_vertex, V[uv_vertex], tol, Path(path), units, name)
    shells, free = _topology(shape)
    if free and _closed(F):
        notes.append(f"the mesh is closed but the STEP shape has {free} free edges (not closed)")
    for note in notes:
        _warnings.warn(note, StepToleranceWarning, stacklevel=2)
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    dev = np.concatenate(fitted.devs)
    return {
        "tolerance": tol, "units": units, "degree": [DEGREE, DEGREE], "faces": len(reports), "sewn": sewn,
        "valid": valid, "shells": shells, "solids": _count(shape, "SOLID"), "free_edges": free,
        "area_mesh": float(0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()), "area_faces": _area(shape),
        "creases": creases, "slit_cuts": slit_cuts, "tolerance_splits": fitted.splits,
        "max_deviation": max(f["max_deviation"] for f in reports),
        "max_vertex_deviation": max(f["max_vertex_deviation"] for f in reports),
        "max_surface_deviation": max(f["max_surface_deviation"] for f in reports),
        "rms_deviation": float(np.sqrt(np.mean(dev**2))),
        "within_tolerance": all(f["within_tolerance"] for f in reports),
        "control_points": int(sum(a * b for a, b in (f["control_points"] for f in reports))),
        "seconds": time.perf_counter() - t0, "step_faces": reports, "charts": _chart_reports(reports),
        "warnings": notes,
    }


class _Fitted(NamedTuple):
    """The STEP faces of a map before their topology: the fitted pieces, their reports, their vertex deviations,
    the warnings so far and how many faces were split because their fit missed the tolerance."""

    pieces: list[_Piece]
    reports: list[dict]
    devs: list[np.ndarray]
    notes: list[str]
    splits: int


def _fitted_faces(region: np.ndarray, chart: np.ndarray, Fuv: np.ndarray, uv: np.ndarray, X_row: np.ndarray,
                  tol: float, diag: float, units: str) -> _Fitted:
    """One fitted piece per region (:func:`_region_face`); a region whose fit misses the tolerance is split
    (:func:`_split`, its failing triangles carved out first) up to ``_MAX_SPLITS`` deep, and what still misses
    is reported in the notes."""
    out = _Fitted([], [], [], [], 0)
    todo = [(np.flatnonzero(region == r), 0) for r in range(region.max() + 1)]
    splits = 0
    while todo:
        fr, depth = todo.pop(0)
        piece, report, dev, off = _region_face(len(out.pieces), int(chart[fr[0]]), Fuv[fr], uv, X_row, tol)
        if not report["within_tolerance"] and len(fr) > 1 and depth < _MAX_SPLITS:
            parts = _split(uv, Fuv[fr], off if depth == 0 else None)
            todo[:0] = [(fr[p], depth + 1) for p in parts]
            splits += 1
            continue
        report["face"] = len(out.pieces)
        out.pieces.append(piece)
        out.reports.append(report)
        out.devs.append(dev)
        if not report["within_tolerance"]:
            out.notes.append(_miss(report, tol, diag, units))
    return out._replace(splits=splits)


def _built(pieces: list[_Piece], uv: np.ndarray, uv_vertex: np.ndarray, X_row: np.ndarray, tol: float,
           share: bool) -> tuple[object, list[bool], float]:
    """The OpenCascade shape of the pieces: (with ``share``, faces joined by shared edges into shells or solids,
    :func:`_joined`; else a compound of faces with edges of their own), each face's validity, the largest edge
    tolerance."""
    chains, wires = _chains(pieces, uv_vertex, share)
    floor = 1e-3 * tol
    precision = _occ_edges(chains, pieces, uv, X_row, floor)
    faces = _occ_faces(pieces, wires, floor)
    shape = _joined(faces, chains) if share else _compound(faces)
    return shape, [_valid(f) for f in faces], precision


def _written(fitted: _Fitted, uv: np.ndarray, uv_vertex: np.ndarray, X_row: np.ndarray, tol: float, path: Path,
             units: str, name: str | None) -> tuple[object, bool, bool]:
    """Build the faces joined along their shared borders (:func:`_built`), write them and read the file back:
    (the shape written, joined?, valid as read back); what went wrong goes into ``fitted.notes`` and the faces'
    reports get their validity.

    The file declares the largest edge tolerance as its uncertainty: with the default (the least tolerance of the
    shape) OpenCascade's reader filled the gaps at vertices with tiny edges. A joined shape that is (or reads
    back) invalid is written again as separate faces."""
    notes = fitted.notes
    shape, valid_faces, precision = _built(fitted.pieces, uv, uv_vertex, X_row, tol, share=True)
    joined = _valid(shape)
    if joined:
        _write_shape(shape, path, UNITS[units][0], name, precision=precision)
        joined = _valid(read_step(path)[0])
    if not joined:
        shape, valid_faces, precision = _built(fitted.pieces, uv, uv_vertex, X_row, tol, share=False)
        _write_shape(shape, path, UNITS[units][0], name, precision=precision)
        notes.append("the faces joined along their borders are (or read back) invalid: they are written unjoined")
    for report, ok in zip(fitted.reports, valid_faces, strict=True):
        report["valid"] = ok
        if not ok:
            notes.append(f"STEP face {report['face']} (chart {report['chart']}): OpenCascade's BRepCheck reports "
                         "it invalid")
    valid = joined or _valid(read_step(path)[0])
    if not valid:
        notes.append("the STEP file reads back invalid (OpenCascade's BRepCheck)")
    return shape, joined, valid


class StepToleranceWarning(UserWarning):
    """A STEP face off the fit tolerance (or invalid, or left unjoined): the message says where and by how much."""


def _miss(face: dict, tol: float, diag: float, units: str) -> str:
    """The warning of a face off the tolerance: where and by how much."""
    d = face["max_deviation"]
    x, y, z = face["worst_at"]
    nu, nv = face["control_points"]
    return (f"STEP face {face['face']} (chart {face['chart']}, {face['triangles']} triangles): the surface is up to "
            f"{d:.4g} {units} off the mesh near ({x:.4g}, {y:.4g}, {z:.4g}) = {d / tol:.2f}x the fit tolerance "
            f"{tol:.4g} ({100 * d / diag:.3g}% of the diagonal; mesh vertices to the surface "
            f"{face['max_vertex_deviation'] / tol:.2f}x, surface to the mesh "
            f"{face['max_surface_deviation'] / tol:.2f}x) at {nu}x{nv} control points")


def _chart_reports(faces: list[dict]) -> list[dict]:
    """The per-chart summary of the per-face reports."""
    out = {}
    for f in faces:
        c = out.setdefault(f["chart"], {"chart": f["chart"], "faces": 0, "vertices": 0, "control_points": 0,
                                        "degree": [DEGREE, DEGREE], "max_deviation": 0.0, "within_tolerance": True})
        c["faces"] += 1
        c["vertices"] += f["vertices"]
        c["control_points"] += f["control_points"][0] * f["control_points"][1]
        c["max_deviation"] = max(c["max_deviation"], f["max_deviation"])
        c["within_tolerance"] &= f["within_tolerance"]
    return [out[k] for k in sorted(out)]


def _closed(F: np.ndarray) -> bool:
    """Whether every edge of F (m,3) has two faces."""
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    key = e[:, 0] * (int(F.max()) + 1) + e[:, 1]
    _, counts = np.unique(key, return_counts=True)
    return bool((counts == 2).all())


def _topology(shape) -> tuple[int, int]:
    """(shells, free edges: the non-degenerate edges of ``shape`` bounding a single face)."""
    from OCP.BRep import BRep_Tool
    from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EdgeFaces
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS

    m = EdgeFaces()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, m)
    free = sum(1 for i in range(1, m.Extent() + 1)
               if m.FindFromIndex(i).Size() == 1 and not BRep_Tool.Degenerated_s(TopoDS.Edge(m.FindKey(i))))
    return _count(shape, "SHELL"), free


def _count(shape, kind: str) -> int:
    """The number of sub-shapes of a kind (``FACE``, ``SHELL``...) in ``shape``."""
    from OCP import TopAbs
    from OCP.TopExp import TopExp_Explorer

    n = 0
    ex = TopExp_Explorer(shape, getattr(TopAbs, f"TopAbs_{kind}"))
    while ex.More():
        n += 1
        ex.Next()
    return n


def _checked_inputs(V, F, uv, Fuv, uv_vertex, chart, tolerance, units) -> tuple:
    """:func:`write_step`'s arguments as arrays of the right dtypes, checked, with ``chart`` filled in (None ->
    zeros) and the tolerance resolved: (V, F, uv, Fuv, uv_vertex, chart, tol). Raises HeatparamError."""
    if units not in UNITS:
        raise HeatparamError(f"unknown STEP units {units!r}: use one of {', '.join(UNITS)}")
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    uv = np.asarray(uv, dtype=np.float64)
    Fuv = F if Fuv is None else np.asarray(Fuv, dtype=np.int64)
    uv_vertex = np.arange(len(uv)) if uv_vertex is None else np.asarray(uv_vertex, dtype=np.int64)
    if (V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or uv.ndim != 2
            or uv.shape[1] != 2 or Fuv.shape != F.shape or len(uv_vertex) != len(uv)):
        raise HeatparamError("cannot write STEP: V must be (n,3), F (m,3), uv (k,2), Fuv like F and uv_vertex (k,)")
    if (F.min() < 0 or F.max() >= len(V) or Fuv.min() < 0 or Fuv.max() >= len(uv) or uv_vertex.min() < 0
            or uv_vertex.max() >= len(V)):
        raise HeatparamError("cannot write STEP: F, Fuv or uv_vertex holds an index out of range")
    if not (np.isfinite(uv).all() and np.isfinite(V).all()):
        raise HeatparamError("cannot write STEP: the map or the mesh has NaN or infinite coordinates")
    chart = np.zeros(len(F), dtype=np.int64) if chart is None else np.asarray(chart).reshape(-1)
    if len(chart) != len(F):
        raise HeatparamError(f"cannot write STEP: chart has {len(chart)} entries for {len(F)} faces")
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    tol = 1e-3 * diag if tolerance is None else float(tolerance)
    if not tol > 0:
        raise HeatparamError(f"the fit tolerance must be positive (got {tolerance})")
    return V, F, uv, Fuv, uv_vertex, chart, tol


def _split(uv: np.ndarray, Fr: np.ndarray, off: np.ndarray | None) -> list[np.ndarray]:
    """The triangles Fr (mr,3) (rows of uv) of a face off the tolerance in several connected pieces (a list of index
    arrays into Fr). Where the triangles off the tolerance (``off`` (mr,)), grown by ``_CARVE_RINGS`` rings of
    neighbours, are under a quarter of the face: those and the rest (a spike or a crease end on a large smooth
    face: camelhead's 22.7k-triangle face missed the tolerance at 2 vertices, 1.07 tol, when the knots had reached
    1/8 of the triangles); else (or with ``off`` None: a piece that missed again) two halves at the median of the
    centroids along the longer side of their uv box.
    """
    a, b, _ = _adjacent(Fr)
    side = np.zeros(len(Fr), dtype=bool) if off is None else off.copy()
    for _ in range(_CARVE_RINGS):
        side[a[side[b]]] = True
        side[b[side[a]]] = True
    if not side.any() or side.sum() > len(Fr) // 4:
        c = uv[Fr].mean(axis=1)
        axis = int(np.argmax(np.ptp(c, axis=0)))
        side = c[:, axis] > np.median(c[:, axis])
        if side.all() or not side.any():
            side = np.arange(len(Fr)) >= len(Fr) // 2
    same = side[a] == side[b]
    lab = _components(len(Fr), a[same], b[same])
    return [np.flatnonzero(lab == k) for k in range(lab.max() + 1)]


def _region_face(k: int, c: int, Fr: np.ndarray, uv: np.ndarray, X_row: np.ndarray, tol: float
                 ) -> tuple[_Piece, dict, np.ndarray, np.ndarray]:
    """Fit one STEP face (the triangles Fr (mr,3), rows of uv, of chart c; face number k): (the piece: its surface
    and boundary loops, its report entry, its vertex deviations, which triangles are off the tolerance)."""
    rows = np.unique(Fr)
    loops = boundary_loops(Fr)
    on_border = np.zeros(len(uv), dtype=bool)
    for lp in loops:
        on_border[lp] = True
    # the edge opposite each corner (rows of uv) is a border edge when no other triangle has it
    opposite = np.stack([Fr[:, [1, 2]], Fr[:, [2, 0]], Fr[:, [0, 1]]], axis=1)  # (m,3,2)
    key = np.sort(opposite, axis=2).reshape(-1, 2)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    border = (counts[inv.reshape(-1)] == 1).reshape(-1, 3)
    data = _Samples(uv, X_row, Fr, _FIT_POINTS, border)
    intervals = int(np.clip(np.ceil(0.5 * np.sqrt(len(Fr))), 2, _START_INTERVALS))  # not finer than the triangles

    def checks(bu, bv):
        return _check_samples(uv, X_row, Fr, border, bu, bv)

    fit = _fit_surface(uv[rows], X_row[rows], on_border[rows], data, checks, tol, intervals)
    check = fit["check"]
    piece = _piece(fit, uv, X_row, loops)
    dev = fit["dev"]
    # where: the worst of the vertices, the fitted samples and the checked ones
    where = [(dev, X_row[rows]), (fit["dev_fit"], data.X), (fit["dev_check"], check.X)]
    d, X = max(where, key=lambda w: w[0].max(initial=0.0))
    at = X[int(np.argmax(d))]
    worst_v, worst_s = float(dev.max()), float(max(fit["dev_fit"].max(initial=0.0), fit["dev_check"].max(initial=0.0)))
    report = {
        "face": k, "chart": c, "triangles": int(len(Fr)), "vertices": int(len(rows)),
        "control_points": [int(s) for s in fit["poles"].shape[:2]], "degree": [DEGREE, DEGREE],
        "knot_rounds": int(fit["rounds"]),
        "max_deviation": max(worst_v, worst_s), "max_vertex_deviation": worst_v, "max_surface_deviation": worst_s,
        "deviation_over_tolerance": max(worst_v, worst_s) / tol, "worst_at": [float(x) for x in at],
        "max_border_deviation": fit["dev_border"], "within_tolerance": fit["within"], "valid": True,
    }
    # the triangles off the tolerance: a sample in them, or a corner, deviates by more than tol
    off = np.zeros(len(Fr), dtype=bool)
    off[data.face[fit["dev_fit"] > tol]] = True
    off[check.face[fit["dev_check"] > tol]] = True
    off |= np.isin(Fr, rows[dev > tol]).any(axis=1)
    return piece, report, dev, off


def _piece(fit: dict, uv: np.ndarray, X_row: np.ndarray, loops: list[np.ndarray]) -> _Piece:
    """The piece of a fitted surface bounded by the loops (rows of uv) of one connected piece of a chart: the outer
    loop first and counter-clockwise on the surface, holes clockwise (a mirrored map's loops reversed, its face
    reversed)."""
    areas = np.array([polygon_area(uv[lp]) for lp in loops])
    outer = int(np.argmax(np.abs(areas)))
    reverse = bool(areas[outer] < 0)  # a mirrored map: uv loops run clockwise, the surface normal is flipped
    ordered = [loops[outer]] + [lp for i, lp in enumerate(loops) if i != outer]
    if reverse:
        ordered = [lp[::-1] for lp in ordered]
    return _Piece(_occ_surface(fit), ordered, reverse, _border_gaps(fit, uv, X_row, ordered))


def _compound(faces: list):
    """A compound of the faces, unjoined."""
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    comp = TopoDS_Compound()
    bld = BRep_Builder()
    bld.MakeCompound(comp)
    for f in faces:
        bld.Add(comp, f)
    return comp


def read_step(path: str | os.PathLike, units: str | None = None):
    """Read a STEP file with OpenCascade: returns (shape, file_units), the shape's coordinates in ``units``
    (one of :data:`UNITS`' keys; None = the file's own unit) and file_units the length unit the file declares
    (OpenCascade's name, e.g. ``millimetre``, ``INCH``)."""
    _require_ocp()
    from OCP.collections import Sequence_TCollection_AsciiString
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    with _quiet_and_units(None):
        r = STEPControl_Reader()
        if r.ReadFile(str(path)) != IFSelect_RetDone:
            raise HeatparamError(f"cannot read {path} as STEP")
        lengths, angles, solid = (Sequence_TCollection_AsciiString() for _ in range(3))
        r.FileUnits(lengths, angles, solid)
        names = [lengths.Value(i).ToCString() for i in range(1, lengths.Length() + 1)]
        file_unit = names[0] if names else "millimetre"
        if units is None:
            mm = {"millimetre": 1.0, "centimetre": 10.0, "metre": 1000.0, "INCH": 25.4, "FOOT": 304.8}
            scale = mm.get(file_unit, 1.0)
        else:
            scale = UNITS[units][1]
        r.SetSystemLengthUnit(scale)
        r.TransferRoots()
        shape = r.OneShape()
    return shape, file_unit


def _distances(shape, P: np.ndarray) -> np.ndarray:
    """(p,) distance of each point P (p,3) to the faces of ``shape``, each an upper bound (a distance to a point of
    the shape): a point's projection on each face's surface (``ShapeAnalysis_Surface.NextValueOfUV`` from the
    nearest of a grid of surface samples, a local projection; the points over 0.9 of the max again with the global
    ``ValueOfUV``) counts where its foot lies on the face (``IntTools_FClass2d``: in or on the border); a point with
    no such foot is measured to the shape's edges by ``BRepExtrema_DistShapeShape``."""
    from OCP.gp import gp_Pnt

    span = float(np.linalg.norm(P.max(0) - P.min(0))) if len(P) else 1.0
    prec = 1e-9 * span
    dist = np.full(len(P), np.inf)
    pts = [gp_Pnt(float(x), float(y), float(z)) for x, y, z in P]
    faces = _project_local(shape, P, pts, prec, dist)
    _project_global(faces, pts, prec, dist)
    rest = np.flatnonzero(~np.isfinite(dist))
    if len(rest):
        _edge_distances(shape, pts, rest, dist)
    # a point on a face's border can have its foot on another face's border far away (a cube's corner on the
    # opposite side) and none on its own faces: the points that could hold the max are measured to the edges too
    done = np.zeros(len(dist), dtype=bool)
    done[rest] = True
    while len(dist):
        todo = np.flatnonzero(~done & (dist >= 0.9 * dist.max()))
        if not len(todo):
            break
        _edge_distances(shape, pts, todo, dist)
        done[todo] = True
    return dist


def _project_local(shape, P: np.ndarray, pts: list, prec: float, dist: np.ndarray) -> list[tuple]:
    """Lower ``dist`` (p,) in place to each point's local projection on every face of ``shape`` whose foot lies on
    the face; returns the (ShapeAnalysis_Surface, IntTools_FClass2d) of each face."""
    from OCP.BRep import BRep_Tool
    from OCP.gp import gp_Pnt2d
    from OCP.IntTools import IntTools_FClass2d
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface
    from OCP.TopAbs import TopAbs_FACE, TopAbs_IN, TopAbs_ON
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS
    from scipy.spatial import cKDTree

    faces = []
    ex = TopExp_Explorer(shape, TopAbs_FACE)
    while ex.More():
        face = TopoDS.Face(ex.Current())
        surf = BRep_Tool.Surface_s(face)
        sas = ShapeAnalysis_Surface(surf)
        cls = IntTools_FClass2d(face, max(BRep_Tool.Tolerance_s(face), prec))
        # start points: the nearest of a grid of surface samples (3 per pole span), then a local projection
        u0, u1, v0, v1 = surf.Bounds()
        nu = 3 * getattr(surf, "NbUPoles", lambda: 64)() + 1
        nv = 3 * getattr(surf, "NbVPoles", lambda: 64)() + 1
        us, vs = np.linspace(u0, u1, nu), np.linspace(v0, v1, nv)
        grid = np.array([[surf.Value(float(u), float(v)).Coord() for v in vs] for u in us]).reshape(-1, 3)
        _, near = cKDTree(grid).query(P)
        for i, p in enumerate(pts):
            start = gp_Pnt2d(float(us[near[i] // nv]), float(vs[near[i] % nv]))
            uv = sas.NextValueOfUV(start, p, prec)
            gap = sas.Gap()
            if gap < dist[i] and cls.Perform(uv) in (TopAbs_IN, TopAbs_ON):
                dist[i] = gap
        faces.append((sas, cls))
        ex.Next()
    return faces


def _project_global(faces: list[tuple], pts: list, prec: float, dist: np.ndarray) -> None:
    """A local projection can stop in a farther local minimum: the points that could hold the maximum (over 0.9 of
    it) are projected again with OpenCascade's global search, until no other point can (the max is then that of
    the global search; the others stay upper bounds). Lowers ``dist`` in place."""
    from OCP.TopAbs import TopAbs_IN, TopAbs_ON

    redone = np.zeros(len(dist), dtype=bool)
    while True:
        finite = dist[np.isfinite(dist)]
        if not len(finite):
            break
        todo = np.flatnonzero(~redone & np.isfinite(dist) & (dist > 0.9 * finite.max()))
        if not len(todo):
            break
        for i in todo:
            for sas, cls in faces:
                uv = sas.ValueOfUV(pts[i], prec)
                gap = sas.Gap()
                if gap < dist[i] and cls.Perform(uv) in (TopAbs_IN, TopAbs_ON):
                    dist[i] = gap
        redone[todo] = True


def _edge_distances(shape, pts: list, rest: np.ndarray, dist: np.ndarray) -> None:
    """Lower ``dist[rest]`` to the distance of those points to the shape's edges (where none has a foot on a face).

    The nearest point of the shape is then on an edge (the faces' borders), unless an interior local minimum is
    nearer; a point on an edge is a point of the shape, so this is an upper bound too (and ~20x faster than
    measuring to the faces: 0.5 s a point on camelhead's 195x180-pole face).
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS_Compound

    edges = TopoDS_Compound()
    bld = BRep_Builder()
    bld.MakeCompound(edges)
    ex = TopExp_Explorer(shape, TopAbs_EDGE)
    while ex.More():
        bld.Add(edges, ex.Current())
        ex.Next()
    ds = BRepExtrema_DistShapeShape()
    ds.LoadS2(edges)
    for i in rest:
        ds.LoadS1(BRepBuilderAPI_MakeVertex(pts[i]).Vertex())
        if not ds.Perform() or not ds.IsDone():
            raise HeatparamError("OpenCascade could not measure a distance to the shape")
        dist[i] = min(dist[i], ds.Value())


def tessellation(shape, deflection: float) -> list[tuple]:
    """Per face of ``shape``: (the face, nodes (p,3), triangles (t,3)) of OpenCascade's tessellation
    (``BRepMesh_IncrementalMesh``, linear ``deflection``, angular 0.5 rad, sequential); a face BRepMesh could not
    mesh gives empty arrays. The nodes lie on the faces' surfaces, inside their trims.

    A copy is meshed, its tolerances set to a hundredth of the deflection: BRepMesh meshes a face no finer than
    twice its largest tolerance (the cow's shared edges, up to 1.4 tol: nodes 2.4 tol apart from the mesh)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.ShapeFix import ShapeFix_ShapeTolerance
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    copy = BRepBuilderAPI_Copy(shape).Shape()
    ShapeFix_ShapeTolerance().SetTolerance(copy, 0.01 * deflection)
    BRepMesh_IncrementalMesh(copy, deflection, False, 0.5, False)
    out = []
    ex, mine = TopExp_Explorer(shape, TopAbs_FACE), TopExp_Explorer(copy, TopAbs_FACE)
    while ex.More():
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(TopoDS.Face(mine.Current()), loc)
        P, T = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
        if tri is not None and tri.NbNodes():
            trsf = loc.Transformation()
            P = np.array([tri.Node(i).Transformed(trsf).Coord() for i in range(1, tri.NbNodes() + 1)])
            T = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64) - 1
        out.append((TopoDS.Face(ex.Current()), P, T))
        ex.Next()
        mine.Next()
    return out


def inspect_step(path: str | os.PathLike, points: np.ndarray | None = None, units: str | None = None,
                 max_points: int | None = None, seed: int = 0, faces: np.ndarray | None = None,
                 deflection: float | None = None) -> dict:
    """Read a STEP file back and measure it: for tests and reports.

    Parameters
    ----------
    points : (p,3) float64 or None; their distances to the shape's faces are measured (see :func:`_distances`).
    units : unit to read the coordinates in (None = the file's own).
    max_points : measure at most this many points (a seeded random sample), or None for all.
    faces : (m,3) int64 or None: with ``points`` the mesh's vertices (all of them), the mesh's triangles; the other
        way is measured too: the shape is tessellated (:func:`tessellation`, linear ``deflection``, default 1/1000
        of the points' bounding-box diagonal) and every node's distance to the mesh taken.

    Returns
    -------
    dict: ``valid`` (BRepCheck_Analyzer), ``faces``, ``area``, ``file_units``, ``shells``, ``free_edges`` and, with
    points, ``max_distance``, ``rms_distance``, ``points_measured``; with faces, ``surface_max_distance``,
    ``surface_p99_distance`` (nodes to the mesh), ``surface_nodes``, ``invalid_faces`` (BRepCheck per face) and
    ``untessellated_faces``.
    """
    import igl
    from OCP.BRepCheck import BRepCheck_Analyzer

    shape, file_unit = read_step(path, units)
    shells, free = _topology(shape)
    out = {"valid": _valid(shape), "faces": 0, "area": _area(shape), "file_units": file_unit, "shells": shells,
           "free_edges": free}
    V = None if points is None else np.asarray(points, dtype=np.float64)
    if faces is not None:
        diag = float(np.linalg.norm(V.max(0) - V.min(0)))
        tess = tessellation(shape, 1e-3 * diag if deflection is None else deflection)
        nodes = np.vstack([P for _, P, _ in tess])
        d = np.sqrt(igl.point_mesh_squared_distance(nodes, V, np.asarray(faces, dtype=np.int64))[0])
        out.update(surface_max_distance=float(d.max()), surface_p99_distance=float(np.percentile(d, 99)),
                   surface_nodes=int(len(nodes)), untessellated_faces=sum(not len(P) for _, P, _ in tess),
                   invalid_faces=sum(not BRepCheck_Analyzer(f).IsValid() for f, _, _ in tess))
    out["faces"] = _count(shape, "FACE")
    if V is not None:
        P = V
        if max_points is not None and len(P) > max_points:
            P = P[np.sort(np.random.default_rng(seed).choice(len(P), max_points, replace=False))]
        dist = _distances(shape, P)
        out.update(max_distance=float(dist.max()), rms_distance=float(np.sqrt(np.mean(dist**2))),
                   points_measured=int(len(P)))
    return out
