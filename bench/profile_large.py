"""Where a large part's time goes around its flattening: ``heatparam.unwrap.unwrap_file`` (what ``heatparam unwrap
part.ply -o out.obj`` runs) of issue 42's family parts, in process, each named stage's wall seconds summed over its
calls (every binding of the function in heatparam's modules wrapped; no profiler, so the figures add up to the
run's): the fixed costs around the flattening (reading, the units check, validation, the atlas's repair and report,
the maps' metrics, writing the OBJ) and what is left, the flattening itself (start checks, heat stage, polish; both
maps of the seams stage). One untimed warm-up run on a small part first and every compiled loop loaded
(``heatparam.compiled.warm_all``: imports, numba's cache, MKL's first call), then R timed runs per part; each cell
is the least of its R runs (a noisy machine slows a run, never speeds it up).

Usage: ``python bench/profile_large.py [--family SEEDS] [--repeat R]`` (default ``1011,1002``: a scan that goes
through the atlas, a holed part that does not; R = 3). Prints a markdown table, one column per part. Run it on
another checkout (``PYTHONPATH=that/src``) for a before / after on the same machine.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import large_family
from common import machine, seeds

import heatparam.pipeline.atlas_stage  # noqa: F401 - the modules whose bindings are wrapped, imported first
import heatparam.pipeline.seams  # noqa: F401
import heatparam.unwrap
from heatparam import compiled, datasets

#: row -> "module:function" (every binding of that function in heatparam's modules is timed)
STAGES = {
    "read": "heatparam.formats.meshes:load_mesh",
    "units check": "heatparam.unwrap:_assumed_units",
    "validation": "heatparam.mesh.validate:validate_mesh",
    "atlas: repair": "heatparam.atlas.repair:repair",
    "map metrics": "heatparam.metrics:summary",
    "atlas: report": "heatparam.pipeline.atlas_stage:_report",
    "write OBJ": "heatparam.formats.uvobj:save_uv_obj",
}


class StageClock:
    """Wall seconds per stage (:data:`STAGES`) while installed: each function is replaced, in every heatparam
    module that binds it, by a timed wrapper (calls made while another call of the same stage runs count once)."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._depth: dict[str, int] = defaultdict(int)
        for stage, spec in STAGES.items():
            mod, name = spec.split(":")
            self._wrap(stage, getattr(importlib.import_module(mod), name))

    def reset(self) -> None:
        self.seconds.clear()
        self.calls.clear()

    def _wrap(self, stage: str, fn) -> None:
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            self._depth[stage] += 1
            t = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self._depth[stage] -= 1
                if not self._depth[stage]:
                    self.seconds[stage] += time.perf_counter() - t
                    self.calls[stage] += 1

        for mod in list(sys.modules.values()):
            if getattr(mod, "__name__", "").startswith("heatparam"):
                for attr, val in list(vars(mod).items()):
                    if val is fn:
                        setattr(mod, attr, timed)


def run(path: Path, out: Path) -> float:
    t = time.perf_counter()
    heatparam.unwrap.unwrap_file(path, out)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--family", default="1011,1002", help="family seeds (as bench_large.py's --family)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per part (the least of each cell)")
    args = ap.parse_args()
    clock = StageClock()
    columns = {}
    with tempfile.TemporaryDirectory() as tmp:
        warm = Path(tmp) / "warm.ply"
        s = datasets.noisy_scan_part()
        large_family.write_ply(warm, s.V, s.F)
        run(warm, Path(tmp) / "warm.obj")
        compiled.warm_all()
        for seed in seeds(args.family):
            V, F, _ = large_family.draw(seed)
            part = Path(tmp) / f"part{seed}.ply"
            large_family.write_ply(part, V, F)
            runs = []
            for k in range(args.repeat):
                clock.reset()
                runs.append((run(part, Path(tmp) / f"out{seed}_{k}.obj"), dict(clock.seconds), dict(clock.calls)))
                print(f"part {seed}: {runs[-1][0]:.1f} s", file=sys.stderr, flush=True)
            least = {stage: min(r[1].get(stage, 0.0) for r in runs) for stage in STAGES}
            columns[seed] = (len(F), min(r[0] for r in runs), least, runs[0][2])
    print(f"machine: {machine()}\n")
    print("| stage | " + " | ".join(f"{seed} ({m // 1000}k faces)" for seed, (m, *_) in columns.items()) + " |")
    print("|---|" + "---|" * len(columns))
    for stage in STAGES:
        cells = [f"{sec.get(stage, 0.0):.2f} s ({calls.get(stage, 0)})" for _, _, sec, calls in columns.values()]
        print(f"| {stage} | " + " | ".join(cells) + " |")
    fixed = [sum(sec.values()) for _, _, sec, _ in columns.values()]
    print("| **fixed costs** (the rows above) | " + " | ".join(f"**{f:.2f} s**" for f in fixed) + " |")
    print("| the flattening and the rest | "
          + " | ".join(f"{total - f:.2f} s" for (_, total, _, _), f in zip(columns.values(), fixed, strict=True))
          + " |")
    print("| **total** (unwrap_file, imports excluded) | "
          + " | ".join(f"**{total:.2f} s**" for _, total, _, _ in columns.values()) + " |")
    print("\n(calls in brackets; the flattening: start checks, heat stage, polish, both maps of the seams stage)")


if __name__ == "__main__":
    main()
