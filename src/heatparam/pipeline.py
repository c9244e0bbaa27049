"""The orchestrator: one mesh through the paper's stages (Figure 1), with a report.

``parameterize(V, F, **options)`` → (uv, report). The CLI calls it; it never touches files.
Stages: validate (``mesh``) → [Poisson fill M*, §2.5 (``fill``)] → operators (Eq. 5-6) → heat geodesics
(Eq. 4, 7-10) → MDS (Eq. 11-14; landmark MDS for large meshes) → [trim to M] → [refine] → metrics.
"""

from __future__ import annotations

import functools
import platform
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from typing import NamedTuple

import numpy as np

from heatparam import __version__, heat, mds, mesh, metrics
from heatparam.errors import HeatparamError
from heatparam.memory import peak_rss_bytes, require
from heatparam.mesh import MeshInfo, validate_mesh
from heatparam.operators import MASS_KINDS, build_operators
from heatparam.progress import Progress
from heatparam.refine import MULTILEVEL_MIN_VERTICES, REFINE_MODES, LscmStart, polish_bytes
from heatparam.solvers import BACKENDS

FILL_MODES = ("auto", "poisson", "biharmonic", "none")
GEODESIC_MODES = ("auto", "all-pairs", "landmarks")
STRESS_MODES = ("none", "smacof")
MDS_START_MODES = ("auto", "always")
SEAM_MODES = ("auto", "holes", "none")


@dataclass
class Options:
    """Every knob of the pipeline, with its default written once (the CLI reuses these).

    fill : ``auto`` decides from the mesh whether a fill surface M* is needed (holes, concave border) and then
        uses the biharmonic fill; ``poisson`` = the paper's screened Poisson surface (§2.5, Eq. 15-16);
        ``biharmonic`` = M plus its holes and border bays triangulated and lifted by a biharmonic extension;
        ``none``. See docs/fill.md for the measurements behind the choice.
    geodesics : ``all-pairs`` (the paper: n×n distances, classical MDS), ``landmarks`` (k farthest-point
        sources, landmark MDS, O(n·k) memory), or ``auto`` (all-pairs up to ``all_pairs_max`` vertices).
    landmarks : k for the landmark path (0 = automatic: ``default_landmarks(n)``).
    time_step : ``default`` (t = t_coef·h², scale-invariant), ``paper`` (Eq. 7, not scale-invariant) or t.
    t_coef : the c in t = c·h² (Crane et al.'s t = h²; see docs/method.md for the measured trade-off).
    mass : ``lumped`` (default) or ``consistent`` (Eq. 6) mass matrix B.
    solver : sparse factorization backend (``auto``, ``cholespy``, ``scipy``, ``pardiso``).
    seed : seeds every random choice (first landmark, Lanczos start vector): same seed, same output.
    all_pairs_max : largest vertex count for which ``auto`` takes the all-pairs path.
    stress_sources : number of sources for the sampled Eq. 1 stress in the report.
    fill_depth : Poisson reconstruction depth for the fill (0 = automatic from the mesh size).
    refine : post-MDS refinement: ``sd`` (bijective symmetric Dirichlet polish at true scale inside a scaffold,
        from the lower-energy bijective one of the MDS and LSCM layouts, else from Tutte; docs/refine.md) or
        ``none`` (raw MDS map).
    stress : ``smacof`` = stress majorization of the raw stress of Eq. 1 (``mds.smacof``) on the MDS layout,
        before refinement, with the distances MDS used (all-pairs: every pair; landmarks: the n×k point-landmark
        pairs; fill: the points and M*'s vertices against the landmarks on M*); ``none`` (default, from the
        measurement in BENCHMARKS.md §7).
    mds_start : with ``refine``, ``auto`` skips the fill, heat geodesics and MDS when the LSCM layout is already
        bijective and within ``refine.ISOMETRIC_START_EXCESS`` (0.1%) of an isometry in energy — the MDS layout
        is then only a start candidate that cannot be better by more than that — and, on meshes of at least
        ``FOLD_CHECK_MIN_VERTICES``, when the MDS layout of a coarse mesh folds beyond what the refinement repairs
        (the full one would not be a start either). The map is the same, faster; the report's ``stress_rel_rms``
        is then null.
        ``always`` computes them anyway. Nothing is skipped with ``refine none`` or when ``fill``, ``geodesics``,
        ``landmarks`` or ``stress`` is set explicitly.
    seams : cutting holes open to the border (``mesh.hole_seams``: the shortest surface paths that join every hole
        to the border, a minimum spanning tree). A map must keep each hole a hole, and where the surface's
        curvature pushes a hole's side over another boundary (the crossings of libigl's SLIM maps on halftunnel and
        beetle) the bijective map has to squeeze the band between them. ``auto`` (default, with ``refine``): when
        the map is bijective-limited like that — mean isometric distortion above ``1 + SEAM_TRY_EXCESS`` on a
        mesh with holes — flatten the cut-open mesh too and keep it if it is bijective and lowers the mean
        isometric distortion by at least ``SEAM_MIN_GAIN``; ``holes`` always cuts; ``none`` never. A seamed map
        has one UV row per seam side (``Result.Fuv``; the OBJ's ``f v/vt`` indices differ) and says so in the
        report (``method.seams``) and a warning.
    refine_multilevel : meshes with at least this many vertices are polished coarse-to-fine (a coarse mesh of
        about 1/8 of the vertices is polished first and prolongated; ``refine.coarse_to_fine``); 0 = never.
    refine_iters : iteration cap of the symmetric Dirichlet polish.
    refine_tol : the polish stops when an iteration lowers the energy by less than this fraction.
    progress : show stage messages and progress bars on stderr.
    """

    fill: str = "auto"
    geodesics: str = "auto"
    landmarks: int = 0
    time_step: str | float = "default"
    t_coef: float = 1.0
    mass: str = "lumped"
    solver: str = "auto"
    seed: int = 0
    all_pairs_max: int = 3000
    stress_sources: int = 32
    fill_depth: int = 0
    refine: str = "sd"
    mds_start: str = "auto"
    seams: str = "auto"
    stress: str = "none"
    refine_multilevel: int = MULTILEVEL_MIN_VERTICES
    refine_iters: int = 200
    refine_tol: float = 1e-6
    progress: bool = False

    def validate(self) -> None:
        """Raise HeatparamError for an option outside its range."""
        _choice("fill", self.fill, FILL_MODES)
        _choice("geodesics", self.geodesics, GEODESIC_MODES)
        _choice("mass", self.mass, MASS_KINDS)
        _choice("solver", self.solver, BACKENDS)
        if isinstance(self.time_step, str):
            _choice("time_step", self.time_step, heat.TIME_STEPS)
        elif not self.time_step > 0:
            raise HeatparamError(f"time_step must be positive, got {self.time_step}")
        if self.landmarks < 0 or self.landmarks == 1 or self.landmarks == 2:
            raise HeatparamError(f"landmarks must be 0 (automatic) or at least 3, got {self.landmarks}")
        _choice("refine", self.refine, REFINE_MODES)
        _choice("stress", self.stress, STRESS_MODES)
        _choice("mds_start", self.mds_start, MDS_START_MODES)
        _choice("seams", self.seams, SEAM_MODES)
        if self.refine_multilevel < 0:
            raise HeatparamError(f"refine_multilevel must be 0 (never) or a vertex count, got {self.refine_multilevel}")
        if self.fill_depth < 0:
            raise HeatparamError(f"fill_depth must be 0 (automatic) or positive, got {self.fill_depth}")
        if not self.t_coef > 0:
            raise HeatparamError(f"t_coef must be positive, got {self.t_coef}")


def _choice(name: str, value, allowed) -> None:
    if value not in allowed:
        raise HeatparamError(f"{name} must be one of {', '.join(allowed)}; got {value!r}")


#: Peak memory of the pipeline without the refinement, per vertex (landmark path): ``--refine none`` peaked at
#: 3.5-3.9 KB per vertex on camelhead↑727k and 4.4-5.9 KB on camelhead↑182k, interpreter and libraries included
#: (BENCHMARKS.md §4). With the refinement, ``refine.polish_bytes`` per face comes on top (727k: 6.3 GB measured,
#: 6.7 GB estimated).
RAW_BYTES_PER_VERTEX = 4000


def default_landmarks(n: int) -> int:
    """Landmark count for the landmark path (see BENCHMARKS.md for the error/time trade-off)."""
    return int(min(n, 100))


class FillSurface(NamedTuple):
    """The fill surface M* the geodesics were computed on, for pictures: M* (V, F), the MDS layout of its
    vertices ``uv`` and of the input's vertices ``uv_points`` in the same frame (before refinement)."""

    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    uv_points: np.ndarray
    method: str


class Result(tuple):
    """What :func:`parameterize` returns; unpacks as ``uv, report``.

    uv : (n_uv,2) float64, the map. Without seams n_uv = n and uv[i] is the image of input vertex i. With seams
        (``report["method"]["seams"]["used"]``) every vertex on a seam has one row per side.
    report : the JSON-able report.
    Fuv : (m,3) int64, the rows of ``uv`` at each face's corners (F itself without seams): OBJ's ``f v/vt``.
    uv_vertex : (n_uv,) int64, the input vertex of each row of ``uv`` (``arange(n)`` without seams).
    fill_surface : a :class:`FillSurface` when a fill was used (for ``--preview``), else None.
    """

    def __new__(cls, uv: np.ndarray, report: dict, fill_surface: FillSurface | None = None,
                Fuv: np.ndarray | None = None, uv_vertex: np.ndarray | None = None):
        self = super().__new__(cls, (uv, report))
        self.fill_surface = fill_surface
        self.Fuv = Fuv
        self.uv_vertex = uv_vertex if uv_vertex is not None else np.arange(len(uv), dtype=np.int64)
        return self

    @property
    def uv(self) -> np.ndarray:
        return self[0]

    @property
    def report(self) -> dict:
        return self[1]

    @property
    def seamed(self) -> bool:
        """Whether the map has seams (``uv`` rows are not the input's vertices)."""
        return bool(self.report["method"]["seams"]["used"])


def parameterize(V: np.ndarray, F: np.ndarray, options: Options | None = None, **kwargs) -> Result:
    """Flatten a disk-like triangle mesh near-isometrically (true scale).

    Parameters
    ----------
    V : (n,3) float64 vertices. F : (m,3) int64 triangles (consistently oriented).
    options : an :class:`Options`; keyword arguments override its fields (``parameterize(V, F, seed=3)``).

    Returns
    -------
    Result(uv (n,2) float64, report dict): uv[i] is the image of V[i]; the report holds the parameters,
    per-stage timings, mesh facts and the map's metrics (see README). With seams (``Options.seams``,
    ``Result.seamed``) uv has one row per seam side: face f's corners map to ``uv[Result.Fuv[f]]``.
    """
    opts = Options(**{**(asdict(options) if options else {}), **kwargs})
    opts.validate()
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    prog = Progress(opts.progress)
    warnings: list[str] = []

    with prog.stage("validate"):
        info = validate_mesh(V, F)
    warnings += info.warnings
    # refuse at once, not after minutes of work, what memory could not hold
    raw = RAW_BYTES_PER_VERTEX * len(V)
    require(raw, f"parameterizing {len(V)} vertices", "decimate the mesh or split it into patches")
    if opts.refine != "none":
        require(raw + polish_bytes(len(F)), f"parameterizing and refining {len(F)} triangles",
                "use --refine none (the raw MDS map) or decimate the mesh")
    # Work on the referenced vertices only (unreferenced ones get the centroid at the end).
    keep = np.flatnonzero(info.referenced)
    remap = np.full(len(V), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    Vc, Fc = V[keep], remap[F]
    flat = _flatten(Vc, Fc, info, opts, prog, warnings)
    seams = _seams(Vc, Fc, info, opts, prog, warnings, flat)
    if seams is not None:
        flat, cut = seams
        return _result(V, F, keep, flat, opts, info, prog, warnings, cut)
    return _result(V, F, keep, flat, opts, info, prog, warnings)


class Flat(NamedTuple):
    """One flattening of a (compacted) mesh: the map, its metrics and how it was made."""

    uv: np.ndarray
    summary: dict
    method: dict
    layout: Layout | None
    surface: FillSurface | None


def _flatten(Vc: np.ndarray, Fc: np.ndarray, info: MeshInfo, opts: Options, prog: Progress, warnings: list[str],
             seamed: bool = False) -> Flat:
    """The stages on a validated mesh without unreferenced vertices (``seamed``: cut open by ``_seams``, whose
    seams a fill would close again, so ``fill auto`` means none)."""

    # M's LSCM layout: the fill's provisional layout and the refinement's fallback start; computed at most once,
    # shared read-only.
    @functools.cache
    def conformal() -> np.ndarray:
        uv0 = mds.conformal_layout(Vc, Fc, info.boundary_loops[0])
        uv0.setflags(write=False)
        return uv0

    @functools.cache
    def gradients() -> tuple[np.ndarray, np.ndarray]:  # the refinement's per-face gradients and areas, once
        from heatparam import refine

        return refine.surface_gradients(Vc, Fc)

    with prog.stage("fill decision"):
        if seamed and opts.fill == "auto":
            fill_used, fill_reason = False, "not on a mesh cut open along seams (a fill would close them)"
        else:
            fill_used, fill_reason = _decide_fill(opts, Vc, Fc, info, conformal)
    fill_report: dict = {"used": fill_used, "reason": fill_reason}
    lscm, skipped, fold_check = _start_checks(Vc, Fc, opts, prog, conformal, gradients)
    if skipped is not None:
        if fill_used:
            fill_report.update(used=False, skipped=skipped)
        uvc, refine_report = _refined(Vc, Fc, None, opts, prog, conformal, gradients, lscm)
        summary = _metrics(Vc, Fc, uvc, prog, None)
        method = {"geodesics": skipped, "solver_backend": None, "fill": fill_report,
                  "stress": {"method": "none"}, "refine": refine_report, "mass_matrix": opts.mass,
                  "mollified_edge_length": None, "fold_check": fold_check}
        return Flat(uvc, summary, method, None, None)
    M = None
    if fill_used:
        from heatparam import fill

        method = "poisson" if opts.fill == "poisson" else "biharmonic"  # auto: the biharmonic fill (docs/fill.md)
        try:
            with prog.stage("fill"):
                M = fill.fill_surface(Vc, Fc, info, method=method, seed=opts.seed, depth=opts.fill_depth,
                                      conformal=conformal)
        except HeatparamError as exc:
            if opts.fill != "auto":
                raise
            fill_report.update(used=False, failed=str(exc))
            warnings.append(f"the fill surface failed ({exc}); geodesics computed on the mesh itself")
    if M is not None:
        fill_report.update(M.report)
        warnings += M.warnings
        layout = _geodesic_layout(M.V, M.F, opts, prog, points=(M.face, M.bary))
    else:
        layout = _geodesic_layout(Vc, Fc, opts, prog)
    if layout.warning:
        warnings.append(layout.warning)
    mirror = mds.needs_mirror(layout.uv, Fc)
    uvc = mds.orient_layout(layout.uv, Fc)
    surface = None
    if M is not None:
        flip = np.array([1.0, -1.0]) if mirror else np.ones(2)
        surface = FillSurface(M.V, M.F, layout.uv_surface * flip, uvc.copy(), fill_report.get("method", ""))
    refine_report: dict = {"method": opts.refine}
    if opts.refine != "none":
        uvc, refine_report = _refined(Vc, Fc, uvc, opts, prog, conformal, gradients, lscm)
    summary = _metrics(Vc, Fc, uvc, prog, layout)
    method = {"geodesics": layout.mode, "solver_backend": layout.backend, "fill": fill_report,
              "stress": layout.stress or {"method": "none"}, "refine": refine_report, "mass_matrix": opts.mass,
              "mollified_edge_length": layout.mollify_eps, "fold_check": fold_check}
    return Flat(uvc, summary, method, layout, surface)


#: ``seams auto`` tries the cut-open mesh only when the map's mean isometric distortion exceeds 1 by more than this
#: (developable parts with holes are at 1.0000 already: nothing to gain) ...
SEAM_TRY_EXCESS = 0.01
#: ... and keeps it only when it lowers the mean isometric distortion by at least this fraction (measured,
#: BENCHMARKS.md §6: halftunnel 1.536 → 1.18, beetle 1.080 → 1.02).
SEAM_MIN_GAIN = 0.02


class Cut(NamedTuple):
    """A mesh cut open along seams: vertices V (n_s,3), faces F (m,3) (the input's, row for row), source (n_s,) the
    compacted vertex each row of V copies, paths the seams' vertex paths (compacted ids)."""

    V: np.ndarray
    F: np.ndarray
    source: np.ndarray
    paths: list[np.ndarray]


def _seams(Vc: np.ndarray, Fc: np.ndarray, info: MeshInfo, opts: Options, prog: Progress, warnings: list[str],
           flat: Flat) -> tuple[Flat, Cut] | None:
    """``Options.seams``: the flattening of the mesh cut open from every hole to the border when it is asked for
    or (``auto``) clearly better than ``flat``; None keeps ``flat``. Both cases write ``method["seams"]``."""
    rep: dict = {"mode": opts.seams, "used": False}
    flat.method["seams"] = rep
    iso = flat.summary["iso_mean"]
    if opts.seams == "none":
        rep["reason"] = "disabled (--seams none)"
        return None
    if info.n_holes == 0:
        rep["reason"] = "no holes"
        return None
    if opts.seams == "auto":
        if opts.refine == "none":
            rep["reason"] = "the raw map (--refine none) is not cut (--seams holes cuts it)"
            return None
        if flat.summary["bijective"] and iso <= 1 + SEAM_TRY_EXCESS:
            rep["reason"] = f"the map without seams is bijective and near-isometric (iso mean {iso:.4f})"
            return None
    with prog.stage("seams"):
        paths = mesh.hole_seams(Vc, Fc, info.boundary_loops)
        Vs, Fs, src = mesh.cut_open(Vc, Fc, paths)
        try:
            info_s = validate_mesh(Vs, Fs)
        except HeatparamError as exc:  # a seam set that does not leave a disk (never seen): keep the map
            rep["reason"] = f"the cut-open mesh is not a disk ({exc})"
            return None
    lengths = [float(np.linalg.norm(np.diff(Vc[p], axis=0), axis=1).sum()) for p in paths]
    rep.update(seams=len(paths), length=round(sum(lengths), 9), longest=round(max(lengths), 9),
               split_vertices=int(len(Vs) - len(Vc)), iso_mean_without=iso)
    cut_warnings: list[str] = []
    cut = _flatten(Vs, Fs, info_s, opts, prog, cut_warnings, seamed=True)
    iso_s = cut.summary["iso_mean"]
    rep.update(iso_mean_with=iso_s, bijective_with=cut.summary["bijective"])
    if opts.seams == "auto":
        better = cut.summary["bijective"] and (not flat.summary["bijective"] or iso_s <= iso * (1 - SEAM_MIN_GAIN))
        if not better:
            rep["reason"] = (f"the cut-open map is not {SEAM_MIN_GAIN:.0%} better (iso mean {iso_s:.4f} vs "
                             f"{iso:.4f}{'' if cut.summary['bijective'] else ', not bijective'}); kept without seams")
            return None
        rep["reason"] = (f"the holes cost distortion: iso mean {iso:.4f} without seams, {iso_s:.4f} with "
                         f"{len(paths)} (--seams none keeps one uncut piece)")
    else:
        rep["reason"] = "requested (--seams holes)"
    rep["used"] = True
    cut.method["seams"] = rep
    cut.method["without_seams"] = {"refine": flat.method["refine"], "metrics": flat.summary}
    warnings += cut_warnings
    warnings.append(f"the map has seams: {len(paths)} cut(s), {sum(lengths):.6g} long in all, join the holes to "
                    f"the border (iso mean {iso:.4f} → {iso_s:.4f}); the OBJ's vt rows split along them "
                    "(--seams none: one uncut piece)")
    return cut, Cut(Vs, Fs, src, paths)


def _start_checks(V: np.ndarray, F: np.ndarray, opts: Options, prog: Progress, conformal: Callable[[], np.ndarray],
                  gradients: Callable[[], tuple[np.ndarray, np.ndarray]]
                  ) -> tuple[LscmStart | None, str | None, dict | None]:
    """Whether the fill, geodesics and MDS can be skipped (``mds_start auto``): (the LSCM start judged by
    ``refine.lscm_start`` or None, why the heat stage is skipped or None, the fold check's report or None)."""
    if opts.refine == "none" or opts.mds_start != "auto" or not _heat_stage_optional(opts):
        return None, None, None
    from heatparam import refine

    with prog.stage("start check"):
        lscm = refine.lscm_start(V, F, conformal, gradients())
    if lscm.near_isometric:
        return lscm, (f"skipped: the LSCM layout is bijective and within {refine.ISOMETRIC_START_EXCESS:g} of an "
                      f"isometry (energy {lscm.energy:.7f}), so it starts the refinement (--mds-start always "
                      "computes them)"), None
    if lscm.energy is None or len(V) < FOLD_CHECK_MIN_VERTICES:
        return lscm, None, None
    with prog.stage("fold check"):
        fc = _coarse_fold_check(V, F, lscm.uv, opts)
    if fc.get("usable", True):
        return lscm, None, fc
    return lscm, (f"skipped: the MDS layout of a {fc['vertices']}-vertex coarse mesh folds ({fc['flips']} of "
                  f"{fc['faces']} triangles flipped, more than a repair handles), so the full one would not be a "
                  "start for the refinement either; it starts from LSCM (--mds-start always computes them)"), fc


#: Meshes of at least this many vertices whose LSCM start is bijective but not isometric get a fold check: the
#: fill, geodesics and MDS run first on a coarse mesh (1/8 of the vertices, ``refine.coarse_vertices`` triangulated
#: in the LSCM layout); if more of its triangles are flipped than the refinement would repair
#: (``refine.MDS_REPAIR_MAX_FRACTION``), the full one is not computed. Folding is a property of the shape
#: (camelhead: 53% of the coarse triangles flipped at 11k and 51% at 45k, 59% and 58% of the full ones); a coarse
#: layout that does not fold proves nothing, and the full heat stage runs (beetle: 0 flips coarse, 1 full).
FOLD_CHECK_MIN_VERTICES = 30_000


def _coarse_fold_check(V: np.ndarray, F: np.ndarray, uv: np.ndarray, opts: Options) -> dict:
    """The pipeline without refinement on a coarse mesh of (V, F) triangulated in the bijective layout ``uv``:
    flips and boundary crossings of its MDS layout (the same options otherwise), or why it could not be done."""
    from dataclasses import replace

    from heatparam import refine

    try:
        disk = refine.build_disk(V, F)
        loops = [disk.outer, *disk.holes]
        ids = refine.coarse_vertices(V, F, loops, max(int(len(V) * refine.COARSE_FRACTION), refine.COARSE_MIN))
        T = refine.coarse_mesh(uv, loops, ids)
        _, rep = parameterize(V[ids], T, replace(opts, refine="none", progress=False))
        m = rep["metrics"]
        out = {"vertices": len(ids), "faces": len(T), "flips": m["flips"], "crossings": m["boundary_crossings"],
               "fill": rep["method"]["fill"]["used"], "seconds": round(sum(rep["timings_s"].values()), 3)}
        # the refinement repairs an MDS start with a few flips, so only more than that counts as folded; anything
        # less (1 flip of 20k at a boundary corner of a noisy scan's coarse mesh, 3 repairable ones in the full
        # layout) proves nothing about the full layout
        out["usable"] = m["flips"] <= max(1, refine.MDS_REPAIR_MAX_FRACTION * len(T))
    except (HeatparamError, ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # only a shortcut
        return {"failed": str(exc)}
    return out


def _heat_stage_optional(opts: Options) -> bool:
    """Whether ``mds_start auto`` may skip the fill, geodesics and MDS: not when any of them was asked for."""
    return opts.fill == "auto" and opts.geodesics == "auto" and opts.stress == "none" and opts.landmarks == 0


def _refined(V: np.ndarray, F: np.ndarray, uv: np.ndarray | None, opts: Options, prog: Progress,
             conformal: Callable[[], np.ndarray], gradients: Callable[[], tuple[np.ndarray, np.ndarray]],
             lscm: LscmStart | None) -> tuple[np.ndarray, dict]:
    """``refine.refine`` of the layout ``uv`` (None: LSCM starts) as the "refine" stage."""
    from heatparam import refine

    with prog.stage("refine"):
        return refine.refine(V, F, uv, opts, progress=prog, conformal=conformal, lscm=lscm, surface=gradients())


def _metrics(V: np.ndarray, F: np.ndarray, uv: np.ndarray, prog: Progress, layout: Layout | None) -> dict:
    """The map's metrics; the sampled Eq. 1 stress against the geodesics when they were computed (else None)."""
    with prog.stage("metrics"):
        summary = metrics.summary(V, F, uv)
        summary["stress_rel_rms"] = (metrics.stress(uv, layout.D_points, layout.stress_columns)
                                     if layout is not None else None)
    return summary


def _result(V: np.ndarray, F: np.ndarray, keep: np.ndarray, flat: Flat, opts: Options, info: MeshInfo,
            prog: Progress, warnings: list[str], cut: Cut | None = None) -> Result:
    """The map of every input vertex (unreferenced ones at the centroid), or of every seam side with ``cut``,
    and the report."""
    uvc, summary, method, layout = flat.uv, flat.summary, flat.method, flat.layout
    if cut is None:
        uv = np.zeros((len(V), 2))
        uv[keep] = uvc
        uv[~info.referenced] = uvc.mean(axis=0)
        Fuv, uv_vertex = F, np.arange(len(V), dtype=np.int64)
    else:  # the cut mesh's faces are F's, row for row, in compacted and then split vertex ids
        uv, Fuv, uv_vertex = uvc, cut.F, keep[cut.source]
    if summary["flips"] or summary["boundary_crossings"]:
        warnings.append(
            f"the map is not bijective: {summary['flips']} flipped triangles, "
            f"{summary['boundary_crossings']} boundary crossings"
        )
    for w in warnings:
        prog.warn(w)
    report = {
        "heatparam_version": __version__,
        "parameters": {**{f.name: getattr(opts, f.name) for f in fields(opts)},
                       "time_step_value": layout.t if layout else None,
                       "landmarks_used": layout.k if layout else None},
        "method": method,
        "mesh": info.as_dict(),
        "metrics": summary,
        "timings_s": prog.timings,
        "peak_rss_mb": round(peak_rss_bytes() / 2**20, 1),
        "machine": {"python": platform.python_version(), "platform": platform.platform()},
        "warnings": warnings,
    }
    return Result(uv, report, flat.surface, Fuv, uv_vertex)


def _decide_fill(opts: Options, V: np.ndarray, F: np.ndarray, info: MeshInfo,
                 conformal: Callable[[], np.ndarray]) -> tuple[bool, str]:
    """Whether to compute on a Poisson fill M* (§2.5), and why."""
    if opts.fill == "none":
        return False, "disabled (--fill none)"
    if opts.fill in ("poisson", "biharmonic"):
        return True, f"requested (--fill {opts.fill})"
    from heatparam import fill

    return fill.needs_fill(V, F, info, conformal)


class Layout(NamedTuple):
    uv: np.ndarray  # (n,2) MDS layout of the points
    uv_surface: np.ndarray | None  # (N,2) MDS layout of the geodesic surface's vertices (fill path only)
    D_points: np.ndarray  # (n_points, c) geodesic distances used for the stress sample
    stress_columns: np.ndarray  # (c,) point index of each column's source
    mode: str
    k: int
    t: float
    backend: str
    mollify_eps: float
    stress: dict | None = None  # SMACOF info (``mds.smacof``, without its history) when opts.stress == "smacof"
    warning: str | None = None  # an explicit time step too small for the surface (``heat.underflow_warning``)


def _geodesic_layout(V: np.ndarray, F: np.ndarray, opts: Options, prog: Progress,
                     points: tuple[np.ndarray, np.ndarray] | None = None) -> Layout:
    """Heat geodesics on (V, F) and MDS (Eq. 4-14) of its vertices, or of ``points`` located on it.

    points : (face (p,), bary (p,3)) — points on the surface (V, F), e.g. the vertices of M located on a fill
        surface M*. Their distances are interpolated from the landmark distance fields, and they are placed by
        landmark MDS with the landmarks on (V, F).
    """
    n = len(V)
    mode = opts.geodesics
    if mode == "auto":
        mode = "all-pairs" if n <= opts.all_pairs_max else "landmarks"
    if points is not None:
        mode = "landmarks" if opts.geodesics != "all-pairs" else "all-pairs"
    if mode == "all-pairs":
        require(heat.all_pairs_bytes(n), f"all-pairs geodesics on {n} vertices ({n} x {n} matrix)",
                "use --geodesics landmarks (or auto)")
    with prog.stage("operators"):
        op = build_operators(V, F, mass=opts.mass)
    t = heat.time_step(op, opts.time_step, opts.t_coef)
    warning = heat.underflow_warning(op, t) if opts.time_step != "default" else None
    with prog.stage("factorize"):
        solver = heat.HeatGeodesics(op, t, backend=opts.solver)
    rng = np.random.default_rng(opts.seed)
    if mode == "all-pairs" and points is None:
        with prog.stage("geodesics"), prog.bar(n, "geodesics", "src") as bar:
            D = heat.all_pairs(solver, progress=bar.update)
        cols = np.sort(rng.choice(n, size=min(n, opts.stress_sources), replace=False))
        D_stress = D[:, cols].copy()
        with prog.stage("mds"):
            uv = mds.classical_mds(D, seed=opts.seed, overwrite=True)
        sinfo = None
        if opts.stress == "smacof":
            with prog.stage("stress"):
                np.sqrt(D, out=D)  # MDS squared D in place; sqrt(fl(x²)) = x restores it exactly
                uv, sinfo = _smacof(uv, D)
        del D
        return Layout(uv, None, D_stress, cols, mode, n, t, solver.backend, op.mollify_eps, sinfo, warning)
    k = n if mode == "all-pairs" else (opts.landmarks or default_landmarks(n))
    with prog.stage("geodesics"), prog.bar(k + 1, "landmark geodesics", "src") as bar:
        if k >= n:
            lm = np.arange(n)
            DL = solver.distances(lm, progress=bar.update)
        else:
            lm, DL = heat.farthest_point_landmarks(solver, V, k, seed=opts.seed, progress=bar.update)
    if points is None:
        with prog.stage("mds"):
            uv, _ = mds.landmark_mds(DL, lm)
        sinfo = None
        if opts.stress == "smacof":
            with prog.stage("stress"):
                uv, sinfo = _smacof(uv, DL, lm)
        cols = np.arange(min(k, opts.stress_sources))
        return Layout(uv, None, DL[:, cols], lm[cols], mode, k, t, solver.backend, op.mollify_eps, sinfo,
                      warning)
    face, bary = points
    with prog.stage("mds"):
        DP = np.einsum("pc,pck->pk", bary, DL[F[face]])  # landmark distances interpolated at the points
        DA = np.vstack([DP, DL])
        both, _ = mds.landmark_mds(DA, Dkk=DL[lm])  # points and M*'s vertices, one frame
    sinfo = None
    if opts.stress == "smacof":  # the same n×k pattern: points and M*'s vertices against the landmarks on M*
        with prog.stage("stress"):
            both, sinfo = _smacof(both, DA, len(face) + lm)
    del DA
    both -= both[: len(face)].mean(axis=0)
    uv, uv_surface = both[: len(face)], both[len(face) :]
    # Stress sample: distances on the fill surface from a few of the points themselves (point sources).
    with prog.stage("geodesics"):
        cols = np.sort(rng.choice(len(face), size=min(len(face), opts.stress_sources), replace=False))
        Ds = solver.distances(heat.point_sources(F, face[cols], bary[cols], n))
        D_stress = np.einsum("pc,pck->pk", bary, Ds[F[face]])
    return Layout(uv, uv_surface, D_stress, cols, mode, k, t, solver.backend, op.mollify_eps, sinfo, warning)


def _smacof(X0: np.ndarray, D: np.ndarray, landmarks: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """``mds.smacof`` from the MDS layout; its info for the report (without the per-iteration history)."""
    X, info = mds.smacof(X0, D, landmarks)
    info.pop("history")
    return X, {"method": "smacof", **info}
