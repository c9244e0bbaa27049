"""Issue 43's acceptance on the real-file corpus: heatparam's atlas against uvunwrap on every corpus mesh of at
least ``--min-faces`` faces, in process, same run, judged by ``bench_atlas.judge``: a markdown table and, per
criterion, how many meshes meet it, with the distribution (median, worst) of the ratios.

Usage: ``python bench/bench_atlas_corpus.py [CORPUS] [--min-faces 5000] [--max-faces 150000] [--repeat 1]``
(CORPUS defaults to ``bench/_corpus``, built by ``python bench/corpus.py``; its ``manifest.json`` gives the faces).
A file whose bytes repeat another's (the same mesh in two formats is read twice) is judged each time. heatparam runs
``pipeline.atlas_stage.atlas`` with its defaults (``max_distortion`` None), as ``heatparam.parameterize`` of a mesh
that is not one disk does; uvunwrap 0.3 with its defaults. Criteria (issue 43): time ≤ 3× uvunwrap's; charts ≤
max(3, ½ uvunwrap's); seam length ≤ uvunwrap's; iso mean ≤ min(1.05, uvunwrap's); 0 flips, overlaps and collapsed
faces.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from bench_atlas import best_of, fmt, run_ours, run_uvunwrap
from common import machine

from heatparam import datasets, formats

DEFAULT_CORPUS = Path(__file__).resolve().parent / "_corpus"


def criteria(ours: dict, peer: dict) -> dict[str, bool]:
    """Issue 43's criteria for one mesh (module docstring)."""
    return {"time ≤ 3×": ours["seconds"] <= 3 * peer["seconds"],
            "charts ≤ max(3, ½)": ours["charts"] <= max(3, peer["charts"] / 2),
            "seams ≤": ours["seam"] <= peer["seam"],
            "iso ≤ min(1.05, peer)": ours["iso_mean"] <= min(1.05, peer["iso_mean"]),
            "0 flips / overlaps / collapsed": ours["flips"] + ours["overlaps"] + ours["collapsed"] == 0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("corpus", nargs="?", default=str(DEFAULT_CORPUS))
    ap.add_argument("--min-faces", type=int, default=5000)
    ap.add_argument("--max-faces", type=int, default=150_000)
    ap.add_argument("--repeat", type=int, default=1, help="runs per method; the least time is reported")
    args = ap.parse_args()
    root = Path(args.corpus)
    files = [f["path"] for f in json.loads((root / "manifest.json").read_text())["files"]
             if isinstance(f.get("faces"), int) and args.min_faces <= f["faces"] <= args.max_faces]
    print(f"machine: {machine()}; {len(files)} files of {args.min_faces}-{args.max_faces} faces in {root}\n")
    Vw, Fw = datasets.torus()  # warm-up, untimed (bench_atlas.py's module docstring)
    run_ours(Vw, Fw, "torus"), run_uvunwrap(Vw, Fw)
    print("| mesh | method | charts | seam/√A | iso mean | iso p95 | flips | overlaps | collapsed | packing | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for path in files:
        V, F = formats.load_mesh(root / path)
        try:
            ours = best_of(run_ours, (V, F, path), args.repeat)
            peer = best_of(run_uvunwrap, (V, F), args.repeat)
        except Exception as exc:  # noqa: BLE001 - a failure is a result
            print(f"| {path} | failed: {type(exc).__name__}: {str(exc)[:80]} |||||||||", flush=True)
            continue
        print(fmt(path, "heatparam", ours), flush=True)
        print(fmt(path, "uvunwrap", peer), flush=True)
        rows.append((path, ours, peer))
    print(f"\n{len(rows)} meshes judged. Per criterion: meshes meeting it; ratio heatparam / uvunwrap median, worst\n")
    print("| criterion | met | ratio median | ratio worst (mesh) |")
    print("|---|---|---|---|")
    keys = {"time ≤ 3×": "seconds", "charts ≤ max(3, ½)": "charts", "seams ≤": "seam", "iso ≤ min(1.05, peer)":
            "iso_mean"}
    for name in criteria(rows[0][1], rows[0][2]) if rows else []:
        met = sum(criteria(o, p)[name] for _, o, p in rows)
        if name in keys:
            r = np.array([o[keys[name]] / max(p[keys[name]], 1e-300) for _, o, p in rows])
            w = int(np.argmax(r))
            print(f"| {name} | {met} of {len(rows)} | {np.median(r):.3f} | {r[w]:.3f} ({rows[w][0]}) |")
        else:
            print(f"| {name} | {met} of {len(rows)} | | |")


if __name__ == "__main__":
    main()
