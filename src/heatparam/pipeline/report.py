"""What a flattening returns: :class:`Flat` (one flattening of a surface), :class:`Result` (the API's value) and the
report, assembled here and nowhere else."""

from __future__ import annotations

import platform
from collections.abc import Callable
from dataclasses import asdict
from typing import NamedTuple

import numpy as np

from heatparam import metrics
from heatparam.memory import peak_rss_bytes
from heatparam.mesh.frame import UnitFrame
from heatparam.pipeline.heat_stage import FillSurface, Layout
from heatparam.progress import Progress
from heatparam.version import __version__


class Flat(NamedTuple):
    """One flattening of a surface: the map (n,2), its metrics, the report's ``method`` part, the MDS layout it
    came from (None when the heat stage was skipped), the fill surface (for pictures) and warnings. ``resume``:
    None for a finished flattening; for one whose polish paused (``pipeline.flatten(pause_excess=...)``: the map
    is bijective, its metrics those of the paused layout) a call that finishes it and returns the finished Flat
    (``resume(pause_excess)``: goes on to its next pause instead)."""

    uv: np.ndarray
    summary: dict
    method: dict
    layout: Layout | None
    fill_surface: FillSurface | None
    warnings: list[str]
    resume: Callable[..., Flat] | None = None


def map_metrics(V: np.ndarray, F: np.ndarray, uv: np.ndarray, prog: Progress, layout: Layout | None) -> dict:
    """The map's metrics; the sampled Eq. 1 stress against the geodesics when they were computed (else None)."""
    with prog.stage("metrics"):
        summary = metrics.summary(V, F, uv)
        try:
            summary["stress_rel_rms"] = (metrics.stress(uv, layout.D_points, layout.stress_columns)
                                         if layout is not None else None)
        except ValueError:  # no finite geodesic distance (degenerate faces): the stress is undefined, not fatal
            summary["stress_rel_rms"] = None
    return summary


def method_report(opts, layout: Layout | None, skipped: str | None, fill: dict, refine: dict) -> dict:
    """The report's ``method`` part of one flattening."""
    return {"geodesics": skipped if layout is None else layout.mode,
            "solver_backend": None if layout is None else layout.backend, "fill": fill,
            "stress": (layout.stress if layout is not None else None) or {"method": "none"}, "refine": refine,
            "mass_matrix": opts.mass, "mollified_edge_length": None if layout is None else layout.mollify_eps}


class Result(tuple):
    """What :func:`heatparam.parameterize` returns; unpacks as ``uv, report``.

    uv : (n_uv,2) float64, the map. Without seams n_uv = n and uv[i] is the image of input vertex i. With seams
        (``report["method"]["seams"]["used"]``) every vertex on a seam has one row per side.
    report : the JSON-able report.
    Fuv : (m,3) int64, the rows of ``uv`` at each face's corners (F itself without seams): OBJ's ``f v/vt``.
    uv_vertex : (n_uv,) int64, the input vertex of each row of ``uv`` (``arange(n)`` without seams).
    fill_surface : a :class:`FillSurface` when a fill was used (for pictures), else None.
    chart : (m,) int64 chart of each face for an atlas (``report["method"]["atlas"]``), else None (one piece).
    """

    def __new__(cls, uv: np.ndarray, report: dict, fill_surface: FillSurface | None = None,
                Fuv: np.ndarray | None = None, uv_vertex: np.ndarray | None = None, chart: np.ndarray | None = None):
        self = super().__new__(cls, (uv, report))
        self.fill_surface = fill_surface
        self.chart = chart
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
        """Whether the map has seams or charts (``uv`` rows are not the input's vertices)."""
        return self.chart is not None or bool(self.report["method"]["seams"]["used"])


def build_report(opts, flat: Flat, seams: dict, without_seams: dict | None, mesh_facts: dict, prog: Progress,
                 warnings: list[str], frame: UnitFrame) -> dict:
    """The whole report: parameters, method (with the seams part), mesh facts, metrics, timings, machine,
    warnings (a last one when the map is not bijective). Lengths and areas in model units (``frame``: the
    surface's unit frame, whose internal units the stages reported in)."""
    summary, layout = flat.summary, flat.layout
    if frame.exponent:
        summary, mesh_facts, seams = _model_units(frame, summary, mesh_facts, seams)
        flat = flat._replace(method=_method_in_model_units(frame, flat.method))
        if without_seams is not None:
            without_seams = {**without_seams, "metrics": _model_units(frame, without_seams["metrics"], {}, {})[0]}
    method = {**flat.method, "seams": seams}
    if without_seams is not None:
        method["without_seams"] = without_seams
    parameters = {**asdict(opts), "time_step_value": frame.areas_to_model(layout.t) if layout else None,
                  "landmarks_used": layout.k if layout else None}
    return envelope(parameters, method, mesh_facts, summary, prog.timings, warnings)


def envelope(parameters: dict, method: dict, mesh_facts: dict, summary: dict, timings: dict, warnings: list[str]
             ) -> dict:
    """A report's top level, the same for one flattening and an atlas: version, parameters, method, mesh facts,
    metrics, timings, peak memory, machine, and the warnings (a last one when the map is not bijective)."""
    if summary["flips"] or summary["boundary_crossings"] or summary.get("inverted_loops"):
        warnings = [*warnings, f"the map is not bijective: {summary['flips']} flipped triangles, "
                               f"{summary['boundary_crossings']} boundary crossings"
                               + (f", {summary['inverted_loops']} holes turned inside out (covered twice)"
                                  if summary.get("inverted_loops") else "")]
    return {
        "heatparam_version": __version__,
        "parameters": parameters,
        "method": method,
        "mesh": mesh_facts,
        "metrics": summary,
        "timings_s": timings,
        "peak_rss_mb": round(peak_rss_bytes() / 2**20, 1),
        "machine": {"python": platform.python_version(), "platform": platform.platform()},
        "warnings": warnings,
    }


#: report fields that are lengths / areas, per part (converted from internal to model units)
_LENGTHS = {"mesh": ("mean_edge_length", "max_edge_length", "bbox_diagonal"), "seams": ("length", "longest"),
            "fill": ("distance_max", "distance_mean")}
_AREAS = {"mesh": ("area",), "metrics": ("total_area_3d", "total_area_uv")}


def _model_units(frame: UnitFrame, summary: dict, mesh_facts: dict, seams: dict) -> tuple[dict, dict, dict]:
    """The metrics, mesh facts and seams report parts in model units."""
    def conv(d: dict, part: str) -> dict:
        out = dict(d)
        for k in _LENGTHS.get(part, ()):
            if out.get(k) is not None:
                out[k] = frame.lengths_to_model(out[k])
        for k in _AREAS.get(part, ()):
            if out.get(k) is not None:
                out[k] = frame.areas_to_model(out[k])
        return out

    return conv(summary, "metrics"), conv(mesh_facts, "mesh"), conv(seams, "seams")


def _method_in_model_units(frame: UnitFrame, method: dict) -> dict:
    out = dict(method)
    if out.get("mollified_edge_length") is not None:
        out["mollified_edge_length"] = frame.lengths_to_model(out["mollified_edge_length"])
    fill = dict(out.get("fill") or {})
    for k in _LENGTHS["fill"]:
        if fill.get(k) is not None:
            fill[k] = frame.lengths_to_model(fill[k])
    out["fill"] = fill
    return out
