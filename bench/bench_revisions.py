"""The same meshes flattened by two checkouts of heatparam, each in a fresh process: what a change to the polish
did to iterations, time and the maps.

Usage: ``python bench/bench_revisions.py BEFORE_SRC [mesh ...]`` — BEFORE_SRC is the ``src`` folder of another
checkout (e.g. ``git worktree add /tmp/before <commit>`` → ``/tmp/before/src``); "after" is this checkout's
``src``. Meshes: ../shared/meshes files or ``heatparam.datasets`` names (default: halftunnel.off beetle.off
camelhead.off curved_cap_with_holes noisy_scan_part). Each mesh runs before, after, before, after (two runs each,
alternating, so that a machine's drift hits both); ``pipeline.parameterize`` with default options, timed inside the
process (no import time). Prints a markdown table: wall s of both runs, Newton iterations of the kept map and of the
map without seams (when the seams stage ran), the polish's stop reason and final energy, iso mean, flips, crossings.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from common import machine, run_isolated

CODE = """
import json, sys, time
p = json.load(open(sys.argv[1]))
sys.path.insert(0, p["src"])
sys.path.insert(0, p["bench"])
from common import load
import heatparam
from heatparam.pipeline import parameterize
assert heatparam.__file__.startswith(p["src"]), heatparam.__file__
V, F, _ = load(p["mesh"])
t = time.perf_counter()
r = parameterize(V, F)
w = time.perf_counter() - t
m = r.report["method"]
ref, wo = m["refine"], (m.get("without_seams") or {}).get("refine")
print(json.dumps(dict(s=w, it=ref["polish"]["iterations"], start=ref["start"]["layout"], stop=ref["polish"]["stop"],
                      E=ref["polish"]["energy_end"], seams=(m.get("seams") or {}).get("used"),
                      wo_it=wo["polish"]["iterations"] if wo else None, iso=r.report["metrics"]["iso_mean"],
                      flips=r.report["metrics"]["flips"], cross=r.report["metrics"]["boundary_crossings"])))
"""

DEFAULT = ["halftunnel.off", "beetle.off", "camelhead.off", "curved_cap_with_holes", "noisy_scan_part"]


def main(before: str, names: list[str]) -> None:
    here = Path(__file__).resolve().parent
    srcs = {"before": str(Path(before).resolve()), "after": str(here.parent / "src")}
    print(f"# Two checkouts, the same meshes — {time.strftime('%Y-%m-%d %H:%M')} — {machine()}\n")
    print(f"before = {srcs['before']}, after = {srcs['after']}\n")
    print("| mesh | code | wall s (2 runs) | start | Newton it | stop | energy end | seams | it without seams | "
          "iso mean | flips | crossings |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        runs: dict[str, list[dict]] = {"before": [], "after": []}
        for _ in range(2):
            for code in ("before", "after"):
                runs[code].append(run_isolated(CODE, {"src": srcs[code], "bench": str(here), "mesh": name}))
        for code, rs in runs.items():
            r = rs[-1]
            if "error" in r:
                print(f"| {name} | {code} | failed: {r['error']} |", flush=True)
                continue
            walls = " / ".join(f"{x['s']:.2f}" for x in rs)
            print(f"| {name} | {code} | {walls} | {r['start']} | {r['it']} | "
                  f"{r['stop']} | {r['E']:.6f} | {r['seams']} | {r['wo_it']} | {r['iso']:.5f} | {r['flips']} | "
                  f"{r['cross']} |", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2:] or DEFAULT)
