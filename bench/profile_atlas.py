"""Where an atlas's time goes: ``heatparam.parameterize`` of each mesh under cProfile, the cumulative seconds of its
stages (repair; the segmentation's growing, farthest seeds, region checks, merges and straightening; the joint
polish; the pieces flattened one by one; packing; the report's overlap count and metrics), after one untimed warm-up
call on the generated torus (imports, numba's cache, MKL's first call left out).

Usage: ``python bench/profile_atlas.py [--repeat R] [name ...]`` (../shared/meshes files or generated datasets;
default cow, 3holes, camelhead, beetle, bunny); open meshes with ``max_distortion=1.05`` as in bench_atlas.py.
Prints a markdown table, one row per mesh: total seconds (the least of R plain runs) and each stage's seconds
(one profiled run; profiling slows pure-Python code more than compiled code: read the shares, not the sums).
Run it on another checkout (``PYTHONPATH=that/src``) for a before / after on the same machine.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

from common import SHARED, machine

import heatparam
from heatparam import datasets, formats

OPEN = ("camelhead.off", "beetle.off", "halftunnel.off")
#: stage -> (file suffix, function name, the caller it is timed under or None): its cumulative seconds
STAGES = {
    "repair": ("atlas/repair.py", "repair", None),
    "growing": ("atlas/grow.py", "grow", None),
    "of which seeds": ("atlas/grow.py", "farthest_seeds", None),
    "region checks": ("atlas/flatten.py", "flatten_charts", "segment"),
    "merges": ("atlas/merge.py", "merge", None),
    "straightening": ("atlas/straighten.py", "straighten", None),
    "joint polish": ("atlas/polish.py", "polish_charts", None),
    "one by one": ("pipeline/atlas_stage.py", "_one_by_one", None),
    "packing": ("atlas/pack.py", "pack_charts", None),
    "report": ("pipeline/atlas_stage.py", "_report", None),
    "metrics": ("heatparam/metrics.py", "summary", None),
}


def load(name):
    return getattr(datasets, name)() if hasattr(datasets, name) else formats.load_mesh(SHARED / name)


def stage_seconds(stats: pstats.Stats) -> dict[str, float]:
    """Cumulative seconds per stage (:data:`STAGES`), from a profile's statistics."""
    out = {}
    for stage, (suffix, fn, caller) in STAGES.items():
        total = 0.0
        for (file, _, name), (_, _, _, ct, callers) in stats.stats.items():
            if name != fn or not file.replace("\\", "/").endswith(suffix):
                continue
            total += ct if caller is None else sum(c[3] for (_, _, cn), c in callers.items() if cn == caller)
        out[stage] = total
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("names", nargs="*", default=["cow.off", "3holes.off", "camelhead.off", "beetle.off",
                                                   "stanford-bunny.obj"])
    args = ap.parse_args()
    print(f"heatparam {heatparam.__file__}; {machine()}")
    heatparam.parameterize(*datasets.torus())
    print("| mesh | faces | total s | " + " | ".join(STAGES) + " |")
    print("|---" * (len(STAGES) + 3) + "|")
    for name in args.names:
        V, F = load(name)
        kw = {"max_distortion": 1.05} if name in OPEN else {}
        best = float("inf")
        for _ in range(args.repeat):
            t = time.perf_counter()
            heatparam.parameterize(V, F, **kw)
            best = min(best, time.perf_counter() - t)
        prof = cProfile.Profile()
        prof.enable()
        heatparam.parameterize(V, F, **kw)
        prof.disable()
        sec = stage_seconds(pstats.Stats(prof))
        print(f"| {name} | {len(F)} | {best:.2f} | " + " | ".join(f"{sec[s]:.2f}" for s in STAGES) + " |",
              flush=True)


if __name__ == "__main__":
    main()
