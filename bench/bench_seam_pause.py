"""Seams decided on paused polishes (``options.SEAM_PAUSE_EXCESS``, ``SEAM_PAUSE_FLOOR``): how far a paused polish
still is from its finished map, and what pausing saves end to end.

Usage: ``python bench/bench_seam_pause.py [mesh ...]`` (default: halftunnel.off beetle.off from ../shared/meshes,
``cyl_noisy`` = ``datasets.cylinder_with_holes`` with scan noise 0.1 × its edge length, ``demo`` =
``datasets.noisy_scan_part``, and ``curved_cap_with_holes``; also ``beetle_up``, ``halftunnel_up`` and the other
names of ``bench_large.py``, minutes each). Two markdown tables on stdout:

1. per mesh and map (without / with seams): ``pipeline.flatten`` paused as the seams stage pauses it
   (``seams.seam_pause``: the map without seams at its coarse levels too), then ``Flat.resume()``: Newton
   iterations (fine level, and the coarse level's in brackets) and iso mean where the polish paused and where it
   stopped, the ratio of their excesses over 1 (``SEAM_PAUSE_FLOOR`` must stay below every ratio), seconds;
2. ``parameterize`` with default options against the same with ``SEAM_PAUSE_EXCESS = 0`` (both trials finished),
   same process: seconds, the seams decision, whether the kept maps are identical.
"""

from __future__ import annotations

import sys
import time

import bench_large
import numpy as np
from common import load, machine

import heatparam.pipeline.seams as seams
from heatparam import datasets
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.mesh.validate import validate_mesh
from heatparam.options import SEAM_PAUSE_EXCESS, make_options
from heatparam.pipeline import flatten, parameterize
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress

DEFAULT = ["halftunnel.off", "beetle.off", "cyl_noisy", "demo", "curved_cap_with_holes"]


def mesh(name: str) -> tuple[np.ndarray, np.ndarray]:
    if name == "cyl_noisy":
        s = datasets.cylinder_with_holes()
        return s.V + 0.1 * 0.045 * np.random.default_rng(0).standard_normal(s.V.shape), s.F
    if name == "demo":
        s = datasets.noisy_scan_part()
        return s.V, s.F
    if name in bench_large.NAMES:
        return bench_large.make(name)
    V, F, _ = load(name)
    return V, F


def paused_vs_finished(name: str) -> None:
    opts, quiet = make_options(None), Progress(False)
    V, F = mesh(name)
    surface = Surface.validated(V, F)[0]
    paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
    Vs, Fs, _ = cut_open(surface.V, surface.F, paths)
    cut = Surface(Vs, Fs, validate_mesh(Vs, Fs))
    pausing = seams.seam_pause(surface, opts)
    for tag, srf, seamed in (("without seams", surface, False), ("with seams", cut, True)):
        t0 = time.perf_counter()
        f = flatten(srf, opts, quiet, seamed=seamed, pausing=pausing if not seamed else pausing._replace(coarse=0.0))
        it_p, iso_p = _its(f.method["refine"]), f.summary["iso_mean"]
        t1 = time.perf_counter()
        g = f if f.resume is None else f.resume()
        it, iso = _its(g.method["refine"]), g.summary["iso_mean"]
        ratio = (iso - 1) / (iso_p - 1) if iso_p > 1 else float("nan")
        print(f"| {name} | {tag} | {it_p} | {iso_p:.5f} | {it} | {iso:.5f} | {ratio:.3f} | {t1 - t0:.1f} + "
              f"{time.perf_counter() - t1:.1f} |", flush=True)


def _its(ref: dict) -> str:
    """Fine Newton iterations, with the coarse level's in brackets when there is one."""
    cp = ref.get("multilevel", {}).get("coarse_polish")
    return f"{ref['polish']['iterations']}" + (f" ({cp['iterations']})" if cp else "")


def end_to_end(name: str) -> None:
    V, F = mesh(name)
    runs = {}
    for pause in (SEAM_PAUSE_EXCESS, 0.0):
        seams.SEAM_PAUSE_EXCESS = pause
        try:
            t = time.perf_counter()
            runs[pause] = (parameterize(V, F), time.perf_counter() - t)
        finally:
            seams.SEAM_PAUSE_EXCESS = SEAM_PAUSE_EXCESS
    (a, ta), (b, tb) = runs[SEAM_PAUSE_EXCESS], runs[0.0]
    s = a.report["method"]["seams"]
    same = np.array_equal(a.uv, b.uv) and np.array_equal(a.Fuv, b.Fuv)
    print(f"| {name} | {ta:.2f} | {tb:.2f} | {s['used']} | {', '.join(s.get('paused', {}).get('maps', [])) or '–'} "
          f"| {same} |", flush=True)


def main(names: list[str]) -> None:
    print(f"# Seams decided on paused polishes — {time.strftime('%Y-%m-%d %H:%M')} — {machine()}\n")
    print(f"SEAM_PAUSE_EXCESS = {SEAM_PAUSE_EXCESS}, SEAM_PAUSE_FLOOR = {seams.SEAM_PAUSE_FLOOR}\n")
    print("| mesh | map | paused after (it) | iso mean paused | finished after (it) | iso mean finished | "
          "finished excess / paused excess | s to the pause + s to finish |")
    print("|---|---|---|---|---|---|---|---|")
    for name in names:
        paused_vs_finished(name)
    print("\n| mesh | parameterize s (paused trials) | s (finished trials) | seams used | decided paused | "
          "same kept map |")
    print("|---|---|---|---|---|---|")
    for name in names:
        end_to_end(name)


if __name__ == "__main__":
    main(sys.argv[1:] or DEFAULT)
