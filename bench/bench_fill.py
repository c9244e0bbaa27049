"""Benchmark of the fill surface M* (paper §2.5, Eq. 15-16): without fill, Poisson fill, biharmonic fill.

For each mesh prints fill time, M* size, the M → M* distance (max, relative to the bbox diagonal) and the map's
metrics (flips, boundary crossings, mean isometric distortion, layout error when the true layout is known).
``--figures`` also writes docs/figures/fill_*.png (paper Figures 7 and 12).

    python bench/bench_fill.py [--figures] [--only NAME]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from heatparam import datasets, fill, metrics, pipeline
from heatparam.formats import preview
from heatparam.mesh import validate_mesh

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"
FIGURES = ROOT / "docs" / "figures"


def load(name: str) -> datasets.Shape:
    if name.endswith(".off"):
        from heatparam.formats import load_mesh

        V, F = load_mesh(MESHES / name)
        return datasets.Shape(V, F, None, name)
    return getattr(datasets, name)()


def run(sh: datasets.Shape, method: str):
    t0 = time.perf_counter()
    uv, rep = pipeline.parameterize(sh.V, sh.F, fill=method, refine="none")
    total = time.perf_counter() - t0
    m, fr = rep["metrics"], rep["method"]["fill"]
    err = metrics.layout_error(uv, sh.uv_true) if sh.uv_true is not None else float("nan")
    row = {
        "mesh": sh.name, "n": len(sh.V), "fill": method,
        "fill_s": rep["timings_s"].get("fill", 0.0), "total_s": total,
        "Mstar_v": fr.get("vertices", 0), "depth": fr.get("depth") or "-",
        "dist_max_rel": fr.get("distance_max_rel", float("nan")),
        "flips": m["flips"], "crossings": m["boundary_crossings"], "iso_mean": m["iso_mean"], "layout_err": err,
    }
    return uv, row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figures", action="store_true", help="write docs/figures/fill_*.png")
    ap.add_argument("--only", default="", help="run one mesh")
    args = ap.parse_args()
    names = ["cone_s_strip", "cylinder_with_holes", "curved_cap_with_holes", "halftunnel.off", "beetle.off"]
    if args.only:
        names = [args.only]
    hdr = (f"| {'mesh':22s} | {'n':>6s} | {'fill':10s} | {'fill s':>6s} | {'total s':>7s} | {'M* verts':>8s} | "
           f"{'depth':>5s} | {'M->M* max':>9s} | {'flips':>5s} | {'cross':>5s} | {'iso mean':>8s} | "
           f"{'layout err':>10s} |")
    print(hdr)
    print("|" + "|".join("-" * (len(c)) for c in hdr.split("|")[1:-1]) + "|")
    for name in names:
        sh = load(name)
        uvs = {}
        for method in ("none", "poisson", "biharmonic"):
            uv, r = run(sh, method)
            uvs[method] = uv
            dist = "-" if method == "none" else f"{100 * r['dist_max_rel']:.2f}%"
            err = "-" if np.isnan(r["layout_err"]) else f"{r['layout_err']:.4f}"
            print(f"| {r['mesh']:22s} | {r['n']:6d} | {method:10s} | {r['fill_s']:6.2f} | {r['total_s']:7.2f} | "
                  f"{r['Mstar_v']:8d} | {str(r['depth']):>5s} | {dist:>9s} | {r['flips']:5d} | {r['crossings']:5d} | "
                  f"{r['iso_mean']:8.4f} | {err:>10s} |", flush=True)
        if args.figures and name in ("cone_s_strip", "cylinder_with_holes"):
            FIGURES.mkdir(parents=True, exist_ok=True)
            info = validate_mesh(sh.V, sh.F)
            stem = name.replace("_", "-")
            for method in ("poisson", "biharmonic"):
                M = fill.fill_surface(sh.V, sh.F, info, method=method)
                preview.save_fill_figure(FIGURES / f"fill-{stem}-{method}-surface.png", sh.V, sh.F, M.V, M.F,
                                        title=f"{name}, {method} fill")
                preview.save_fill_comparison(FIGURES / f"fill-{stem}-{method}-checker.png", sh.V, sh.F, uvs["none"],
                                            uvs[method], labels=("without fill", f"with {method} fill"),
                                            title=name)


if __name__ == "__main__":
    main()
