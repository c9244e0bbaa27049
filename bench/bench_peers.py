"""heatparam vs libigl peers (LSCM, ARAP, SLIM) on the disk-like test meshes: a markdown table on stdout.

Usage: ``python bench/bench_peers.py [name ...]`` (names of ../shared/meshes files or generated datasets).
Columns: flips, boundary crossings, iso mean/p95, conformal mean, area mean (``metrics.summary``; these are
scale-normalized), SD = true-scale symmetric Dirichlet energy per area / 4 (1 = isometry; the energy SLIM and our
polish minimize; "–" where a face is flipped), true-scale layout error (``metrics.layout_error``, only where
``uv_true`` is known; maps that are not at true scale are first scaled by ``uv_scale`` and marked ``*``), seconds
(wall), notes (our start layout and polish iterations, seams). On meshes with holes the default (``seams auto``) is
also run with ``--seams none`` (one uncut piece). After each table: the best flip-free and the best bijective
peer, and SLIM's time over ours.
"""

from __future__ import annotations

import sys
import time

import igl
import numpy as np
from common import load

from heatparam import metrics, pipeline
from heatparam.refine import energy

MESHES = ["camelhead.off", "halftunnel.off", "beetle.off", "woody.obj", "bump-domain.obj"]
SHAPES = ["cylinder_patch", "cylinder_with_holes", "cone_s_strip", "curved_cap_with_holes"]


def _outer(F):
    loops = metrics.boundary_loops(F)
    return loops[int(np.argmax([len(lp) for lp in loops]))]


def lscm(V, F):
    b = _outer(F)
    fixed = np.array([b[0], b[len(b) // 2]])
    uv, _ = igl.lscm(V, F, fixed, np.array([[0.0, 0.0], [1.0, 0.0]]))
    return uv


def tutte(V, F):
    b = _outer(F)
    bc = igl.map_vertices_to_circle(V, b.astype(np.int32))
    return igl.harmonic(V, F, b, bc, 1)


def arap(V, F, uv0, iters=100):
    data = igl.ARAPData()
    data.max_iter = iters
    b = np.zeros(1, np.int32)  # one pinned vertex (translation); with none the precomputation fails on some meshes
    igl.arap_precomputation(V, F, 2, b, data)
    return igl.arap_solve(np.ascontiguousarray(uv0[b]), data, np.ascontiguousarray(uv0))


def slim(V, F, uv0, iters=100):
    data = igl.slim_precompute(V, F.astype(np.int32), uv0, igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                               np.zeros(0, np.int32), np.zeros((0, 2)))
    return np.asarray(igl.slim_solve(data, iters))[:, :2]


def sd_energy(V, F, uv, Fuv=None) -> float:
    """Σ A_f (|J|² + |J⁻¹|²) / (4 Σ A_f) at true scale; nan if any face is flipped. Fuv: uv rows per corner."""
    g, area = energy.surface_gradients(V, F)
    J = energy.jacobians(uv, F if Fuv is None else Fuv, g)
    if (energy.det(J) <= 0).any():
        return float("nan")
    return energy.symmetric_dirichlet(J, area / area.sum())[0] / 4


def row(method, V, F, uv, seconds, uv_true, true_scale, notes="", result=None):
    """One table row; ``result``: a pipeline Result, whose map may have seams (uv rows per seam side)."""
    Fuv, uv_vertex = (None, np.arange(len(uv))) if result is None else (result.Fuv, result.uv_vertex)
    s = metrics.summary(V, F, uv, Fuv)
    if uv_true is not None:
        mark = "" if true_scale else "*"
        le = f"{metrics.layout_error(uv * (1.0 if true_scale else s['uv_scale']), uv_true[uv_vertex]):.2e}{mark}"
    else:
        le = "–"
    sd = sd_energy(V, F, uv, Fuv) if true_scale else float("nan")
    line = (f"| {method} | {s['flips']} | {s['boundary_crossings']} | {s['iso_mean']:.4f} | {s['iso_p95']:.4f} | "
            f"{s['conformal_mean']:.4f} | {s['area_mean']:.4f} | {'–' if np.isnan(sd) else f'{sd:.5f}'} | {le} | "
            f"{seconds:.2f} | {notes} |")
    seams = result.report["method"]["seams"].get("seams", 0) if result is not None and result.seamed else 0
    return line, {"method": method, "flips": s["flips"], "crossings": s["boundary_crossings"],
                  "iso": s["iso_mean"], "seconds": seconds, "seams": seams}


def timed(fn, *a):
    t = time.perf_counter()
    out = fn(*a)
    return out, time.perf_counter() - t


def _notes(rep: dict) -> str:
    r, seams = rep["method"]["refine"], rep["method"]["seams"]
    cut = f"; {seams['seams']} seams, {seams['length']:.3g} long" if seams["used"] else ""
    if "polish" not in r:
        return cut[2:]
    return f"start {r['start']['layout']}, {r['polish']['iterations']} it, {r['polish']['stop']}{cut}"


def bench(name: str) -> list[str]:
    V, F, uvt = load(name)
    out = [f"\n### {name} ({len(V)} vertices, {len(F)} faces)\n",
           "| method | flips | crossings | iso mean | iso p95 | conformal mean | area mean | SD | layout err | s "
           "| notes |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    rows = []
    for label, kw in (("heatparam raw (refine none, fill none)", {"refine": "none", "fill": "none"}),
                      ("heatparam filled (fill poisson, refine none)", {"refine": "none", "fill": "poisson"}),
                      ("heatparam default", {}),
                      ("heatparam default, --seams none", {"seams": "none"})):
        if label.endswith("--seams none") and len(metrics.boundary_loops(F)) == 1:
            continue  # no holes: the default row is this row
        try:
            res, dt = timed(lambda kw=kw: pipeline.parameterize(V, F, **kw))
            line, r = row(label, V, F, res.uv, dt, uvt, True, _notes(res.report), res)
            out.append(line)
            rows.append(r)
        except Exception as exc:  # e.g. --fill poisson is refused on planar meshes
            out.append(f"| {label} | n/a ({type(exc).__name__}) |  |  |  |  |  |  |  |  |  |")
    uv_l, t_l = timed(lscm, V, F)
    line, r = row("libigl LSCM (2 fixed vertices)", V, F, uv_l, t_l, uvt, False)
    out.append(line)
    rows.append(r)
    uv_t, t_t = timed(tutte, V, F)
    # ARAP/SLIM start from LSCM scaled to true area (they are true-scale energies).
    s_l = metrics.summary(V, F, uv_l)["uv_scale"]
    for start, uv0, t0 in (("Tutte", uv_t, t_t), ("LSCM", uv_l * s_l, t_l)):
        for peer, fn in (("ARAP", arap), ("SLIM", slim)):
            label = f"libigl {peer} 100 it from {start}"
            try:
                uv, dt = timed(fn, V, F, uv0)
                line, r = row(label, V, F, uv, dt + t0, uvt, True)
                out.append(line)
                rows.append(r)
            except Exception as exc:  # e.g. arap_precomputation fails on some meshes
                out.append(f"| {label} | failed ({type(exc).__name__}: {exc}) |  |  |  |  |  |  |  |  |  |")
    out.append("")
    out.append(summary_line(rows))
    return out


def summary_line(rows: list[dict]) -> str:
    """Our default against the best flip-free and the best bijective ARAP/SLIM/LSCM peer, and SLIM's time ratio."""
    ours = next(r for r in rows if r["method"] == "heatparam default")
    peers = [r for r in rows if r["method"].startswith("libigl")]
    flip_free = [r for r in peers if r["flips"] == 0 and not r["method"].startswith("libigl LSCM")]
    bijective = [r for r in peers if r["flips"] == 0 and r["crossings"] == 0]
    slim = [r["seconds"] for r in peers if "SLIM" in r["method"]]

    def best(rs):
        if not rs:
            return "none"
        b = min(rs, key=lambda r: r["iso"])
        return f"{b['method'][7:]} {b['iso']:.4f} ({b['crossings']} crossings)"

    lo, hi = min(slim) / ours["seconds"], max(slim) / ours["seconds"]
    cut = f", {ours['seams']} seams" if ours["seams"] else ""
    return (f"**heatparam default** {ours['iso']:.4f}, {ours['flips']} flips, {ours['crossings']} crossings{cut}, "
            f"{ours['seconds']:.2f} s. Best flip-free ARAP/SLIM: {best(flip_free)}. Best bijective peer: "
            f"{best(bijective)}. SLIM time / ours: {lo:.1f}–{hi:.1f}×.")


def main(argv: list[str]) -> None:
    names = argv or MESHES + SHAPES
    print("# heatparam vs libigl peers")
    print("`*` layout error after scaling by uv_scale (the map is not at true scale). "
          "iso/conformal/area are scale-normalized (metrics.summary); means over non-flipped faces.")
    for name in names:
        for line in bench(name):
            print(line, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
