"""Nonlinear Gauss-Seidel on the symmetric Dirichlet energy: the smoother between a coarse level's prolongation and
the fine polish (``refine.multilevel``).

A coarse map carried piecewise-affinely to the fine vertices is right at the coarse scale and wrong at the fine
one: every fine triangle keeps the distortion of the fine mesh's own detail (a scan's noise: tuning seed 21's main
piece, 146k vertices, prolongated at energy 1.111; its polish from there took 8 Newton iterations to 1.0008). That
error is local, the kind a multigrid smoother removes, and a Newton iteration over the whole mesh (a factorization)
is the dearest way to remove it. Each sweep here moves one interior vertex at a time to the minimum of the energy of
its own faces (a 2×2 Newton step, its Hessian projected to positive definite), within the step that keeps those
faces unflipped and only where the energy falls: ~0.05 s per sweep at 190k vertices (seed 21: 8 sweeps to 1.0014,
then 2 Newton iterations). The boundary (every loop) and the vertices of guard triangles stay where they are, so
the map stays bijective. Sweeps stop once one gains more than ``SLOWDOWN`` × the previous one (what is left is
smooth error, which the Newton step removes at once) or after ``MAX_SWEEPS``.
"""

from __future__ import annotations

import time

import numpy as np

from heatparam.compiled import compiled, warmup
from heatparam.mesh.topology import vertex_corners
from heatparam.refine.energy import face_jacobian, normalized_energy

#: Sweeps stop once a sweep gains more than this fraction of the previous sweep's gain: the smoother has then
#: removed the local error and converges at the slow rate of the smooth error left (tuning seed 21: gains 0.083,
#: 0.019, 0.0053, 0.0016, 0.0005, 0.0002, 8e-5, 4e-5: ratios 0.23 rising to 0.49, then 0.55)
SLOWDOWN = 0.5
#: ... or after this many sweeps
MAX_SWEEPS = 20
#: The step that may flip none of a vertex's faces is cut to this fraction of the way to the first one that would
#: (its determinant is linear in the vertex's move)
STEP_FRACTION = 0.9
#: Halvings of a step that does not lower the energy of the vertex's faces before the vertex is left where it is
HALVINGS = 10


class Smoother:
    """Gauss-Seidel sweeps over the interior vertices of a mesh F (m,3) with per-face hat gradients ``g`` (m,3,2)
    and areas ``area`` (m,): the vertex → face table once, then :meth:`smooth` any bijective layout of it.

    fixed : (k,) vertex ids that never move (the boundary loops, the corners of guard triangles)."""

    def __init__(self, F: np.ndarray, g: np.ndarray, area: np.ndarray, n: int, fixed: np.ndarray):
        self.F, self.area = np.ascontiguousarray(F, dtype=np.int64), area
        self.g = np.ascontiguousarray(g, dtype=np.float64)
        self.w = np.ascontiguousarray(area / area.sum(), dtype=np.float64)
        corners, self.ptr = vertex_corners(self.F, n)
        self.faces, self.corner = corners // 3, corners % 3  # each vertex's faces and its corner in each
        self.movable = np.ones(n, dtype=np.bool_)
        self.movable[fixed] = False
        self.scratch = np.empty((max(1, int(np.diff(self.ptr).max(initial=1))), 8))

    def sweep(self, uv: np.ndarray) -> float:
        """One sweep over ``uv`` (n,2) in place; the fall of Σ w_f Ψ_f (the energy before the 1/4 normalization)."""
        return float(_sweep(uv, self.F, self.g, self.w, self.ptr, self.faces, self.corner, self.movable,
                            self.scratch))

    def smooth(self, uv: np.ndarray) -> tuple[np.ndarray, dict]:
        """The smoothed layout (a copy) and the report's ``smoothing`` part (sweeps, normalized energy before and
        after, seconds)."""
        t0 = time.perf_counter()
        x = np.array(uv, dtype=np.float64, order="C")
        before = normalized_energy(x, self.F, self.g, self.area)
        last, sweeps = np.inf, 0
        while sweeps < MAX_SWEEPS:
            gain = self.sweep(x)
            sweeps += 1
            if not gain < SLOWDOWN * last:
                break
            last = gain
        after = normalized_energy(x, self.F, self.g, self.area)
        return x, {"sweeps": sweeps, "energy_before": before, "energy_after": after,
                   "seconds": round(time.perf_counter() - t0, 3)}


@compiled()
def _step(scratch, count, dx, dy, e0):  # pragma: no cover - compiled
    """The step t along (dx, dy) of one vertex and the fall of its faces' energy (0, 0 where none lowers it): the
    first ``count`` scratch rows are its faces' (|J|², det, a, c, |g_i|², w), see :func:`_sweep`."""
    t = 1.0
    for k in range(count):
        lin = scratch[k, 4] * dx + scratch[k, 5] * dy
        if lin < 0.0 and -STEP_FRACTION * scratch[k, 1] / lin < t:
            t = -STEP_FRACTION * scratch[k, 1] / lin
    dn = dx * dx + dy * dy
    for _ in range(HALVINGS):
        e1 = 0.0
        for k in range(count):
            s = scratch[k]
            ft = s[0] + t * (s[2] * dx + s[3] * dy) + t * t * s[6] * dn
            det_t = s[1] + t * (s[4] * dx + s[5] * dy)
            e1 += s[7] * ft * (1.0 + 1.0 / (det_t * det_t))
        if e1 < e0:
            return t, e0 - e1
        t *= 0.5
    return 0.0, 0.0


@compiled(_step, face_jacobian)
def _sweep(uv, F, g, w, ptr, faces, corner, movable, scratch):  # pragma: no cover - compiled
    """:meth:`Smoother.sweep`. For a vertex at corner i of face f, moved by d: J(d) = J + d g_iᵀ, so |J(d)|² =
    |J|² + aᵀd + |g_i|²|d|² with a = 2 J g_i and det J(d) = det J + cᵀd with c = adj(J)ᵀ g_i (linear); with
    q = 1 + det⁻², Ψ = |J|² q has gradient a q - 2 |J|² det⁻³ c and Hessian 2 |g_i|² q I - 2 det⁻³ (a cᵀ + c aᵀ)
    + 6 |J|² det⁻⁴ c cᵀ. The scratch rows keep (|J|², det, a, c, |g_i|², w) per face for the line search."""
    gain = 0.0
    for v in range(uv.shape[0]):
        if not movable[v]:
            continue
        k0, k1 = ptr[v], ptr[v + 1]
        gx = gy = hxx = hxy = hyy = e0 = 0.0
        for k in range(k0, k1):
            f, i = faces[k], corner[k]
            j00, j01, j10, j11 = face_jacobian(uv, F, g, f)
            g0, g1 = g[f, i, 0], g[f, i, 1]
            dt = j00 * j11 - j01 * j10
            f2 = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
            c0, c1 = g0 * j11 - g1 * j10, g1 * j00 - g0 * j01
            a0, a1 = 2.0 * (j00 * g0 + j01 * g1), 2.0 * (j10 * g0 + j11 * g1)
            gg = g0 * g0 + g1 * g1
            i1 = 1.0 / dt
            i2 = i1 * i1
            q, wf = 1.0 + i2, w[f]
            e0 += wf * f2 * q
            gx += wf * (a0 * q - 2.0 * f2 * i2 * i1 * c0)
            gy += wf * (a1 * q - 2.0 * f2 * i2 * i1 * c1)
            hxx += wf * (2.0 * gg * q - 4.0 * i2 * i1 * a0 * c0 + 6.0 * f2 * i2 * i2 * c0 * c0)
            hyy += wf * (2.0 * gg * q - 4.0 * i2 * i1 * a1 * c1 + 6.0 * f2 * i2 * i2 * c1 * c1)
            hxy += wf * (-2.0 * i2 * i1 * (a0 * c1 + a1 * c0) + 6.0 * f2 * i2 * i2 * c0 * c1)
            s = scratch[k - k0]
            s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7] = f2, dt, a0, a1, c0, c1, gg, wf
        mid, rad = 0.5 * (hxx + hyy), np.sqrt(0.25 * (hxx - hyy) ** 2 + hxy * hxy)
        if mid + rad <= 0.0:
            continue
        shift = 1e-8 * (mid + rad) - (mid - rad)  # the smaller eigenvalue raised to 1e-8 × the larger
        if shift > 0.0:
            hxx += shift
            hyy += shift
        dd = hxx * hyy - hxy * hxy
        dx, dy = (hxy * gy - hyy * gx) / dd, (hxy * gx - hxx * gy) / dd
        t, fall = _step(scratch, k1 - k0, dx, dy, e0)
        uv[v, 0] += t * dx
        uv[v, 1] += t * dy
        gain += fall
    return gain


@warmup
def _warm() -> None:
    """The compiled sweep run once on one triangle (:func:`heatparam.compiled.warm_all`)."""
    g = np.array([[[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]])
    Smoother(np.array([[0, 1, 2]]), g, np.ones(1), 3, np.array([0, 1])).sweep(np.eye(3, 2))
