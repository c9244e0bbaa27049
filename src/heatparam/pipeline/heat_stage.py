"""The paper's stage (Figure 1): [fill surface M*, §2.5] → heat geodesics (Eq. 2-10) → MDS (Eq. 11-14) → the
layout of M, oriented like the mesh.

:func:`mds_map` runs it on a :class:`~heatparam.pipeline.surface.Surface` and returns the layout with its part of
the report.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from heatparam import heat
from heatparam.errors import HeatparamError
from heatparam.layout import mds
from heatparam.layout.conformal import needs_mirror, orient_layout
from heatparam.memory import require
from heatparam.operators import build_operators
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress


def default_landmarks(n: int) -> int:
    """Landmark count for the landmark path (see BENCHMARKS.md for the error/time trade-off)."""
    return int(min(n, 100))


class HeatParams(NamedTuple):
    """The heat + MDS stage's parameters (``Options`` fields of the same names)."""

    geodesics: str = "auto"
    landmarks: int = 0
    time_step: str | float = "default"
    t_coef: float = 1.0
    mass: str = "lumped"
    solver: str = "auto"
    seed: int = 0
    all_pairs_max: int = 3000
    stress_sources: int = 32
    stress: str = "none"
    unit: float = 1.0  # the surface's internal length unit in model units (``mesh.frame.UnitFrame.unit``)

    @classmethod
    def from_options(cls, opts, unit: float = 1.0) -> HeatParams:
        return cls(*(getattr(opts, f) for f in cls._fields[:-1]), unit)


class FillSurface(NamedTuple):
    """The fill surface M* the geodesics were computed on, for pictures: M* (V, F), the MDS layout of its
    vertices ``uv`` and of the input's vertices ``uv_points`` in the same frame (before refinement)."""

    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    uv_points: np.ndarray
    method: str


class Layout(NamedTuple):
    """The MDS layout and what it was computed from."""

    uv: np.ndarray  # (n,2) MDS layout of the points
    uv_surface: np.ndarray | None  # (N,2) MDS layout of the geodesic surface's vertices (fill path only)
    D_points: np.ndarray  # (n_points, c) geodesic distances used for the stress sample
    stress_columns: np.ndarray  # (c,) point index of each column's source
    mode: str
    k: int
    t: float
    backend: str
    mollify_eps: float
    stress: dict | None = None  # SMACOF info (``mds.smacof``, without its history) with stress="smacof"
    warning: str | None = None  # an explicit time step too small for the surface (``heat.underflow_warning``)


class MdsMap(NamedTuple):
    """:func:`mds_map`'s value: the oriented layout of the surface's vertices (n,2), the :class:`Layout`, the fill
    surface for pictures (or None), the report's ``fill`` part, and warnings."""

    uv: np.ndarray
    layout: Layout
    fill_surface: FillSurface | None
    fill: dict
    warnings: list[str]


def decide_fill(opts, surface: Surface, seamed: bool) -> tuple[bool, str]:
    """Whether to compute on a fill surface M*, and why (``seamed``: a mesh cut open along seams, which a
    fill would close again, so ``fill auto`` means none)."""
    if seamed and opts.fill == "auto":
        return False, "not on a mesh cut open along seams (a fill would close them)"
    if opts.fill == "none":
        return False, "disabled (fill='none')"
    if opts.fill in ("poisson", "biharmonic"):
        return True, f"requested (fill='{opts.fill}')"
    from heatparam import fill

    return fill.needs_fill(surface.V, surface.F, surface.info, surface.conformal)


def mds_map(surface: Surface, opts, prog: Progress, fill_used: bool, fill_reason: str) -> MdsMap:
    """The fill (when ``fill_used``; with ``fill auto`` a failed fill falls back to the mesh itself), heat
    geodesics and MDS of the surface's vertices, mirrored to keep the mesh's orientation."""
    warnings: list[str] = []
    fill_report: dict = {"used": fill_used, "reason": fill_reason}
    M = None
    if fill_used:
        from heatparam import fill

        method = "poisson" if opts.fill == "poisson" else "biharmonic"  # auto: the biharmonic fill (docs/fill.md)
        try:
            with prog.stage("fill"):
                M = fill.fill_surface(surface.V, surface.F, surface.info, method=method, seed=opts.seed,
                                      depth=opts.fill_depth, conformal=surface.conformal)
        except HeatparamError as exc:
            if opts.fill != "auto":
                raise
            fill_report.update(used=False, failed=str(exc))
            warnings.append(f"the fill surface failed ({exc}); geodesics computed on the mesh itself")
    params = HeatParams.from_options(opts, surface.frame.unit)
    if M is not None:
        fill_report.update(M.report)
        warnings += M.warnings
        layout = geodesic_layout(M.V, M.F, params, prog, points=(M.face, M.bary))
    else:
        layout = geodesic_layout(surface.V, surface.F, params, prog)
    if layout.warning:
        warnings.append(layout.warning)
    mirror = needs_mirror(layout.uv, surface.F)
    uv = orient_layout(layout.uv, surface.F)
    fs = None
    if M is not None:
        flip = np.array([1.0, -1.0]) if mirror else np.ones(2)
        fs = FillSurface(M.V, M.F, layout.uv_surface * flip, uv.copy(), fill_report.get("method", ""))
    return MdsMap(uv, layout, fs, fill_report, warnings)


def geodesic_layout(V: np.ndarray, F: np.ndarray, params: HeatParams, prog: Progress,
                    points: tuple[np.ndarray, np.ndarray] | None = None) -> Layout:
    """Heat geodesics on (V, F) and MDS (Eq. 4-14) of its vertices, or of ``points`` located on it.

    points : (face (p,), bary (p,3)) — points on the surface (V, F), e.g. the vertices of M located on a fill
        surface M*. Their distances are interpolated from the landmark distance fields, and they are placed by
        landmark MDS with the landmarks on (V, F).
    """
    n = len(V)
    mode = params.geodesics
    if mode == "auto":
        mode = "all-pairs" if n <= params.all_pairs_max else "landmarks"
    if points is not None:
        mode = "landmarks" if params.geodesics != "all-pairs" else "all-pairs"
    if mode == "all-pairs":
        require(heat.all_pairs_bytes(n), f"all-pairs geodesics on {n} vertices ({n} x {n} matrix)",
                "use geodesics='landmarks' (or 'auto')")
    with prog.stage("operators"):
        op = build_operators(V, F, mass=params.mass)
    t = heat.time_step(op, params.time_step, params.t_coef, params.unit)
    warning = heat.underflow_warning(op, t) if params.time_step != "default" else None
    with prog.stage("factorize"):
        solver = heat.HeatGeodesics(op, t, backend=params.solver)
    rng = np.random.default_rng(params.seed)
    if mode == "all-pairs" and points is None:
        return _all_pairs_layout(solver, n, params, prog, rng, (mode, t, op.mollify_eps, warning))
    k = n if mode == "all-pairs" else min(n, params.landmarks or default_landmarks(n))  # never more than vertices
    with prog.stage("geodesics", "landmarks"), prog.bar(k + 1, "landmark geodesics", "src") as bar:
        if k >= n:
            lm = np.arange(n)
            DL = solver.distances(lm, progress=bar.update)
        else:
            lm, DL = heat.farthest_point_landmarks(solver, V, k, seed=params.seed, progress=bar.update)
    facts = (mode, k, t, solver.backend, op.mollify_eps)
    if points is None:
        with prog.stage("mds"):
            uv, _ = mds.landmark_mds(DL, lm)
        sinfo = None
        if params.stress == "smacof":
            with prog.stage("stress"):
                uv, sinfo = _smacof(uv, DL, lm)
        cols = np.arange(min(k, params.stress_sources))
        return Layout(uv, None, DL[:, cols], lm[cols], *facts, sinfo, warning)
    return _points_layout(solver, F, DL, lm, points, params, prog, rng, facts, warning)


def _all_pairs_layout(solver: heat.HeatGeodesics, n: int, params: HeatParams, prog: Progress,
                      rng: np.random.Generator, facts: tuple) -> Layout:
    """The paper's path: all n×n distances (Eq. 10 from every vertex) and classical MDS (Eq. 11-14)."""
    mode, t, eps, warning = facts
    with prog.stage("geodesics"), prog.bar(n, "geodesics", "src") as bar:
        D = heat.all_pairs(solver, progress=bar.update)
    cols = np.sort(rng.choice(n, size=min(n, params.stress_sources), replace=False))
    D_stress = D[:, cols].copy()
    with prog.stage("mds"):
        uv = mds.classical_mds(D, seed=params.seed, overwrite=True)
    sinfo = None
    if params.stress == "smacof":
        with prog.stage("stress"):
            np.sqrt(D, out=D)  # MDS squared D in place; sqrt(fl(x²)) = x restores it exactly
            uv, sinfo = _smacof(uv, D)
    del D
    return Layout(uv, None, D_stress, cols, mode, n, t, solver.backend, eps, sinfo, warning)


def _points_layout(solver: heat.HeatGeodesics, F: np.ndarray, DL: np.ndarray, lm: np.ndarray,
                   points: tuple[np.ndarray, np.ndarray], params: HeatParams, prog: Progress,
                   rng: np.random.Generator, facts: tuple, warning: str | None) -> Layout:
    """Landmark MDS of points on a fill surface M* (the vertices of M) and of M*'s vertices, in one frame."""
    face, bary = points
    n = solver.n
    with prog.stage("mds"):
        DP = np.einsum("pc,pck->pk", bary, DL[F[face]])  # landmark distances interpolated at the points
        DA = np.vstack([DP, DL])
        both, _ = mds.landmark_mds(DA, Dkk=DL[lm])  # points and M*'s vertices, one frame
    sinfo = None
    if params.stress == "smacof":  # the same n×k pattern: points and M*'s vertices against the landmarks on M*
        with prog.stage("stress"):
            both, sinfo = _smacof(both, DA, len(face) + lm)
    del DA
    both -= both[: len(face)].mean(axis=0)
    uv, uv_surface = both[: len(face)], both[len(face) :]
    # Stress sample: distances on the fill surface from a few of the points themselves (point sources).
    with prog.stage("geodesics", "stress sample"):
        cols = np.sort(rng.choice(len(face), size=min(len(face), params.stress_sources), replace=False))
        Ds = solver.distances(heat.point_sources(F, face[cols], bary[cols], n))
        D_stress = np.einsum("pc,pck->pk", bary, Ds[F[face]])
    return Layout(uv, uv_surface, D_stress, cols, *facts, sinfo, warning)


def _smacof(X0: np.ndarray, D: np.ndarray, landmarks: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """``mds.smacof`` from the MDS layout; its info for the report (without the per-iteration history)."""
    X, info = mds.smacof(X0, D, landmarks)
    info.pop("history")
    return X, {"method": "smacof", **info}
