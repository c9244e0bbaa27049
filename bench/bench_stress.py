"""Stress majorization (SMACOF, ``--stress smacof``) before the polish: does it help? A markdown table on stdout.

Usage: ``python bench/bench_stress.py [name ...]`` (generated datasets or files in ../shared/meshes).
For each mesh: ``--stress none`` / ``smacof`` × ``--refine none`` / ``sd``, every other option at its default
(fill auto, geodesics auto). Columns: the path SMACOF ran on (all-pairs or landmarks) and its Guttman iterations,
the relative RMS stress of Eq. 1 on the MDS distances before → after SMACOF, SMACOF seconds, the refinement's
start layout and Newton iterations, flips, iso mean (``report["metrics"]["iso_mean"]``), true-scale layout error
(``metrics.layout_error`` / diameter, generated datasets only) and the whole ``parameterize`` call in seconds.
"""

from __future__ import annotations

import sys
import time

from common import load, machine

from heatparam import metrics, pipeline

SHAPES = ["cylinder_patch", "cylinder_with_holes", "cone_s_strip", "curved_cap_with_holes"]
MESHES = ["halftunnel.off", "beetle.off", "camelhead.off", "woody.obj", "bump-domain.obj"]


def row(name: str, V, F, uvt, refine: str, stress: str) -> str:
    t = time.perf_counter()
    uv, rep = pipeline.parameterize(V, F, refine=refine, stress=stress)
    dt = time.perf_counter() - t
    m, meth = rep["metrics"], rep["method"]
    s = meth["stress"]
    if s["method"] == "smacof":
        sm = (f"{s['pattern']} {s['iterations']} | {s['stress_start']:.4f} → {s['stress_end']:.4f} | "
              f"{s['seconds']:.2f}")
    else:
        sm = "– | – | –"
    r = meth["refine"]
    ref = f"{r['start']['layout']} | {r['polish']['iterations']}" if refine != "none" else "– | –"
    le = f"{metrics.layout_error(uv, uvt):.2e}" if uvt is not None else "–"
    return (f"| {name} | {refine} | {stress} | {sm} | {ref} | {m['flips']} | {m['iso_mean']:.4f} | {le} | "
            f"{dt:.2f} |")


def main(argv: list[str]) -> None:
    names = argv or SHAPES + MESHES
    print(f"# SMACOF before the polish ({machine()})\n")
    print("| mesh | refine | stress | SMACOF path, it | stress before → after | SMACOF s | refine start | "
          "Newton it | flips | iso mean | layout err | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        try:
            V, F, uvt = load(name)
        except FileNotFoundError:
            print(f"| {name} | not found |  |  |  |  |  |  |  |  |  |  |")
            continue
        for refine in ("none", "sd"):
            for stress in ("none", "smacof"):
                print(row(f"{name} ({len(V)} v)", V, F, uvt, refine, stress), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
