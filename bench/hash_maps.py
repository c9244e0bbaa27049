"""Fingerprints of heatparam's maps, to show that a restructuring changed no bit: sha256 of every map (uv, Fuv)
and its report's metrics, over the atlas set, the disks with seams, and coarse-to-fine polishes of upsampled meshes
(with and without the seams stage's pauses).

    python bench/hash_maps.py > before.txt      # on the old code
    python bench/hash_maps.py > after.txt       # on the new code, same machine: diff the two

Bits depend on the CPU and the numerical libraries: compare two runs on one machine only.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time

import numpy as np
from common import SHARED

import heatparam
from heatparam import datasets
from heatparam.formats import load_mesh


def digest(a) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]


def upsampled(name: str, times: int):
    import igl

    V, F = load_mesh(SHARED / name)
    for _ in range(times):
        V, F = igl.upsample(V, F)
    return V, F


def noisy_cylinder():
    s = datasets.cylinder_with_holes(h=0.045 * np.sqrt(2101 / 60_000))
    h = float(np.mean(np.linalg.norm(s.V[s.F[:, 1]] - s.V[s.F[:, 0]], axis=1)))
    return s.V + 0.2 * h * np.random.default_rng(0).standard_normal(s.V.shape), s.F


def generated(name):
    s = getattr(datasets, name)()
    return (s.V, s.F) if hasattr(s, "V") else s[:2]


#: (label, mesh maker, options)
CASES = [
    ("cow atlas", lambda: load_mesh(SHARED / "cow.off"), {}),
    ("3holes atlas", lambda: load_mesh(SHARED / "3holes.off"), {}),
    ("bunny atlas", lambda: load_mesh(SHARED / "stanford-bunny.obj"), {}),
    ("dragon-res3 atlas", lambda: load_mesh(SHARED / "stanford-dragon-res3.ply"), {}),
    ("torus atlas", lambda: generated("torus"), {}),
    ("closed_cube atlas", lambda: generated("closed_cube"), {}),
    ("capped_cylinder atlas", lambda: generated("capped_cylinder"), {}),
    ("cone_with_base atlas", lambda: generated("cone_with_base"), {}),
    ("camelhead max1.05", lambda: load_mesh(SHARED / "camelhead.off"), {"max_distortion": 1.05}),
    ("beetle max1.05", lambda: load_mesh(SHARED / "beetle.off"), {"max_distortion": 1.05}),
    ("halftunnel max1.05", lambda: load_mesh(SHARED / "halftunnel.off"), {"max_distortion": 1.05}),
    ("camelhead", lambda: load_mesh(SHARED / "camelhead.off"), {}),
    ("beetle", lambda: load_mesh(SHARED / "beetle.off"), {}),
    ("halftunnel", lambda: load_mesh(SHARED / "halftunnel.off"), {}),
    ("camelhead seams none", lambda: load_mesh(SHARED / "camelhead.off"), {"seams": "none"}),
    ("camelhead x4 multilevel", lambda: upsampled("camelhead.off", 2), {}),
    ("halftunnel x4 multilevel", lambda: upsampled("halftunnel.off", 2), {}),
    ("beetle x1 multilevel+seams", lambda: upsampled("beetle.off", 1), {}),
    ("cylinder noisy multilevel", noisy_cylinder, {}),
    ("camelhead x1 low threshold", lambda: upsampled("camelhead.off", 1), {"refine_multilevel": 5000}),
    ("beetle threshold 8k", lambda: load_mesh(SHARED / "beetle.off"), {"refine_multilevel": 8000}),
]


def main(only: list[str]) -> None:
    for label, make, opts in CASES:
        if only and not any(o in label for o in only):
            continue
        V, F = make()
        t = time.perf_counter()
        r = heatparam.parameterize(V, F, seed=0, **opts)
        m = r.report["metrics"]
        met = {k: m.get(k) for k in ("flips", "boundary_crossings", "iso_mean", "iso_p95")}
        print(f"{label}: n={len(V)} uv={digest(r.uv)} Fuv={digest(np.asarray(r.Fuv, np.int64))} "
              f"{json.dumps(met)}", flush=True)
        print(f"  ({time.perf_counter() - t:.1f} s)", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
