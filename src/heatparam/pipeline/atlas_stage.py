"""The atlas stage: any mesh as disk charts, each flattened by the pipeline's stages, packed without overlap.

``pipeline.parameterize`` comes here for what a single flattening refuses (closed surfaces, handles, nearly closed
scans, several components, non-manifold vertices and edges) and when a distortion bound is asked for::

    repair (lossless): clean components                     atlas.repair
    a scan (one main piece, the rest debris: each under DEBRIS_AREA_SHARE of its area)
      the main piece whole, one chart (pattern mode: any    flatten_disk
        distortion; --pack texture: within the bound)
      each debris piece whole (LSCM, polished jointly)      atlas.polish
        within the bound, the rest together, segmented      atlas.segment (below)
    else each component
      whole, when it is one disk mapped bijectively         flatten_disk (the default bound only)
      else segmented: grow, check, split, merge             atlas.segment
        the charts polished together                        atlas.polish (refine.charts)
        a chart that fails: the pipeline, else its halves,  flatten_disk, atlas.grow.halves,
          else its LSCM layout, else one chart per face     atlas.flatten.quick_flatten
    the tiny components together, as one part               atlas.repair.union
    pack                                                    atlas.pack
    the map and its report (overlaps: the border band)      AtlasResult; Result (report.envelope)

The input's vertices and faces are unchanged, row for row; face f's corners map to ``uv[Fuv[f]]``. Disks are
flattened by the function the stage is given (``flatten_disk``: ``pipeline.parameterize_disk``), so that this
module imports nothing that imports it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from heatparam import metrics
from heatparam.atlas.border_band import exact_overlap_count
from heatparam.atlas.chart_seams import chart_seam_lengths, cut_half_edges, seam_length
from heatparam.atlas.chart_topology import Topology, chart_mesh
from heatparam.atlas.flatten import quick_flatten, segment_layout, triangle_layout
from heatparam.atlas.grow import halves
from heatparam.atlas.overlap import folded_zero_area, uv_degenerate_faces
from heatparam.atlas.pack import pack_charts
from heatparam.atlas.polish import polish_charts
from heatparam.atlas.repair import Component, Repair, repair, union
from heatparam.atlas.segment import Segmentation, proxy_bound, segment
from heatparam.errors import HeatparamError
from heatparam.mesh.topology import degenerate_faces
from heatparam.mesh.validate import as_arrays
from heatparam.options import Options, make_options
from heatparam.pipeline.report import Result, envelope
from heatparam.refine import RefineParams

__all__ = ["ATLAS_FIELDS", "AtlasResult", "Chart", "DEBRIS_AREA_SHARE", "DEFAULT_MAX_DISTORTION", "DiskFlattener",
           "TINY_COMPONENT_FACES", "atlas", "atlas_result", "scan_main", "stretch_note"]

#: isometric distortion bound per chart (area-weighted mean of max(s1, 1/s2)); measured in BENCHMARKS.md
DEFAULT_MAX_DISTORTION = 1.05
#: components with fewer faces are reported as tiny (they still get charts)
TINY_COMPONENT_FACES = 20
#: a component under this share of the largest one's area is scan debris (a floating island, a fin cut off at a
#: bowtie), not a part: the largest debris piece measured 0.004-0.15% of the main piece on 26 tuning scans of all six
#: kinds, a second real part (a two-part mask, an assembly) is tens of percent; 1% is far from both (docs/atlas.md)
DEBRIS_AREA_SHARE = 0.01
#: the Options fields that are the atlas's own (not passed to the per-chart pipeline)
ATLAS_FIELDS = ("max_distortion", "max_charts", "pack", "padding", "resolution", "texels_per_unit", "progress")

#: one disk (V, F) flattened by the pipeline's stages with the options given: ``pipeline.parameterize_disk``
DiskFlattener = Callable[[np.ndarray, np.ndarray, Options], Result]


@dataclass
class AtlasResult:
    """uv (k,2) float64; Fuv (m,3) int64 rows of uv per face corner (F row for row); uv_vertex (k,) int64 input
    vertex of each uv row; chart (m,) int64 chart of each face; report dict (per chart and totals); summary: the
    map's ``metrics.summary`` (computed once: the report's totals and the pipeline's metrics both read it)."""

    uv: np.ndarray
    Fuv: np.ndarray
    uv_vertex: np.ndarray
    chart: np.ndarray
    report: dict = field(default_factory=dict)
    summary: dict = field(default_factory=dict)


@dataclass
class Chart:
    """One chart of the atlas: faces (m_i,) input face rows, Fl (m_i,3) its triangles in local rows, vert (n_i,)
    input vertex of each local row, uv (n_i,2) its layout, component (input component id), info (report entry)."""

    faces: np.ndarray
    Fl: np.ndarray
    vert: np.ndarray
    uv: np.ndarray
    component: int
    info: dict


def atlas(V: np.ndarray, F: np.ndarray, flatten_disk: DiskFlattener, *, max_distortion: float | None = None,
          max_charts: int | None = None, pack: str = "scale", padding: float = 4.0, resolution: int = 1024,
          texels_per_unit: float | None = None, seed: int = 0, progress: bool = False,
          **pipeline_options) -> AtlasResult:
    """A bijective, near-isometric atlas of any triangle mesh (module docstring).

    Parameters
    ----------
    V : (n,3) float64. F : (m,3) int64.
    flatten_disk : flattens one disk chart: ``heatparam.pipeline.parameterize_disk``.
    max_distortion : per-chart bound on the isometric distortion (area-weighted mean of max(s1, 1/s2)).
        None (default): charts are segmented and merged to ``DEFAULT_MAX_DISTORTION`` (1.05); a part that
        ``parameterize`` accepts (a disk, possibly with holes, not nearly closed) stays one piece when its map is
        bijective and within that bound. A scan (:func:`scan_main`: one main piece, every other component debris)
        keeps its main piece whole as a plain disk would be: with ``pack='scale'`` whatever its distortion
        (when bijective), with ``'texture'`` within the bound; its debris is charted together, within the bound.
        A number: every part is segmented to that bound.
    max_charts : a cap on the charts of each component: when the bound leaves more, merging goes on past the
        bound (each merged chart still bijective) down to this count where bijective merges exist; a warning
        says when the atlas still has more.
    pack : ``scale`` (true scale, model units) or ``texture`` (UVs in [0,1]², one common scale).
    padding, resolution : gutter in pixels of a ``resolution``² texture (``texture``).
    texels_per_unit : ``texture``: pixels per model unit for every chart (None: the largest that fits).
    seed : seeds the farthest-point seeds and the pipeline.
    progress : a scan's main piece kept whole whatever its distortion shows its stages' lines as the pipeline's do
        (its minutes are the atlas's; the charts' many small runs stay quiet).
    pipeline_options : :class:`~heatparam.options.Options` fields for every chart's flattening.
    """
    t0 = time.perf_counter()
    V, F = as_arrays(V, F)
    if pack not in ("scale", "texture"):
        raise HeatparamError(f"pack must be 'scale' or 'texture', got {pack!r}")
    if max_distortion is not None and not max_distortion > 1.0:
        raise HeatparamError(f"max distortion must be > 1 (1 = isometry), got {max_distortion}")
    bound = DEFAULT_MAX_DISTORTION if max_distortion is None else float(max_distortion)
    opts = {"seed": seed, **pipeline_options}
    if opts.get("mds_start", "auto") == "auto":  # charts are small and clean: the heat stage never won a start on
        opts["mds_start"] = "never"  # them (the same atlases, 26-36% faster; docs/history.md §10)
    rep = repair(V, F)
    # a scan's main piece is one piece in pattern mode, as a disk is (parameterize); a texture bounds it
    main_bound = None if max_distortion is None and pack == "scale" else bound
    maker = _ChartMaker(flatten_disk, make_options(None, **opts), bound, whole_first=max_distortion is None,
                        max_charts=max_charts, seed=seed, main_bound=main_bound,
                        main_progress=progress and main_bound is None)
    components, tiny = maker.components(rep.components)
    debris = maker.debris_report(rep.components)
    t_flat = time.perf_counter() - t0
    placed, pinfo = pack_charts([c.uv for c in maker.charts], [c.Fl for c in maker.charts], pack, padding,
                                resolution, texels_per_unit=texels_per_unit)
    res = _assemble(maker.charts, placed, len(F))
    res.summary = metrics.summary(V, F, res.uv, res.Fuv)
    res.report = {"parameters": {"max_distortion": max_distortion, "bound_used": bound, "max_charts": max_charts,
                                 "pack": pinfo["mode"]},
                  **_report(V, F, res, charts=maker.charts, rep=rep, components=components, tiny=tiny, pinfo=pinfo,
                            debris=debris),
                  "warnings": _warnings(len(maker.charts), max_charts, rep, int(rep.degenerate.sum()), debris),
                  "seconds": {"charts": t_flat, "total": time.perf_counter() - t0}}
    return res


def atlas_result(V: np.ndarray, F: np.ndarray, opts: Options, *, why: str, flatten_disk: DiskFlattener,
                 prog=None) -> Result:
    """:func:`atlas` of (V, F) with the ``Options`` ``opts`` (their atlas fields and the pipeline's for each chart),
    as a ``pipeline.Result``: ``uv``, ``Fuv``, ``uv_vertex``, ``chart`` and a report with the same top-level keys as
    a single flattening's (``metrics`` over the whole atlas, ``method.atlas`` per chart and totals); ``why``: why
    the mesh became an atlas."""
    o = asdict(opts)
    pipeline_options = {k: v for k, v in o.items() if k not in ATLAS_FIELDS and k != "seed"}
    res = atlas(V, F, flatten_disk, max_distortion=opts.max_distortion or None, max_charts=opts.max_charts or None,
                pack=opts.pack, padding=opts.padding, resolution=opts.resolution,
                texels_per_unit=opts.texels_per_unit or None, seed=opts.seed, progress=opts.progress,
                **pipeline_options)
    summary = dict(res.summary)
    summary["stress_rel_rms"] = None
    t = res.report["totals"]
    summary.update(charts=t["charts"], overlapping_triangle_pairs=t["overlapping_triangle_pairs"],
                   uv_degenerate_faces=t["uv_degenerate_faces"], seam_length=t["seam_length"])
    # an atlas asked for (a bound, texture packing) is no news; one the mesh forced is, with what to do for one piece
    scan = "scan" in res.report["repair"]  # (its own warning says what was split off)
    made = [] if opts.max_distortion or opts.pack == "texture" or scan else [
        f"an atlas of {t['charts']} chart(s): the mesh is not one disk ({why}); the OBJ's vt rows split along the "
        "seams (for one piece, cut the mesh into a disk first)"]
    warnings = [*made, *res.report.get("warnings", [])]
    referenced = np.zeros(len(V), dtype=bool)
    referenced[F.ravel()] = True
    method = {"atlas": res.report, "why": why, "seams": {"mode": opts.seams, "used": True,
                                                         "reason": "charts of an atlas"}}
    mesh_facts = {"vertices": len(V), "faces": len(F), "unreferenced_vertices": int((~referenced).sum()),
                  "zero_area_faces": t["zero_area_faces"], "components": len(res.report["components"]),
                  "repair": res.report["repair"]}
    report = envelope(o, method, mesh_facts, summary, {"atlas": round(float(res.report["seconds"]["total"]), 4)},
                      warnings)
    if prog is not None:
        for w in report["warnings"]:
            prog.warn(w)
    return Result(res.uv, report, None, res.Fuv, res.uv_vertex, res.chart)


#: the seams stage's iso means (without and with seams: a cut tried) that a chart's report keeps where they are
_SEAM_ISO = ("iso_mean_without", "iso_mean_with")


class _ChartMaker:
    """The charts of a mesh's components (``charts``, in order), each part flattened whole or segmented.

    flatten_disk : the pipeline on one disk. opts : the Options of every chart's flattening. bound : the charts'
    distortion bound. whole_first : try each component whole first (no bound asked for). max_charts : the cap on
    each component's charts. seed : the segmentation's seeds. main_bound : the bound on a scan's main piece kept
    whole (None: any distortion). main_progress : the main piece's pipeline shows its stages (the map kept whatever
    its distortion, so its lines are those of the map written). After :meth:`components`, ``main`` is the scan's
    main piece kept whole (None when the mesh is no scan or its main piece was segmented) and ``debris`` the other
    components."""

    def __init__(self, flatten_disk: DiskFlattener, opts: Options, bound: float, *, whole_first: bool,
                 max_charts: int | None, seed: int, main_bound: float | None = None, main_progress: bool = False):
        self.flatten_disk, self.opts, self.bound = flatten_disk, opts, bound
        self.main_opts = replace(opts, progress=main_progress)
        self.whole_first, self.max_charts, self.seed, self.main_bound = whole_first, max_charts, seed, main_bound
        self.polish = None if opts.refine == "none" else RefineParams.from_options(opts)
        self.charts: list[Chart] = []
        self.main: int | None = None
        self.debris: list[int] = []

    def components(self, comps: list[Component]) -> tuple[list[dict], list[int]]:
        """Every component charted: (the report entry of each, the tiny components)."""
        reports: list[dict] = [{} for _ in comps]
        tiny = [ci for ci, c in enumerate(comps) if len(c.F) < TINY_COMPONENT_FACES]
        tried = self._scan(comps, reports) if self.whole_first else None
        if self.main is not None:
            return reports, tiny
        for ci, comp in enumerate(comps):
            if len(tiny) > 1 and ci in tiny:
                continue  # below, all together
            whole = self.whole(comp, ci, self.bound) if self.whole_first and ci != tried else None
            if whole is not None:
                self.charts.append(whole)
                reports[ci] = {"faces": int(len(comp.F)), "charts": 1, "segmented": False}
                continue
            made, stats = self.segmented(comp, ci, self.max_charts)
            reports[ci] = {"faces": int(len(comp.F)), "charts": made, "segmented": True, **stats}
        if len(tiny) > 1:
            self._together(comps, tiny, reports, "tiny_components")
        return reports, tiny

    def _scan(self, comps: list[Component], reports: list[dict]) -> int | None:
        """A scan's main piece (:func:`scan_main`) flattened whole, its debris charted together; sets ``main`` when
        the main piece was kept as one chart. Returns the main piece tried (None: no scan), whose whole map,
        refused, need not be tried again."""
        main = scan_main(comps)
        if main is None:
            return None
        whole = self.whole(comps[main], main, self.main_bound, self.main_opts)
        if whole is None:
            return main
        self.main, self.debris = main, [ci for ci in range(len(comps)) if ci != main]
        self.charts.append(whole)
        reports[main] = {"faces": int(len(comps[main].F)), "charts": 1, "segmented": False, "main_piece": True,
                         "pipeline": whole.info["pipeline"]}
        if self.debris:
            self._debris(comps, reports)
        return main

    def _debris(self, comps: list[Component], reports: list[dict]) -> None:
        """A scan's debris: each piece of at least ``TINY_COMPONENT_FACES`` faces one chart when its LSCM layout,
        polished with the others' in one system, is bijective and within the bound (what the pipeline, one run
        per piece, decided before); the rest segmented together."""
        # (mds_start='always' asks for the pipeline on every chart: the segmented path runs it)
        big = self.opts.mds_start != "always"
        whole = [ci for ci in self.debris if big and len(comps[ci].F) >= TINY_COMPONENT_FACES]
        rest = [ci for ci in self.debris if ci not in whole]
        if whole:
            part, owner = union([comps[ci] for ci in whole], whole)
            topo = Topology.build(part.V, part.F)
            piece = np.repeat(np.arange(len(whole)), [len(comps[ci].F) for ci in whole])
            seg = Segmentation(piece, topo.opp >= 0, {}, np.zeros((3 * len(part.F), 2)),
                               np.zeros(len(whole), dtype=bool))
            groups = [np.flatnonzero(piece == i) for i in range(len(whole))]
            limit = proxy_bound(self.bound) if self.polish is None else self.bound
            done, failed, _ = polish_charts(topo, groups, seg, limit=limit, params=self.polish)
            for p in done:
                self._add(part, owner, p.faces, Fl=p.Fl, vert=p.vert, uv=p.uv, info=p.info)
                ci = int(owner[p.faces[0]])
                reports[ci] = {"faces": int(len(comps[ci].F)), "charts": 1, "segmented": False}
            rest = sorted(rest + [whole[i] for i in failed])
        if rest:
            self._together(comps, rest, reports, "debris")

    def debris_report(self, comps: list[Component]) -> dict | None:
        """The report's ``repair.scan`` (None when no scan's main piece was kept whole): the main piece, and the
        debris (components, faces, share of the mesh's area, charts)."""
        if self.main is None:
            return None
        area = np.array([c.area for c in comps])
        charts = sum(c.component != self.main for c in self.charts)
        main_iso = next(c.info["iso_mean"] for c in self.charts if c.component == self.main)
        return {"main_component": self.main, "main_faces": int(len(comps[self.main].F)), "main_iso_mean": main_iso,
                "debris_components": len(self.debris), "debris_faces": int(sum(len(comps[ci].F) for ci in self.debris)),
                "debris_area_fraction": float(area[self.debris].sum() / area.sum()), "debris_charts": int(charts),
                "debris_area_share_max": DEBRIS_AREA_SHARE}

    def _together(self, comps: list[Component], ids: list[int], reports: list[dict], label: str) -> None:
        """The fins and crumbs of a scan (``label``: the tiny components, or a scan's debris) segmented and polished
        as one part (one solve, not one each)."""
        part, owner = union([comps[ci] for ci in ids], ids)
        start = len(self.charts)
        _, stats = self.segmented(part, owner, None)
        made = np.bincount([c.component for c in self.charts[start:]], minlength=len(comps))
        for ci in ids:
            reports[ci] = {"faces": int(len(comps[ci].F)), "charts": int(made[ci]), "segmented": True,
                           f"with_the_{label}": True}
        reports[ids[0]][f"{label}_together"] = {"components": len(ids), **stats}

    def whole(self, comp: Component, ci: int, bound: float | None, opts: Options | None = None) -> Chart | None:
        """A component that is a single disk (not nearly closed), flattened whole by the pipeline (which validates
        it), as one chart when its map is bijective and within ``bound`` (None: any distortion); None otherwise (it
        is segmented like any other). ``opts``: the pipeline's options (default the charts')."""
        try:
            res = self.flatten_disk(comp.V, comp.F, opts or self.opts)
        except HeatparamError:
            return None
        met = res.report["metrics"]
        Fuv = res.Fuv if res.Fuv is not None else comp.F
        kept = met["bijective"] and not met["flips"] and (bound is None or met["iso_mean"] <= bound)
        if not kept or folded_zero_area(comp.V, comp.F, res.uv, Fuv, comp.zero_area):
            return None
        seams = res.report["method"].get("seams", {})
        seams = {"used": seams.get("used"), "reason": seams.get("reason")} | {k: seams[k] for k in _SEAM_ISO
                                                                              if k in seams}
        return Chart(comp.faces, np.asarray(Fuv, dtype=np.int64), comp.vertex[res.uv_vertex], res.uv, ci,
                     {"iso_mean": float(met["iso_mean"]), "flips": int(met["flips"]), "bijective": True,
                      "method": "pipeline (whole part)",
                      "pipeline": {"timings_s": res.report.get("timings_s", {}),
                                   "seams": seams}})

    def segmented(self, comp: Component, ci: int | np.ndarray, max_charts: int | None) -> tuple[int, dict]:
        """Segment a component (``atlas.segment``), polish the charts together, flatten a chart that fails with the
        pipeline (:meth:`_one_by_one`). ``ci``: the component's id, or (m_c,) the id of each face (a union of
        components). Returns (charts made, the segmentation's stats)."""
        owner = ci if isinstance(ci, np.ndarray) else np.full(len(comp.F), ci, dtype=np.int64)
        topo = Topology.build(comp.V, comp.F)
        seg = segment(topo, self.bound, max_charts=max_charts, seed=self.seed)
        groups = [np.flatnonzero(seg.chart == c) for c in range(int(seg.chart.max()) + 1)]
        capped = seg.stats["capped"]
        # without the polish the charts keep their LSCM layouts: held to the segmentation's own (proxy) bound
        limit = None if capped else proxy_bound(self.bound) if self.polish is None else self.bound
        if self.opts.mds_start == "always":  # the paper's route asked for: every chart through the pipeline
            done, rest = [], list(range(len(groups)))
            seg.stats["joint_polish"] = {"used": False, "reason": "mds_start='always': each chart through the pipeline"}
        else:
            done, rest, seg.stats["joint_polish"] = polish_charts(topo, groups, seg, limit=limit, params=self.polish)
        start = len(self.charts)
        for p in done:
            self._add(comp, owner, p.faces, Fl=p.Fl, vert=p.vert, uv=p.uv, info=p.info)
        self._one_by_one(topo, comp, owner, [(groups[i], seg.glued) for i in rest], None if capped else self.bound)
        return len(self.charts) - start, seg.stats

    def _one_by_one(self, topo: Topology, comp: Component, owner: np.ndarray, todo: list, bound: float | None
                    ) -> None:
        """The charts ``todo`` ((faces, glued) each) flattened by the pipeline one at a time; a chart that is not
        bijective or exceeds ``bound`` is split in two (the paper's future-work rule) down to single faces."""
        while todo:
            faces, glued = todo.pop()
            Vl, Fl, vert = chart_mesh(topo, faces, glued)
            uv, info = self._flatten(Vl, Fl)
            if not _chart_ok(info, bound) and len(faces) > 1:
                pieces = halves(topo, faces, glued, self.seed)
                if pieces:
                    todo.extend(pieces)
                    continue
                quick, qiso, qbij = quick_flatten(Vl, Fl)
                bijective = uv is not None and info.get("bijective") and not info.get("flips")
                if qbij and not bijective:
                    uv, info = quick, {"iso_mean": qiso, "flips": 0, "bijective": True, "method": "lscm"}
                elif not bijective:  # last resort: one chart per face, each laid out exactly
                    todo.extend((faces[i:i + 1], np.zeros_like(glued)) for i in range(len(faces)))
                    continue
            if uv is None:
                raise HeatparamError(f"a chart of {len(faces)} face(s) could not be flattened: "
                                     f"{info.get('error', 'no valid layout')} — repair the mesh there (remove "
                                     "sliver or duplicate faces) and try again")
            self._add(comp, owner, faces, Fl=Fl, vert=vert, uv=uv, info=info)

    def _flatten(self, Vl: np.ndarray, Fl: np.ndarray) -> tuple[np.ndarray | None, dict]:
        """The pipeline's map of one disk chart, or (None, {"error": why}) when it fails. A chart of zero-area faces
        only (one that no neighbour took in: a tiny component of them) is laid out as the segment it is."""
        if degenerate_faces(Vl, Fl).all():
            uv = segment_layout(Vl, Fl)
            if uv is None:
                return None, {"error": "its zero-area faces do not lie on one line"}
            return uv, {"iso_mean": 1.0, "flips": 0, "bijective": True, "boundary_crossings": 0,
                        "method": "segment (zero-area faces)"}
        if len(Fl) < 2:  # (LSCM has no finite layout for a sliver)
            return triangle_layout(Vl, Fl), {"iso_mean": 1.0, "flips": 0, "bijective": True,
                                              "boundary_crossings": 0, "method": "exact triangle"}
        try:
            res = self.flatten_disk(Vl, Fl, self.opts)
        except HeatparamError as exc:
            return None, {"error": str(exc)}
        met = res.report["metrics"]
        if res.Fuv is not None and not np.array_equal(res.Fuv, Fl):
            return None, {"error": "the pipeline cut the chart"}
        flips = int(met["flips"]) + folded_zero_area(Vl, Fl, res.uv)  # (the metrics leave zero-area faces out)
        return res.uv, {"iso_mean": float(met["iso_mean"]), "flips": flips,
                        "boundary_crossings": int(met.get("boundary_crossings", 0)),
                        "bijective": bool(met["bijective"]), "method": "pipeline"}

    def _add(self, comp: Component, owner: np.ndarray, faces: np.ndarray, *, Fl: np.ndarray, vert: np.ndarray,
             uv: np.ndarray, info: dict) -> None:
        """A chart of ``comp`` (its ``faces``, ``vert`` in component rows) in input rows."""
        self.charts.append(Chart(comp.faces[faces], Fl, comp.vertex[vert], uv, int(owner[faces[0]]), info))


def scan_main(comps: list[Component]) -> int | None:
    """The main piece of a scan: the component of largest area when every other component is debris, under
    ``DEBRIS_AREA_SHARE`` of its area (islands, fins cut off at bowties, crumbs); None when the mesh has two or
    more comparable parts (each is then charted within the bound). An area share, not a face count: a scan's
    density says nothing of what is a part; its area does."""
    areas = np.array([c.area for c in comps])
    main = int(np.argmax(areas))
    return main if (np.delete(areas, main) < DEBRIS_AREA_SHARE * areas[main]).all() else None


def _chart_ok(info: dict, bound: float | None) -> bool:
    if "error" in info or not info["bijective"] or info["flips"]:
        return False
    return bound is None or info["iso_mean"] <= bound


def _assemble(charts: list[Chart], placed: list[np.ndarray], m: int) -> AtlasResult:
    """The packed charts as one map of the m input faces (report to come)."""
    Fuv = np.full((m, 3), -1, dtype=np.int64)
    chart_of = np.full(m, -1, dtype=np.int64)
    off = 0
    for i, c in enumerate(charts):
        Fuv[c.faces] = c.Fl + off
        chart_of[c.faces] = i
        off += len(placed[i])
    uv_vertex = np.concatenate([c.vert for c in charts]).astype(np.int64)
    return AtlasResult(np.concatenate(placed), Fuv, uv_vertex, chart_of)


def _report(V: np.ndarray, F: np.ndarray, res: AtlasResult, *, charts: list[Chart], rep: Repair,
            components: list[dict], tiny: list[int], pinfo: dict, debris: dict | None) -> dict:
    """The atlas's report: repair (with ``scan``: a scan's main piece and debris), components, per chart and
    totals, packing."""
    A3 = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    opp = rep.opp
    cut = cut_half_edges(F, res.Fuv, opp)  # per chart seam length: its border edges that are not mesh border
    seams = chart_seam_lengths(V, F, cut, res.chart, len(charts))
    per = [{"chart": i, "component": c.component, "faces": int(len(c.faces)), "area": float(A3[c.faces].sum()),
            "iso_mean": float(c.info.get("iso_mean", float("nan"))), "flips": int(c.info["flips"]),
            "method": c.info.get("method"), "seam_length": float(seams[i])} for i, c in enumerate(charts)]
    d = res.summary
    L = seam_length(V, F, res.Fuv, opp, cut)
    area = float(A3.sum())
    totals = {
        "charts": len(charts),
        "seam_length": L,
        "seam_length_over_sqrt_area": L / np.sqrt(area) if area > 0 else float("nan"),
        "iso_mean": d["iso_mean"],
        "iso_p95": d["iso_p95"],
        "flips": d["flips"],
        "overlapping_triangle_pairs": exact_overlap_count(res.uv, res.Fuv),
        "uv_degenerate_faces": int(uv_degenerate_faces(res.uv, res.Fuv).sum()),
        "zero_area_faces": int(rep.degenerate.sum()),
        "packing_efficiency": pinfo["efficiency"],
        "area": area,
        "uv_scale": pinfo["scale"],
    }
    return {"repair": {**rep.report(), **({"scan": debris} if debris else {})},
            "tiny_components": [{"component": i, "faces": int(len(rep.components[i].F))} for i in tiny],
            "components": components, "charts": per, "totals": totals, "pack": pinfo}


def _warnings(charts: int, max_charts: int | None, rep: Repair, zero_area: int, debris: dict | None
              ) -> list[str]:
    return (([f"{charts} charts exceed --max-charts {max_charts}"] if max_charts is not None and charts > max_charts
             else [])
            + ([_scan_warning(debris, rep.split_vertices)] if debris else [])
            + ([f"{len(rep.loose_points)} unreferenced vertices kept without UV"] if len(rep.loose_points) else [])
            + ([f"{zero_area} zero-area faces laid out with the charts around them (intrinsic mollification of edge "
                "lengths), or as segments where they are alone"] if zero_area else []))


def _scan_warning(debris: dict, split: int) -> str:
    """What a scan's repair split off its main piece (kept as one chart), in one line."""
    parts = [f"{split} non-manifold vertices split (one UV row per fan)"] if split else []
    if debris["debris_components"]:
        parts.append(f"{debris['debris_components']} detached small piece(s) ({debris['debris_faces']} faces, "
                     f"{debris['debris_area_fraction']:.2%} of the area, each under "
                     f"{DEBRIS_AREA_SHARE:.0%} of the main piece's) charted apart in {debris['debris_charts']} "
                     "chart(s) (remove them in the scan software for a single chart)")
    line = "a scan: its main piece is one chart; " + ("; ".join(parts) or "nothing split off")
    if debris["main_iso_mean"] > DEFAULT_MAX_DISTORTION:  # as a one-piece disk map says (pipeline.parameterize)
        line += "; " + stretch_note("the main piece's map", debris["main_iso_mean"])
    return line


def stretch_note(subject: str, iso_mean: float, iso_p95: float | None = None) -> str:
    """The note on a one-piece map stretched past ``DEFAULT_MAX_DISTORTION``: how much, and the option that cuts it
    into pieces within the bound (a disk's map, a scan's main piece)."""
    p95 = "" if iso_p95 is None else f", p95 {iso_p95:.3f}"
    return (f"{subject} stretches the surface: isometric distortion mean {iso_mean:.3f}{p95} (1 = none); "
            f"max_distortion={DEFAULT_MAX_DISTORTION} cuts it into pieces within {DEFAULT_MAX_DISTORTION}")
