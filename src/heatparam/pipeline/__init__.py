"""The orchestrator: one mesh down the paper's stages (Figure 1) and ours, with a report.

``parameterize(V, F, **options)`` → :class:`Result` (unpacks as ``uv, report``). It never touches files.

::

    validate + compact (surface)                   mesh.validate_mesh, Surface
      └ flatten(surface)
          fill decision                            heat_stage.decide_fill (fill.needs_fill, §2.5)
          start checks: skip the heat stage?       shortcuts.start_checks (the conformal start judged)
          fill M* → heat geodesics → MDS           heat_stage.mds_map (fill, heat, layout.mds; Eq. 2-16)
          refine: start + bijective polish         refine.refine
          metrics                                  report.map_metrics
      └ seams: flatten(surface cut open)?          seams.seams_stage
    report + Result                                report.build_report

Each stage returns its value and its part of the report; the report is assembled once, in ``report``.
"""

from __future__ import annotations

import numpy as np

from heatparam.errors import HeatparamError, TopologyError
from heatparam.heat import check_time_step
from heatparam.memory import require
from heatparam.options import Options, make_options
from heatparam.pipeline.atlas_stage import atlas_result
from heatparam.pipeline.heat_stage import FillSurface, decide_fill, mds_map
from heatparam.pipeline.report import Flat, Result, build_report, map_metrics, method_report
from heatparam.pipeline.seams import seam_pause, seams_stage
from heatparam.pipeline.shortcuts import heat_stage_optional, start_checks
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress

#: Peak memory of the pipeline without the refinement, per vertex (landmark path): ``refine none`` peaked at
#: 3.5-3.9 KB per vertex on camelhead↑727k and 4.4-5.9 KB on camelhead↑182k, interpreter and libraries included
#: (BENCHMARKS.md §4). With the refinement, ``refine.polish_bytes`` per face comes on top (727k: 6.3 GB measured,
#: 6.7 GB estimated).
RAW_BYTES_PER_VERTEX = 4000


def parameterize(V: np.ndarray, F: np.ndarray, options: Options | None = None, **kwargs) -> Result:
    """Flatten a disk-like triangle mesh near-isometrically (true scale).

    Parameters
    ----------
    V : (n,3) float64 vertices.
    F : (m,3) int64 triangles (consistently oriented).
    options : an :class:`~heatparam.options.Options`; keyword arguments override its fields
        (``parameterize(V, F, seed=3)``).

    Returns
    -------
    Result(uv (n,2) float64, report dict): uv[i] is the image of V[i]; the report holds the parameters,
    per-stage timings, mesh facts and the map's metrics (see README). With seams (``Options.seams``,
    ``Result.seamed``) uv has one row per seam side: face f's corners map to ``uv[Result.Fuv[f]]``.

    Raises
    ------
    HeatparamError (MeshError, ResourceError) with a one-line message for bad input or a request that cannot fit.

    Examples
    --------
    >>> from heatparam import datasets, parameterize
    >>> s = datasets.cylinder_patch(h=0.1)
    >>> uv, report = parameterize(s.V, s.F)
    >>> report["metrics"]["flips"], round(report["metrics"]["iso_mean"], 3)
    (0, 1.0)
    """
    opts = make_options(options, **kwargs)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    prog = Progress(opts.progress)
    if opts.max_distortion:  # a bound asked for: segmented into charts that meet it (a disk too)
        return _atlas(V, F, opts, prog, "max_distortion was given")
    try:
        return _disk(V, F, opts, prog)
    except TopologyError as exc:  # closed, handles, several parts, non-manifold: an atlas of disk charts
        return _atlas(V, F, opts, prog, str(exc).split(" — ")[0])


def parameterize_disk(V: np.ndarray, F: np.ndarray, options: Options | None = None, **kwargs) -> Result:
    """:func:`parameterize` of a single disk (possibly with holes) only: a mesh that is not one (closed, handles,
    several parts, non-manifold) raises :class:`~heatparam.errors.TopologyError` instead of becoming an atlas. The
    atlas stage flattens each of its charts with it."""
    opts = make_options(options, **kwargs)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    return _disk(V, F, opts, Progress(opts.progress))


def _disk(V: np.ndarray, F: np.ndarray, opts: Options, prog: Progress) -> Result:
    """The stages of one disk (the module docstring's flow)."""
    with prog.stage("validate"):
        surface, comp, info = Surface.validated(V, F)
    _check_memory(len(V), len(F), opts)
    check_time_step(opts.time_step, info.diameter * surface.frame.unit)
    pause, coarse = seam_pause(surface, opts)
    sr = seams_stage(surface, opts, prog, flatten(surface, opts, prog, pause_excess=pause, pause_coarse=coarse),
                     flatten)
    flat = sr.uncut  # finished when kept; possibly paused when the cut map won (seams_stage)
    if surface.frame.exponent:  # back to model units (exact: × a power of two)
        flat, sr = _to_model(flat, surface.frame), sr._replace(flat=_to_model(sr.flat, surface.frame))
    if sr.cut is None:
        uv = np.zeros((len(V), 2))
        uv[comp.keep] = flat.uv
        uv[~info.referenced] = flat.uv.mean(axis=0)
        Fuv, uv_vertex, without = F, np.arange(len(V), dtype=np.int64), None
    else:  # the cut mesh's faces are F's, row for row, in compacted and then split vertex ids
        uv, Fuv, uv_vertex = sr.flat.uv, sr.cut.surface.F, comp.keep[sr.cut.source]
        without = {"refine": flat.method["refine"], "metrics": flat.summary}
    warnings = [*info.warnings, *flat.warnings, *sr.warnings]
    report = build_report(opts, sr.flat, sr.report, without, info.as_dict(), prog, warnings, surface.frame)
    for w in report["warnings"]:
        prog.warn(w)
    return Result(uv, report, sr.flat.fill_surface, Fuv, uv_vertex)


def _atlas(V: np.ndarray, F: np.ndarray, opts: Options, prog: Progress, why: str) -> Result:
    """The atlas stage (``atlas_stage``): repair, segment into disk charts, flatten each with these stages
    (:func:`parameterize_disk`), pack; the map as a :class:`Result` with ``chart`` set."""
    with prog.stage("atlas"):
        return atlas_result(V, F, opts, why=why, flatten_disk=parameterize_disk, prog=prog)


def _to_model(flat: Flat, frame) -> Flat:
    """A flattening's layout in model units (its report's lengths are converted in ``report.build_report``)."""
    return flat._replace(uv=frame.lengths_to_model(flat.uv))


def _check_memory(n: int, m: int, opts: Options) -> None:
    """Refuse at once, not after minutes of work, what memory could not hold."""
    from heatparam.refine import polish_bytes

    raw = RAW_BYTES_PER_VERTEX * n
    require(raw, f"parameterizing {n} vertices", "decimate the mesh or split it into patches")
    if opts.refine != "none":
        require(raw + polish_bytes(m), f"parameterizing and refining {m} triangles",
                "use refine='none' (the raw MDS map) or decimate the mesh")


def flatten(surface: Surface, opts: Options, prog: Progress, seamed: bool = False,
            starts: dict[str, np.ndarray] | None = None, pause_excess: float = 0.0, pause_coarse: float = 0.0,
            pause_park: bool = True) -> Flat:
    """The stages on one surface (``seamed``: cut open by the seams stage, whose seams a fill would close again;
    ``starts``: further named start layouts (n,2) for the refinement, e.g. the uncut map with its slits opened;
    ``pause_excess`` > 0: the polish may pause once an iteration gains less than that fraction of the energy's
    excess over an isometry, and the Flat's ``resume`` finishes it: the seams stage decides on paused maps;
    ``pause_coarse`` > 0: its coarse levels may pause too while their iso mean exceeds it,
    ``refine.multilevel.Levels``; ``pause_park`` False: the paused fine polish keeps its factorization, for a trial
    that is usually finished next).
    """
    from heatparam.refine import Refinement, RefineParams

    with prog.stage("fill decision"):
        fill_used, fill_reason = decide_fill(opts, surface, seamed)
    check = start_checks(surface, opts, prog, seamed, trial=pause_excess > 0)
    params = RefineParams.from_options(opts)

    def without_heat_stage(why: str, fill: dict, warnings: list[str]) -> Flat:
        """The refinement from the conformal layout or Tutte, the heat stage not computed (``why``)."""
        with prog.stage("refine"):
            rf = Refinement(surface.V, surface.F, None, params, prog, surface.conformal, check.lscm,
                            surface.gradients(), starts, pause_excess, pause_coarse, pause_park)
        return _refined(surface, opts, prog, rf, None, why, fill, None, warnings)

    if check.skipped is not None:
        fill = {"used": False, "reason": fill_reason, "skipped": check.skipped} if fill_used else \
            {"used": False, "reason": fill_reason}
        return without_heat_stage(check.skipped, fill, [])
    try:
        m = mds_map(surface, opts, prog, fill_used, fill_reason)
    except HeatparamError as exc:
        if opts.refine == "none" or opts.mds_start != "auto" or not heat_stage_optional(opts):
            raise  # the heat stage was asked for (or is the map itself): its failure is the answer
        # otherwise it only offers a start: the refinement starts from the conformal layout or Tutte
        why = (f"skipped: the heat stage failed ({exc}); the refinement starts from the conformal layout, or Tutte "
               "when it is not bijective")
        return without_heat_stage(why, {"used": False, "reason": fill_reason, "skipped": why},
                                  [f"the heat stage failed ({exc}): the map starts without MDS"])
    if opts.refine == "none":
        summary = map_metrics(surface.V, surface.F, m.uv, prog, m.layout)
        method = method_report(opts, m.layout, None, m.fill, {"method": opts.refine})
        return Flat(m.uv, summary, method, m.layout, m.fill_surface, m.warnings)
    with prog.stage("refine"):
        rf = Refinement(surface.V, surface.F, m.uv, params, prog, surface.conformal, check.lscm,
                        surface.gradients(), starts, pause_excess, pause_coarse, pause_park)
    return _refined(surface, opts, prog, rf, m.layout, None, m.fill, m.fill_surface, m.warnings)


def _refined(surface: Surface, opts: Options, prog: Progress, rf, layout, skipped, fill, fill_surface,
             warnings: list[str]) -> Flat:
    """The Flat of a refinement (``refine.Refinement``), with a ``resume`` that finishes it when it paused."""
    summary = map_metrics(surface.V, surface.F, rf.x, prog, layout)
    method = method_report(opts, layout, skipped, fill, rf.report())

    def resume() -> Flat:
        with prog.stage("refine"):
            rf.run()
        return _refined(surface, opts, prog, rf, layout, skipped, fill, fill_surface, warnings)

    return Flat(rf.x, summary, method, layout, fill_surface, warnings, None if rf.done else resume)


__all__ = ["FillSurface", "Options", "Result", "flatten", "parameterize", "parameterize_disk"]
