"""Atlases of any mesh: repair, segmentation into disk charts, each chart flattened by the pipeline, packing.

``atlas(V, F)`` accepts what :func:`heatparam.parameterize` refuses (closed surfaces, handles, nearly closed
scans, several components, non-manifold vertices and edges) and returns one UV row per chart corner: the input's
vertices and faces are unchanged, row for row; face f's corners map to ``uv[Fuv[f]]``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from heatparam.atlas.overlap import count_overlaps, uv_degenerate_faces
from heatparam.atlas.pack import pack_charts
from heatparam.atlas.repair import repair
from heatparam.atlas.segment import (
    Segmentation,
    Topology,
    chart_iso,
    chart_mesh,
    flatten_charts,
    grow,
    proxy_bound,
    quick_flatten,
    segment,
)
from heatparam.errors import HeatparamError
from heatparam.mesh.topology import unique_inverse

__all__ = ["ATLAS_FIELDS", "AtlasResult", "DEFAULT_MAX_DISTORTION", "TINY_COMPONENT_FACES", "atlas", "atlas_result"]

#: isometric distortion bound per chart (area-weighted mean of max(s1, 1/s2)); measured in BENCHMARKS.md
DEFAULT_MAX_DISTORTION = 1.05
#: components with fewer faces are reported as tiny (they still get charts)
TINY_COMPONENT_FACES = 20


@dataclass
class AtlasResult:
    """uv (k,2) float64; Fuv (m,3) int64 rows of uv per face corner (F row for row); uv_vertex (k,) int64 input
    vertex of each uv row; chart (m,) int64 chart of each face; report dict (per chart and totals)."""

    uv: np.ndarray
    Fuv: np.ndarray
    uv_vertex: np.ndarray
    chart: np.ndarray
    report: dict = field(default_factory=dict)


def _flatten_chart(Vl, Fl, opts) -> tuple[np.ndarray | None, dict]:
    """The pipeline's map of one disk chart, or (None, reason) when it fails."""
    from heatparam.pipeline import parameterize_disk as parameterize

    if len(Fl) < 2:
        uv, iso, bij = quick_flatten(Vl, Fl)
        return uv, {"iso_mean": iso, "flips": 0 if bij else 1, "bijective": bij, "boundary_crossings": 0,
                    "method": "exact triangle"}
    try:
        res = parameterize(Vl, Fl, **opts)
    except HeatparamError as exc:
        return None, {"error": str(exc)}
    met = res.report["metrics"]
    uv = res.uv
    if res.Fuv is not None and not np.array_equal(res.Fuv, Fl):
        return None, {"error": "the pipeline cut the chart"}
    return uv, {"iso_mean": float(met["iso_mean"]), "flips": int(met["flips"]),
                "boundary_crossings": int(met.get("boundary_crossings", 0)), "bijective": bool(met["bijective"]),
                "method": "pipeline"}


def _chart_ok(info: dict, bound: float | None) -> bool:
    if "error" in info or not info["bijective"] or info["flips"]:
        return False
    return bound is None or info["iso_mean"] <= bound


def atlas(V: np.ndarray, F: np.ndarray, *, max_distortion: float | None = None, max_charts: int | None = None,
          pack: str = "scale", padding: float = 4.0, resolution: int = 1024, seed: int = 0,
          **pipeline_options) -> AtlasResult:
    """A bijective, near-isometric atlas of any triangle mesh.

    Parameters
    ----------
    V : (n,3) float64. F : (m,3) int64.
    max_distortion : per-chart bound on the isometric distortion (area-weighted mean of max(s1, 1/s2)).
        None (default): charts are segmented and merged to ``DEFAULT_MAX_DISTORTION`` (1.05), and an open part
        that ``parameterize`` accepts (a disk, possibly with holes, not nearly closed) stays one piece when its
        map is bijective, whatever its distortion. A number: every part is segmented to that bound.
    max_charts : a cap on the charts of each component: when the bound leaves more, merging goes on past the
        bound (each merged chart still bijective) down to this count where bijective merges exist; a warning
        says when the atlas still has more.
    pack : ``scale`` (true scale, model units) or ``texture`` (UVs in [0,1]², one common scale).
    padding, resolution : gutter in pixels of a ``resolution``² texture (``texture``).
    seed : seeds the farthest-point seeds and the pipeline.
    pipeline_options : passed to :func:`heatparam.parameterize` for every chart.

    Returns
    -------
    :class:`AtlasResult`.
    """
    t0 = time.perf_counter()
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if pack not in ("scale", "texture"):
        raise HeatparamError(f"pack must be 'scale' or 'texture', got {pack!r}")
    if max_distortion is not None and not max_distortion > 1.0:
        raise HeatparamError(f"max distortion must be > 1 (1 = isometry), got {max_distortion}")
    bound = DEFAULT_MAX_DISTORTION if max_distortion is None else float(max_distortion)
    opts = {"seed": seed, **pipeline_options}
    if opts.get("mds_start", "auto") == "auto":  # charts are small and clean: the heat stage never won a start on
        opts["mds_start"] = "never"  # them (measured on cow and 3holes: the same atlases, 26-36% faster; §10)
    rep = repair(V, F)
    charts: list[dict] = []  # each: faces (input rows), Fl, vert (input vertex per local row), uv, info
    comp_reports: list[dict] = [{} for _ in rep.components]
    tiny = [ci for ci, c in enumerate(rep.components) if len(c.F) < TINY_COMPONENT_FACES]
    for ci, comp in enumerate(rep.components):
        if len(tiny) > 1 and ci in tiny:
            continue  # below, all together
        whole = _whole_part(comp, ci, opts) if max_distortion is None else None
        if whole is not None:
            charts.append(whole)
            comp_reports[ci] = {"faces": int(len(comp.F)), "charts": 1, "segmented": False}
            continue
        made, stats = _segmented_part(comp, ci, bound, max_charts, seed, opts, charts)
        comp_reports[ci] = {"faces": int(len(comp.F)), "charts": made, "segmented": True, **stats}
    if len(tiny) > 1:  # the fins and crumbs of a scan: segmented and polished as one part (one solve, not one each)
        union, owner = _union([rep.components[ci] for ci in tiny], tiny)
        start = len(charts)
        _, stats = _segmented_part(union, owner, bound, None, seed, opts, charts)
        made = np.bincount([c["component"] for c in charts[start:]], minlength=len(rep.components))
        for ci in tiny:
            comp_reports[ci] = {"faces": int(len(rep.components[ci].F)), "charts": int(made[ci]), "segmented": True,
                                "with_the_tiny_components": True}
        comp_reports[tiny[0]]["tiny_components_together"] = {"components": len(tiny), **stats}
    t_flat = time.perf_counter() - t0
    placed, pinfo = pack_charts([c["uv"] for c in charts], [c["Fl"] for c in charts], pack, padding, resolution)
    m = len(F)
    Fuv = np.full((m, 3), -1, dtype=np.int64)
    chart_of = np.full(m, -1, dtype=np.int64)
    uvs, verts = [], []
    off = 0
    for i, c in enumerate(charts):
        Fuv[c["faces"]] = c["Fl"] + off
        chart_of[c["faces"]] = i
        uvs.append(placed[i])
        verts.append(c["vert"])
        off += len(placed[i])
    uv = np.concatenate(uvs)
    uv_vertex = np.concatenate(verts).astype(np.int64)
    report = _report(V, F, uv, Fuv, uv_vertex, chart_of, charts, rep, comp_reports, tiny, pinfo, bound,
                     max_distortion, max_charts)
    report["seconds"] = {"charts": t_flat, "total": time.perf_counter() - t0}
    return AtlasResult(uv=uv, Fuv=Fuv, uv_vertex=uv_vertex, chart=chart_of, report=report)


def _whole_part(comp, ci: int, opts: dict) -> dict | None:
    """A component that is a single disk (not nearly closed), flattened whole by the pipeline, as one chart when
    its map is bijective; None otherwise (it is segmented)."""
    from heatparam.mesh import validate_mesh
    from heatparam.pipeline import parameterize_disk

    try:
        validate_mesh(comp.V, comp.F, flatten=True)
        res = parameterize_disk(comp.V, comp.F, **opts)
    except HeatparamError:
        return None
    met = res.report["metrics"]
    if not (met["bijective"] and not met["flips"]):
        return None
    Fuv = res.Fuv if res.Fuv is not None else comp.F
    return {"faces": comp.faces, "Fl": np.asarray(Fuv, dtype=np.int64), "vert": comp.vertex[res.uv_vertex],
            "uv": res.uv, "component": ci, "info": {"iso_mean": float(met["iso_mean"]), "flips": int(met["flips"]),
                                                   "bijective": True, "method": "pipeline (whole part)"}}


def _union(parts: list, ids: list[int]):
    """Several components as one (a :class:`repair.Component` of their disjoint union) and the component id of
    each of its faces."""
    from heatparam.atlas.repair import Component

    offs = np.cumsum([0] + [len(c.V) for c in parts])
    F = np.vstack([c.F + o for c, o in zip(parts, offs[:-1], strict=True)])
    comp = Component(np.vstack([c.V for c in parts]), F, np.concatenate([c.faces for c in parts]),
                     np.concatenate([c.vertex for c in parts]))
    return comp, np.repeat(np.asarray(ids, dtype=np.int64), [len(c.F) for c in parts])


def _segmented_part(comp, ci, bound: float, max_charts: int | None, seed: int, opts: dict,
                    charts: list[dict]) -> tuple[int, dict]:
    """Segment a component (``segment.segment``), polish the charts together, flatten a chart that fails with the
    pipeline, split a chart that is still not bijective or exceeds the bound in two (the paper's future-work rule)
    down to single faces; the charts are appended to ``charts``. ``ci``: the component's id, or (m_c,) the id of
    each face (a union of components: :func:`_union`). Returns (charts made, the segmentation's stats)."""
    owner = ci if isinstance(ci, np.ndarray) else np.full(len(comp.F), ci, dtype=np.int64)
    topo = Topology.build(comp.V, comp.F)
    seg = segment(topo, bound, max_charts=max_charts, seed=seed)
    groups = [np.flatnonzero(seg.chart == c) for c in range(int(seg.chart.max()) + 1)]
    # without the polish the charts keep their LSCM layouts: held to the segmentation's own (proxy) bound
    limit = None if seg.stats["capped"] else proxy_bound(bound) if opts.get("refine") == "none" else bound
    if opts.get("mds_start") == "always":  # the paper's route asked for: every chart through the pipeline
        done, rest = [], list(range(len(groups)))
        seg.stats["joint_polish"] = {"used": False, "reason": "mds_start='always': each chart through the pipeline"}
    else:
        done, rest, seg.stats["joint_polish"] = _polish_together(topo, groups, seg, opts, limit)
    for faces, Fl, vert, uv, info in done:
        charts.append({"faces": comp.faces[faces], "Fl": Fl, "vert": comp.vertex[vert], "uv": uv,
                       "component": int(owner[faces[0]]), "info": info})
    made = len(done)
    todo = [(groups[i], seg.glued) for i in rest]
    while todo:
        faces, glued = todo.pop()
        Vl, Fl, vert = chart_mesh(topo, faces, glued)
        uv, info = _flatten_chart(Vl, Fl, opts)
        if not _chart_ok(info, None if seg.stats["capped"] else bound) and len(faces) > 1:
            halves = _halves(topo, faces, glued, seed)
            if halves:
                todo.extend(halves)
                continue
            quick, qiso, qbij = quick_flatten(Vl, Fl)
            bijective = uv is not None and info.get("bijective") and not info.get("flips")
            if qbij and not bijective:
                uv, info = quick, {"iso_mean": qiso, "flips": 0, "bijective": True, "method": "lscm"}
            elif not bijective:  # last resort: one chart per face, each laid out exactly
                todo.extend((faces[i:i + 1], np.zeros_like(glued)) for i in range(len(faces)))
                continue
        if uv is None:
            raise HeatparamError(f"a chart of {len(faces)} faces could not be flattened: {info.get('error')}")
        charts.append({"faces": comp.faces[faces], "Fl": Fl, "vert": comp.vertex[vert], "uv": uv,
                       "component": int(owner[faces[0]]), "info": info})
        made += 1
    return made, seg.stats


def _polish_together(topo, groups: list[np.ndarray], seg: Segmentation, opts: dict, limit: float | None):
    """Every chart polished together (``refine.charts``) from its bijective layout: the one the segmentation checked
    (``seg.corner_uv``), else its quick flattening (LSCM) where that is bijective: (the charts done as (faces, Fl,
    vert, uv, info) tuples, the indices of the others — no bijective layout —, the polish's report).

    Until 2026-12-04 every chart was laid out by LSCM too and started from the less distorted of the two (about
    half chose each); starting from the checked layout alone gave the same Newton iterations and iso means within
    2e-4 (cow 1.03143 → 1.03137, 3holes 1.02141 → 1.02143, the bunny 1.01825 → 1.01843; BENCHMARKS §23a) without
    cow's 20 ms of LSCM."""
    from heatparam.refine.charts import refine_charts

    fl = flatten_charts(topo, groups, seg.glued, want=~seg.checked)
    ok = fl.ok(np.inf)
    for i in np.flatnonzero(seg.checked & fl.disk):  # never a chart with a hole
        rows = fl.Fl[fl.face_start[i]:fl.face_start[i + 1]].ravel()
        fl.uv[rows] = seg.corner_uv[(3 * groups[i][:, None] + np.arange(3)).ravel()]
        ok[i] = True
    good = np.flatnonzero(ok)
    if not len(good):
        return [], list(range(len(groups))), {"charts": 0}
    new = np.full(len(groups), -1, dtype=np.int64)
    new[good] = np.arange(len(good))
    fgroup = np.repeat(np.arange(len(groups)), np.diff(fl.face_start))
    rows = np.flatnonzero(new[fl.vgroup] >= 0)
    loc = np.full(len(fl.Vl), -1, dtype=np.int64)
    loc[rows] = np.arange(len(rows))
    Fs = loc[fl.Fl[new[fgroup] >= 0]]
    vg = new[fl.vgroup[rows]]
    x = fl.uv[rows]
    if opts.get("refine", "sd") == "none":
        rep = {"charts": len(good), "used": False, "reason": "refine none: the LSCM layouts are kept"}
    else:
        x, rep = refine_charts(fl.Vl[rows], Fs, x, vg, len(good), max_iters=int(opts.get("refine_iters", 200)),
                               tol=float(opts.get("refine_tol", 1e-6)), backend=opts.get("solver", "auto"))
    iso, flips = chart_iso(fl.Vl[rows], Fs, x, vg[Fs[:, 0]], len(good))
    crossing = rep.get("boundary_crossings", 0) > 0  # the scaffold rules it out; checked, not assumed
    polished = fl.uv.copy()
    polished[rows] = x
    done, rest = [], [i for i in range(len(groups)) if new[i] < 0]
    for j, i in enumerate(good):
        if crossing or flips[j] or (limit is not None and iso[j] > limit):
            rest.append(int(i))
            continue
        _, Fl, vert, uv = fl.chart(i, polished)
        info = {"iso_mean": float(iso[j]), "flips": 0, "bijective": True, "boundary_crossings": 0,
                "method": "lscm + joint polish"}
        done.append((groups[i], Fl, vert, uv, info))
    rep = {k: rep[k] for k in ("charts", "iterations", "converged", "stop", "energy_start", "energy_end", "seconds",
                               "used", "reason") if k in rep}
    return done, sorted(rest), rep


def _halves(topo, faces: np.ndarray, glued: np.ndarray, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The chart ``faces`` grown again from two far seeds into two halves, each welded inside; [] when it will not
    split."""
    parts = grow(topo, faces, 179.0, max(1, (len(faces) + 1) // 2), seed)  # two halves
    if len(parts) < 2:
        return []
    out = []
    for p in parts:
        g = np.zeros_like(glued)
        h = (3 * p[:, None] + np.arange(3)).ravel()
        inside = np.zeros(len(topo.F), dtype=bool)
        inside[p] = True
        o = topo.opp[h]
        ok = o >= 0
        ok[ok] = inside[o[ok] // 3]
        g[h[ok]] = True  # a fresh half: welded inside
        out.append((p, g))
    return out


def seam_length(V: np.ndarray, F: np.ndarray, Fuv: np.ndarray, opp: np.ndarray | None = None,
                cut: np.ndarray | None = None) -> float:
    """Length of the interior mesh edges whose two sides have different UV rows (each edge once). opp (3m,): F's
    ``repair.half_edge_opposites`` and cut (3m,): ``_cut_half_edges``, when the caller has them."""
    from heatparam.atlas.repair import half_edge_opposites

    opp = half_edge_opposites(F) if opp is None else opp
    cut = _cut_half_edges(F, Fuv, opp) if cut is None else cut
    h = np.flatnonzero(cut & (opp > np.arange(len(opp))))
    fa, ja = h // 3, h % 3
    a, b = F[fa, ja], F[fa, (ja + 1) % 3]
    # edges of 3+ faces (or of inconsistent orientation) are cut by the repair: count them too
    a_all, b_all = F.ravel(), F[:, [1, 2, 0]].ravel()
    n = len(V)
    key = np.minimum(a_all, b_all) * n + np.maximum(a_all, b_all)
    _, first, inv = unique_inverse(key)
    # the edges of 2+ half-edges none of which is welded (manifold, oriented)
    multi = first[(np.bincount(inv) >= 2) & (np.bincount(inv, weights=opp >= 0) == 0)]
    L = float(np.linalg.norm(V[b] - V[a], axis=1).sum())
    L += float(np.linalg.norm(V[b_all[multi]] - V[a_all[multi]], axis=1).sum())
    return L


def _cut_half_edges(F: np.ndarray, Fuv: np.ndarray, opp: np.ndarray) -> np.ndarray:
    """(3m,) bool: half-edge ``3 f + j`` has an opposite (``repair.half_edge_opposites``) and the two sides of their
    edge use different UV rows (a seam of the atlas)."""
    h = np.flatnonzero(opp >= 0)
    o = opp[h]
    fa, ja, fb, jb = h // 3, h % 3, o // 3, o % 3
    cut = np.zeros(len(opp), dtype=bool)
    cut[h] = ~((Fuv[fa, ja] == Fuv[fb, (jb + 1) % 3]) & (Fuv[fa, (ja + 1) % 3] == Fuv[fb, jb]))
    return cut


def _report(V, F, uv, Fuv, uv_vertex, chart_of, charts, rep, comp_reports, tiny, pinfo, bound, max_distortion,
            max_charts) -> dict:
    from heatparam.atlas.repair import half_edge_opposites
    from heatparam.metrics import distortion

    A3 = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    per = []
    for i, c in enumerate(charts):
        f = c["faces"]
        per.append({"chart": i, "component": c["component"], "faces": int(len(f)), "area": float(A3[f].sum()),
                    "iso_mean": float(c["info"].get("iso_mean", float("nan"))), "flips": int(c["info"]["flips"]),
                    "method": c["info"].get("method"), "seam_length": 0.0})
    # per chart seam length: its border edges that are not mesh border (computed on the whole atlas)
    opp = half_edge_opposites(F)
    cut = _cut_half_edges(F, Fuv, opp)
    _per_chart_seams(V, F, cut, chart_of, per)
    scale = pinfo["scale"]
    d = distortion(V, F, uv, Fuv)
    L = seam_length(V, F, Fuv, opp, cut)
    area = float(A3.sum())
    totals = {
        "charts": len(charts),
        "seam_length": L,
        "seam_length_over_sqrt_area": L / np.sqrt(area) if area > 0 else float("nan"),
        "iso_mean": d["iso_mean"],
        "iso_p95": d["iso_p95"],
        "flips": d["flips"],
        "overlapping_triangle_pairs": count_overlaps(uv, Fuv),
        "uv_degenerate_faces": int(uv_degenerate_faces(uv, Fuv).sum()),
        "packing_efficiency": pinfo["efficiency"],
        "area": area,
        "uv_scale": scale,
    }
    return {
        "parameters": {"max_distortion": max_distortion, "bound_used": bound, "max_charts": max_charts,
                       "pack": pinfo["mode"]},
        "repair": rep.report(),
        "tiny_components": [{"component": i, "faces": int(len(rep.components[i].F))} for i in tiny],
        "components": comp_reports,
        "charts": per,
        "totals": totals,
        "pack": pinfo,
        "warnings": ([f"{len(charts)} charts exceed --max-charts {max_charts}"]
                     if max_charts is not None and len(charts) > max_charts else [])
        + ([f"{len(rep.loose_points)} unreferenced vertices kept without UV"] if len(rep.loose_points) else []),
    }


def _per_chart_seams(V, F, cut, chart_of, per) -> None:
    h = np.arange(3 * len(F))
    fa, ja = h // 3, h % 3
    L = np.linalg.norm(V[F[fa, (ja + 1) % 3]] - V[F[fa, ja]], axis=1) * cut
    s = np.bincount(chart_of[fa], weights=L, minlength=len(per))
    for i, p in enumerate(per):
        p["seam_length"] = float(s[i])


#: the Options fields that are the atlas's own (not passed to the per-chart pipeline)
ATLAS_FIELDS = ("max_distortion", "max_charts", "pack", "padding", "resolution", "progress")


def atlas_result(V: np.ndarray, F: np.ndarray, opts, why: str, prog=None):
    """:func:`atlas` of (V, F) with the ``Options`` ``opts`` (their atlas fields and the pipeline's for each chart),
    as a ``pipeline.Result``: ``uv``, ``Fuv``, ``uv_vertex``, ``chart`` and a report with the same top-level keys as
    a single flattening's (``metrics`` over the whole atlas, ``method.atlas`` per chart and totals)."""
    from dataclasses import asdict

    from heatparam import metrics
    from heatparam.pipeline.report import Result, envelope

    o = asdict(opts)
    pipeline_options = {k: v for k, v in o.items() if k not in ATLAS_FIELDS and k != "seed"}
    res = atlas(V, F, max_distortion=opts.max_distortion or None, max_charts=opts.max_charts or None,
                pack=opts.pack, padding=opts.padding, resolution=opts.resolution, seed=opts.seed,
                **pipeline_options)
    summary = metrics.summary(V, F, res.uv, res.Fuv)
    summary["stress_rel_rms"] = None
    t = res.report["totals"]
    summary.update(charts=t["charts"], overlapping_triangle_pairs=t["overlapping_triangle_pairs"],
                   uv_degenerate_faces=t["uv_degenerate_faces"], seam_length=t["seam_length"])
    warnings = [f"an atlas of {t['charts']} chart(s) ({why}); the OBJ's vt rows split along the seams",
                *res.report.get("warnings", [])]
    referenced = np.zeros(len(V), dtype=bool)
    referenced[F.ravel()] = True
    method = {"atlas": res.report, "why": why, "seams": {"mode": opts.seams, "used": True,
                                                         "reason": "charts of an atlas"}}
    mesh_facts = {"vertices": len(V), "faces": len(F), "unreferenced_vertices": int((~referenced).sum()),
                  "components": len(res.report["components"]), "repair": res.report["repair"]}
    report = envelope(o, method, mesh_facts, summary, {"atlas": round(float(res.report["seconds"]["total"]), 4)},
                      warnings)
    if prog is not None:
        for w in report["warnings"]:
            prog.warn(w)
    return Result(res.uv, report, None, res.Fuv, res.uv_vertex, res.chart)
