"""Issue 4 benchmark: heatparam vs libigl LSCM / SLIM and potpourri3d on ~10k, ~50k, ~200k vertices, one run.

Meshes: camelhead.off midpoint-upsampled (igl.upsample). heatparam runs end to end *including I/O* (load the
OBJ, parameterize with default settings, write the UV OBJ), each run in a fresh process for its own peak RSS.
Peers run in the same process run on the same meshes. Prints markdown tables; results go in BENCHMARKS.md.

Run: python bench/bench_scale.py [--sizes 10000 50000 200000] [--slim-max 60000]   (~5-10 min on 2 cores)
"""

from __future__ import annotations

import argparse
import datetime
import tempfile
from pathlib import Path

import numpy as np
from common import PEAK_RSS, SHARED, machine, run_isolated, upsampled_camelhead

HEATPARAM = PEAK_RSS + """
import json, time
t0 = time.perf_counter()
from heatparam.io import load_mesh, save_uv_obj
from heatparam.pipeline import parameterize
p = json.load(open(sys.argv[1]))
t1 = time.perf_counter()
V, F = load_mesh(p["mesh"])
t2 = time.perf_counter()
uv, rep = parameterize(V, F, **p["options"])
t3 = time.perf_counter()
save_uv_obj(p["out"], V, F, uv)
t4 = time.perf_counter()
m = rep["metrics"]
print(json.dumps({"import": t1 - t0, "load": t2 - t1, "parameterize": t3 - t2, "save": t4 - t3,
                  "end_to_end": t4 - t1, "stages": rep["timings_s"], "peak_mb": peak_mb(),
                  "flips": m["flips"], "crossings": m["boundary_crossings"], "iso": m["iso_mean"],
                  "k": rep["parameters"]["landmarks_used"], "mode": rep["method"]["geodesics"],
                  "backend": rep["method"]["solver_backend"]}))
"""

PEER = PEAK_RSS + """
import json, time
import numpy as np, igl
from heatparam.io import load_mesh
from heatparam import metrics
p = json.load(open(sys.argv[1]))
V, F = load_mesh(p["mesh"])
t0 = time.perf_counter()
bnd = igl.boundary_loop(F)
if p["peer"] == "lscm":
    b = np.array([bnd[0], bnd[len(bnd) // 2]])
    bc = np.array([[0.0, 0.0], [1.0, 0.0]])
    uv = igl.lscm(V, F, b, bc)[0]
elif p["peer"] == "slim":
    circ = igl.map_vertices_to_circle(V, bnd)
    uv0 = igl.harmonic(V, F, bnd, circ, 1)
    data = igl.slim_precompute(np.asfortranarray(V), np.asfortranarray(F.astype(np.int32)), np.asfortranarray(uv0),
                               igl.SYMMETRIC_DIRICHLET, np.zeros(0, np.int32), np.zeros((0, 2), order="F"), 0.0)
    uv = igl.slim_solve(data, p["iters"])
t = time.perf_counter() - t0
s = metrics.summary(V, F, uv)
print(json.dumps({"seconds": t, "peak_mb": peak_mb(), "flips": s["flips"], "crossings": s["boundary_crossings"],
                  "iso": s["iso_mean"]}))
"""

GEODESICS = PEAK_RSS + """
import json, time
import numpy as np, igl
from heatparam.io import load_mesh
from heatparam.heat import HeatGeodesics, time_step
from heatparam.operators import build_operators
p = json.load(open(sys.argv[1]))
V, F = load_mesh(p["mesh"])
n = len(V)
src = np.linspace(0, n - 1, p["sources"]).astype(np.int64)
out = {}
t0 = time.perf_counter()
op = build_operators(V, F)
solver = HeatGeodesics(op, time_step(op))
pre = time.perf_counter() - t0
solver.distances(src[:8])  # warm-up: threads, first touch of the scratch buffers
t1 = time.perf_counter()
solver.distances(src)
t2 = time.perf_counter()
out["heatparam"] = {"precompute": pre, "per_source_ms": (t2 - t1) / len(src) * 1e3}
import potpourri3d as pp3d
t0 = time.perf_counter()
s = pp3d.MeshHeatMethodDistanceSolver(V, F)
t1 = time.perf_counter()
for i in src[:32]:
    s.compute_distance(int(i))
t2 = time.perf_counter()
out["potpourri3d"] = {"precompute": t1 - t0, "per_source_ms": (t2 - t1) / 32 * 1e3}
t0 = time.perf_counter()
data = igl.HeatGeodesicsData()
igl.heat_geodesics_precompute(V, F, data)
t1 = time.perf_counter()
for i in src[:32]:
    igl.heat_geodesics_solve(data, np.array([i]))
t2 = time.perf_counter()
out["libigl"] = {"precompute": t1 - t0, "per_source_ms": (t2 - t1) / 32 * 1e3}
out["n"] = n
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10000, 50000, 200000])
    ap.add_argument("--slim-max", type=int, default=20000, help="largest mesh on which SLIM is run")
    ap.add_argument("--slim-iters", type=int, default=100)
    ap.add_argument("--geodesics-mesh", default=str(SHARED / "beetle.off"),
                    help="mesh for the per-source geodesics comparison (~25k vertices; default beetle.off, 19.9k)")
    args = ap.parse_args()
    from heatparam.io import save_uv_obj

    print(f"# Scale benchmark — {datetime.date.today()} — {machine()}\n")
    print("| mesh | n | tool | seconds | ratio to LSCM | peak RSS MB | flips | crossings | iso mean | notes |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            V, F = upsampled_camelhead(size)
            path = Path(tmp) / f"camel{len(V)}.obj"
            save_uv_obj(path, V, F, np.zeros((len(V), 2)))
            lscm = run_isolated(PEER, {"mesh": str(path), "peer": "lscm"})
            rows = [("libigl LSCM", lscm, "")]
            hp = run_isolated(HEATPARAM, {"mesh": str(path), "out": str(Path(tmp) / "o.obj"), "options": {}})
            raw = run_isolated(HEATPARAM, {"mesh": str(path), "out": str(Path(tmp) / "o.obj"),
                                           "options": {"refine": "none"}})
            rows[:0] = [("heatparam default (end to end, I/O incl.)", hp, ""),
                        ("heatparam --refine none (end to end, I/O incl.)", raw, "")]
            if len(V) <= args.slim_max:
                rows.append((f"libigl SLIM ({args.slim_iters} it, Tutte start)",
                             run_isolated(PEER, {"mesh": str(path), "peer": "slim", "iters": args.slim_iters}), ""))
            else:
                rows.append(("libigl SLIM", {"error": f"skipped above {args.slim_max} vertices"}, ""))
            for name, r, note in rows:
                if "error" in r:
                    print(f"| camelhead↑ | {len(V)} | {name} | — | — | — | — | — | — | {r['error']} |")
                    continue
                sec = r.get("end_to_end", r.get("seconds"))
                ratio = sec / lscm["seconds"] if "seconds" in lscm else float("nan")
                if "stages" in r:
                    note = (f"{r['mode']} k={r['k']}, {r['backend']}; load {r['load']:.2f} s, save {r['save']:.2f} s; "
                            + ", ".join(f"{k} {v:.2f}" for k, v in r["stages"].items()))
                print(f"| camelhead↑ | {len(V)} | {name} | {sec:.2f} | {ratio:.2f} | {r['peak_mb']:.0f} | {r['flips']} "
                      f"| {r['crossings']} | {r['iso']:.3f} | {note} |")
        print(f"\n## Heat-method geodesics per source on {Path(args.geodesics_mesh).name}\n")
        g = run_isolated(GEODESICS, {"mesh": args.geodesics_mesh, "sources": 256})
        if "error" in g:
            print(f"error: {g['error']}")
            return
        print(f"{g.pop('n')} vertices\n")
        print("| solver | precompute s | per source ms | ratio to heatparam |")
        print("|---|---|---|---|")
        for name, r in g.items():
            print(f"| {name} | {r['precompute']:.2f} | {r['per_source_ms']:.2f} | "
                  f"{r['per_source_ms'] / g['heatparam']['per_source_ms']:.1f} |")
        print("\nheatparam: 256 sources in batches (multi-column solves); peers: one source per call (32 calls).")


if __name__ == "__main__":
    main()
