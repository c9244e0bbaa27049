"""The same meshes flattened by two checkouts of heatparam, each in a fresh process: what a change to the polish
did to iterations, time and the maps.

Usage: ``python bench/bench_revisions.py BEFORE_SRC [mesh ...]`` — BEFORE_SRC is the ``src`` folder of another
checkout (e.g. ``git worktree add /tmp/before <commit>`` → ``/tmp/before/src``); "after" is this checkout's
``src``. Meshes: ../shared/meshes files or ``heatparam.datasets`` names (default: halftunnel.off beetle.off
camelhead.off curved_cap_with_holes noisy_scan_part). Each mesh runs before, after, before, after (two runs each,
alternating, so that a machine's drift hits both); ``pipeline.parameterize`` with default options, timed inside the
process (no import time). Prints a markdown table: wall s of both runs, Newton iterations of the kept map and of the
map without seams (when the seams stage ran), the polish's stop reason and final energy, iso mean, flips, crossings
(for an atlas: the charts' joint polish summed over components, its largest final energy, overlapping triangle
pairs).
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
m, met = r.report["method"], r.report["metrics"]
if "atlas" in m:  # an atlas: the charts' joint polish of every component
    jp = [c["joint_polish"] for c in m["atlas"]["components"] if c.get("joint_polish")]
    out = dict(it=sum(j["iterations"] for j in jp), start=f"atlas, {met.get('charts')} charts",
               stop="; ".join(sorted({j["stop"] for j in jp})), E=max(j["energy_end"] for j in jp), seams=None,
               wo_it=None, cross=met.get("overlapping_triangle_pairs"))
else:
    ref, wo = m["refine"], (m.get("without_seams") or {}).get("refine")
    out = dict(it=ref["polish"]["iterations"], start=ref["start"]["layout"], stop=ref["polish"]["stop"],
               E=ref["polish"]["energy_end"], seams=(m.get("seams") or {}).get("used"),
               wo_it=wo["polish"]["iterations"] if wo else None, cross=met["boundary_crossings"])
print(json.dumps(dict(s=w, iso=met["iso_mean"], flips=met["flips"], **out)))
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
