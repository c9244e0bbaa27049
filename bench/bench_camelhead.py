"""Issue 2 benchmark: per-stage time and peak memory on camelhead.off, all-pairs vs landmark geodesics.

Run: python bench/bench_camelhead.py   (about a minute on 2 cores). Prints a markdown table.
"""

from __future__ import annotations

import datetime

from common import PEAK_RSS, SHARED, machine, run_isolated

CODE = PEAK_RSS + """
import json, time
from heatparam.formats import load_mesh
from heatparam.pipeline import parameterize
p = json.load(open(sys.argv[1]))
t0 = time.perf_counter()
V, F = load_mesh(p["mesh"])
t_load = time.perf_counter() - t0
uv, rep = parameterize(V, F, geodesics=p["mode"], fill="none", refine="none")
m = rep["metrics"]
print(json.dumps({"load": t_load, **rep["timings_s"], "peak_mb": peak_mb(), "iso": m["iso_mean"],
                  "flips": m["flips"], "k": rep["parameters"]["landmarks_used"],
                  "backend": rep["method"]["solver_backend"]}))
"""


def main() -> None:
    print(f"# camelhead.off — {datetime.date.today()} — {machine()}\n")
    stages = ["load", "validate", "operators", "factorize", "geodesics", "mds", "metrics"]
    print("| mode | k | " + " | ".join(stages) + " | total s | peak RSS MB | iso mean | flips |")
    print("|---|---|" + "---|" * len(stages) + "---|---|---|---|")
    for mode in ("all-pairs", "landmarks"):
        r = run_isolated(CODE, {"mesh": str(SHARED / "camelhead.off"), "mode": mode})
        if "error" in r:
            print(f"| {mode} | error: {r['error']} |")
            continue
        total = sum(r.get(s, 0.0) for s in stages)
        cells = " | ".join(f"{r.get(s, 0.0):.2f}" for s in stages)
        print(f"| {mode} | {r['k']} | {cells} | {total:.2f} | {r['peak_mb']:.0f} | {r['iso']:.3f} | {r['flips']} |")
    print(f"\nsolver backend: {r.get('backend')}; raw MDS map (fill none, refine none)")


if __name__ == "__main__":
    main()
