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

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from heatparam.errors import HeatparamError, TopologyError
from heatparam.heat import check_time_step
from heatparam.memory import require
from heatparam.mesh.validate import as_arrays
from heatparam.options import Options, make_options
from heatparam.pipeline.atlas_stage import DEFAULT_MAX_DISTORTION, atlas_result, stretch_note
from heatparam.pipeline.heat_stage import FillSurface, Layout, decide_fill, mds_map
from heatparam.pipeline.report import Flat, Result, build_report, map_metrics, method_report
from heatparam.pipeline.seams import seam_pause, seams_stage
from heatparam.pipeline.shortcuts import heat_stage_optional, start_checks
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine import NO_PAUSE, Pausing, Refinement, RefineParams, polish_bytes
from heatparam.refine.start import SmoothedStart

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
    V, F = as_arrays(V, F)
    prog = Progress(opts.progress)
    if opts.max_distortion:  # a bound asked for: segmented into charts that meet it (a disk too)
        return _atlas(V, F, opts, prog, "max_distortion was given")
    if opts.pack == "texture":  # a texture wants low distortion more than one piece: a disk gets the bound too
        return _atlas(V, F, opts, prog, "pack='texture' bounds every chart's distortion")
    try:
        result = _disk(V, F, opts, prog)
    except TopologyError as exc:  # closed, handles, several parts, non-manifold: an atlas of disk charts
        return _atlas(V, F, opts, prog, exc.reason)
    _warn_if_stretched(result.report, prog)
    return result


def _warn_if_stretched(report: dict, prog: Progress) -> None:
    """A one-piece map stretched past the atlas's bound: say so, and how to get pieces within it."""
    m = report["metrics"]
    if m["iso_mean"] > DEFAULT_MAX_DISTORTION:
        w = stretch_note("the one-piece map", m["iso_mean"], m["iso_p95"])
        report["warnings"].append(w)
        prog.warn(w)


def parameterize_disk(V: np.ndarray, F: np.ndarray, options: Options | None = None, **kwargs) -> Result:
    """:func:`parameterize` of a single disk (possibly with holes) only: a mesh that is not one (closed, handles,
    several parts, non-manifold) raises :class:`~heatparam.errors.TopologyError` instead of becoming an atlas. The
    atlas stage flattens each of its charts with it."""
    opts = make_options(options, **kwargs)
    V, F = as_arrays(V, F)
    return _disk(V, F, opts, Progress(opts.progress))


def _disk(V: np.ndarray, F: np.ndarray, opts: Options, prog: Progress) -> Result:
    """The stages of one disk (the module docstring's flow)."""
    with prog.stage("validate"):
        surface, comp, info = Surface.validated(V, F)
    _check_memory(len(V), len(F), opts)
    check_time_step(opts.time_step, info.diameter * surface.frame.unit)
    sr = seams_stage(surface, opts, prog, flatten(surface, opts, prog, pausing=seam_pause(surface, opts)), flatten)
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
        result = atlas_result(V, F, opts, why=why, flatten_disk=parameterize_disk, prog=prog)
    # the stages as the log printed them (the disk check that found no disk, then the whole atlas stage), so that
    # they add up to the total unwrap prints
    result.report["timings_s"] = dict(prog.timings)
    return result


def _to_model(flat: Flat, frame) -> Flat:
    """A flattening's layout in model units (its report's lengths are converted in ``report.build_report``)."""
    return flat._replace(uv=frame.lengths_to_model(flat.uv))


def _check_memory(n: int, m: int, opts: Options) -> None:
    """Refuse at once, not after minutes of work, what memory could not hold."""
    raw = RAW_BYTES_PER_VERTEX * n
    require(raw, f"parameterizing {n} vertices", "decimate the mesh or split it into patches")
    if opts.refine != "none":
        require(raw + polish_bytes(m), f"parameterizing and refining {m} triangles",
                "use refine='none' (the raw MDS map) or decimate the mesh")


def flatten(surface: Surface, opts: Options, prog: Progress, *, seamed: bool = False,
            starts: dict[str, np.ndarray] | None = None, pausing: Pausing = NO_PAUSE,
            repair: Callable[[np.ndarray], tuple[np.ndarray | None, dict]] | None = None) -> Flat:
    """The stages on one surface (``seamed``: cut open by the seams stage, whose seams a fill would close again;
    ``starts``: further named start layouts (n,2) for the refinement; ``pausing``: how the polish may pause,
    ``refine.Pausing``: the Flat's ``resume`` then finishes it, so that the seams stage decides on paused maps;
    ``repair``: how the refinement's fallback start, the smoothed surface's conformal layout, is made bijective,
    ``refine.start.SmoothedStart``: default ``refine.start.repaired_layout``)."""
    return _Flattening(surface, opts, prog, starts, pausing, repair).run(seamed)


class _Flattening:
    """:func:`flatten`: the fill decision, the start checks, the heat stage (when it can win), the refinement."""

    def __init__(self, surface: Surface, opts: Options, prog: Progress, starts: dict[str, np.ndarray] | None,
                 pausing: Pausing, repair: Callable[[np.ndarray], tuple[np.ndarray | None, dict]] | None = None):
        self.surface, self.opts, self.prog, self.starts, self.pausing = surface, opts, prog, starts, pausing
        self.repair = repair
        self.label = ""

    def run(self, seamed: bool) -> Flat:
        self.label = self.pass_name(seamed)
        with self.prog.in_pass(self.label):
            return self.flattened(seamed)

    def pass_name(self, seamed: bool) -> str:
        """The pass the log names (stages run once per map when the seams stage may make a second one)."""
        if seamed:
            return "map with seams"
        return "map without seams" if self.surface.info.n_holes and self.opts.seams != "none" else ""

    def flattened(self, seamed: bool) -> Flat:
        opts, prog = self.opts, self.prog
        with prog.stage("fill decision"):
            fill_used, fill_reason = decide_fill(opts, self.surface, seamed)
        check = start_checks(self.surface, opts, prog, seamed, trial=self.pausing.excess > 0)
        if check.skipped is not None:
            fill = {"used": False, "reason": fill_reason, "skipped": check.skipped} if fill_used else \
                {"used": False, "reason": fill_reason}
            return self.refined(None, check, _Heat(None, check.skipped, fill, None, []))
        self.surface.release_layouts()  # the heat stage's factorizations need the memory more
        try:
            m = mds_map(self.surface, opts, prog, fill_used, fill_reason)
        except HeatparamError as exc:
            if opts.refine == "none" or opts.mds_start != "auto" or not heat_stage_optional(opts):
                raise  # the heat stage was asked for (or is the map itself): its failure is the answer
            # otherwise it only offers a start: the refinement starts from a conformal layout or Tutte
            why = (f"skipped: the heat stage failed ({exc}); the refinement starts from the conformal layout, or "
                   "the smoothed surface's, or Tutte when neither is bijective")
            fill = {"used": False, "reason": fill_reason, "skipped": why}
            warning = f"the heat stage failed ({exc}): the map starts without MDS"
            return self.refined(None, check, _Heat(None, why, fill, None, [warning]))
        if opts.refine == "none":
            summary = map_metrics(self.surface.V, self.surface.F, m.uv, prog, m.layout)
            method = method_report(opts, m.layout, None, m.fill, {"method": opts.refine})
            return Flat(m.uv, summary, method, m.layout, m.fill_surface, m.warnings)
        return self.refined(m.uv, check, _Heat(m.layout, None, m.fill, m.fill_surface, m.warnings))

    def fallback(self) -> SmoothedStart:
        """The refinement's start before Tutte's: the conformal layout of the smoothed surface, made bijective by
        ``repair`` (default ``refine.start.repaired_layout``)."""
        s = self.surface
        return SmoothedStart(s.smoothed_conformal, s.F, *s.gradients(), s.info.boundary_loops, repair=self.repair,
                             release=s.release_layouts)

    def refined(self, uv: np.ndarray | None, check, heat: _Heat) -> Flat:
        """The refinement from the MDS layout ``uv`` (None: the heat stage was skipped), as a Flat."""
        s = self.surface
        with self.prog.stage("refine"):
            rf = Refinement(s.V, s.F, uv, RefineParams.from_options(self.opts), progress=self.prog,
                            conformal=s.conformal, lscm=check.lscm, surface=s.gradients(), extra_starts=self.starts,
                            pausing=self.pausing, fallback=self.fallback())
        return _Refined(self, rf, heat).flat()


class _Heat(NamedTuple):
    """What the heat stage gave a refinement: its MDS layout (None when skipped), why it was skipped, the report's
    fill part, the fill surface (for pictures) and warnings."""

    layout: Layout | None
    skipped: str | None
    fill: dict
    fill_surface: FillSurface | None
    warnings: list[str]


class _Refined:
    """A refinement's Flat, with a ``resume`` that finishes the refinement when it paused."""

    def __init__(self, flattening: _Flattening, rf: Refinement, heat: _Heat):
        self.flattening, self.rf, self.heat = flattening, rf, heat

    def flat(self) -> Flat:
        f, h = self.flattening, self.heat
        summary = map_metrics(f.surface.V, f.surface.F, self.rf.x, f.prog, h.layout)
        method = method_report(f.opts, h.layout, h.skipped, h.fill, self.rf.report(summary))
        return Flat(self.rf.x, summary, method, h.layout, h.fill_surface, h.warnings,
                    None if self.rf.done else self.resume)

    def resume(self, pause_excess: float = 0.0) -> Flat:
        """The refinement finished (or, with ``pause_excess`` > 0, gone on to its next pause: ``refine.Pausing``)."""
        f = self.flattening
        with f.prog.in_pass(", ".join(x for x in (f.label, "resumed") if x)):
            with f.prog.stage("refine"):
                self.rf.run(pause_excess)
            return self.flat()


__all__ = ["FillSurface", "Options", "Result", "flatten", "parameterize", "parameterize_disk"]
