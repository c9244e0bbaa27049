"""Issue 4 benchmark: heatparam vs libigl LSCM / SLIM and potpourri3d on ~10k, ~50k, ~200k vertices, one run.

Meshes: camelhead.off midpoint-upsampled (igl.upsample). heatparam runs end to end *including I/O* (load the
OBJ, parameterize with default settings, write the UV OBJ), each run in a fresh process for its own peak RSS.
Peers run in the same process run on the same meshes. Prints markdown tables; results go in BENCHMARKS.md.

Run: python bench/bench_scale.py [--sizes 10000 50000 200000] [--slim-max 60000]   (~5-10 min on 2 cores)

Shorter runs (issue 4 follow-up; timings on a shared machine are noisy, so these repeat and print the median and
the spread):
  python bench/bench_scale.py --geodesics-only --repeats 5          per-source geodesic time (beetle, camelhead)
  python bench/bench_scale.py --sizes 200000 --raw-only --repeats 3 --geodesics-mesh   stages at ~180k, --refine none
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
from heatparam.formats import load_mesh, save_uv_obj
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
                  "backend": rep["method"]["solver_backend"],
                  "polish": rep["method"]["refine"].get("polish", {}),
                  "multilevel": rep["method"]["refine"].get("multilevel", {})}))
"""

PEER = PEAK_RSS + """
import json, time
import numpy as np, igl
from heatparam.formats import load_mesh
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
from heatparam.formats import load_mesh
from heatparam.heat import HeatGeodesics, time_step
from heatparam.operators import build_operators
p = json.load(open(sys.argv[1]))
V, F = load_mesh(p["mesh"])
used = np.unique(F)  # drop unreferenced vertices (stanford-bunny.obj has 1113): every solver needs them gone
V, F = V[used], np.searchsorted(used, F)
n = len(V)
src = np.linspace(0, n - 1, p["sources"]).astype(np.int64)
reps = p.get("repeats", 1)
out = {}
t0 = time.perf_counter()
op = build_operators(V, F)
solver = HeatGeodesics(op, time_step(op))
pre = time.perf_counter() - t0
solver.distances(src[:8])  # warm-up: threads, first touch of the scratch buffers
per = []
for _ in range(reps):
    t1 = time.perf_counter()
    solver.distances(src)
    per.append((time.perf_counter() - t1) / len(src) * 1e3)
out["heatparam"] = {"precompute": pre, "per_source_ms": per, "block": solver.block, "backend": solver.backend}
import potpourri3d as pp3d
t0 = time.perf_counter()
s = pp3d.MeshHeatMethodDistanceSolver(V, F)
pre = time.perf_counter() - t0
per = []
for _ in range(reps):
    t1 = time.perf_counter()
    for i in src[:32]:
        s.compute_distance(int(i))
    per.append((time.perf_counter() - t1) / 32 * 1e3)
out["potpourri3d"] = {"precompute": pre, "per_source_ms": per}
t0 = time.perf_counter()
data = igl.HeatGeodesicsData()
igl.heat_geodesics_precompute(V, F, data)
pre = time.perf_counter() - t0
per = []
for _ in range(reps):
    t1 = time.perf_counter()
    for i in src[:32]:
        igl.heat_geodesics_solve(data, np.array([i]))
    per.append((time.perf_counter() - t1) / 32 * 1e3)
out["libigl"] = {"precompute": pre, "per_source_ms": per}
out["n"] = n
print(json.dumps(out))
"""


def _spread(values: list[float], fmt: str = ".2f") -> str:
    """'median [min-max]' of repeated measurements (just the value for one)."""
    if len(values) == 1:
        return format(values[0], fmt)
    return f"{format(float(np.median(values)), fmt)} [{format(min(values), fmt)}-{format(max(values), fmt)}]"


def generated_mesh(spec: str, folder: str) -> str:
    """``cylinder_patch@N``: a generated cylinder patch of about N vertices, written to an OBJ in ``folder``."""
    from heatparam import datasets, io

    n = int(spec.split("@")[1])
    s = datasets.cylinder_patch(h=0.04 * float(np.sqrt(2213 / n)))  # 2213 vertices at the default h = 0.04
    path = str(Path(folder) / f"cylinder_patch_{len(s.V)}.obj")
    io.save_uv_obj(path, s.V, s.F, s.uv_true)
    return path


def geodesics_table(meshes: list[str], repeats: int, processes: int) -> None:
    """Per-source heat-method geodesic time: heatparam batched, peers one source per call."""
    import tempfile

    tmp = tempfile.TemporaryDirectory()
    meshes = [generated_mesh(m, tmp.name) if m.startswith("cylinder_patch@") else m for m in meshes]
    for mesh in meshes:
        print(f"\n## Heat-method geodesics per source on {Path(mesh).name}\n")
        runs = [run_isolated(GEODESICS, {"mesh": mesh, "sources": 256, "repeats": repeats}) for _ in range(processes)]
        errors = [r["error"] for r in runs if "error" in r]
        if errors:
            print(f"error: {errors[0]}")
            continue
        hp = runs[0]["heatparam"]
        print(f"{runs[0]['n']} vertices; {processes} fresh process(es) × {repeats} timed run(s) each: median "
              f"[min-max] over all {processes * repeats}; heatparam {hp['backend']}, {hp['block']} columns per "
              "batch\n")
        print("| solver | precompute s | per source ms | ratio to heatparam (medians) |")
        print("|---|---|---|---|")
        med = {}
        for name in ("heatparam", "potpourri3d", "libigl"):
            per = [x for r in runs for x in r[name]["per_source_ms"]]
            pre = [r[name]["precompute"] for r in runs]
            med[name] = float(np.median(per))
            print(f"| {name} | {_spread(pre)} | {_spread(per)} | {med[name] / med['heatparam']:.1f} |")
        print("\nheatparam: 256 sources in batches (multi-column solves); peers: one source per call (32 calls).")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10000, 50000, 200000])
    ap.add_argument("--surface", choices=("camelhead", "cylinder_patch"), default="camelhead",
                    help="camelhead.off midpoint-upsampled (strongly curved, MDS folds) or a generated developable "
                         "cylinder patch of about each size (MDS does not fold)")
    ap.add_argument("--slim-max", type=int, default=20000, help="largest mesh on which SLIM is run")
    ap.add_argument("--slim-iters", type=int, default=100)
    ap.add_argument("--geodesics-mesh", nargs="*", default=[str(SHARED / "beetle.off"), str(SHARED / "camelhead.off")],
                    help="meshes for the per-source geodesics comparison (beetle.off: 19.9k vertices); none: skip")
    ap.add_argument("--geodesics-only", action="store_true", help="only the per-source geodesics comparison")
    ap.add_argument("--raw-only", action="store_true",
                    help="scale table: only heatparam --refine none (and LSCM for the ratio), no default run, no SLIM")
    ap.add_argument("--repeats", type=int, default=1,
                    help="fresh-process runs of each heatparam row, and timed runs per geodesics process")
    ap.add_argument("--geodesics-processes", type=int, default=1, help="fresh processes per geodesics mesh")
    args = ap.parse_args()
    from heatparam.formats import save_uv_obj

    print(f"# Scale benchmark — {datetime.date.today()} — {machine()}\n")
    if not args.geodesics_only:
        scale_table(args, save_uv_obj)
    # bare names: shared meshes; cylinder_patch@N: a generated patch of about N vertices
    meshes = [m if Path(m).exists() or "@" in m else str(SHARED / m) for m in args.geodesics_mesh]
    geodesics_table(meshes, args.repeats, args.geodesics_processes)


STAGES = ("load", "validate", "fill decision", "operators", "factorize", "geodesics", "mds", "refine", "metrics",
          "save", "end_to_end")


def _levels_note(ml: dict) -> str:
    """The coarse levels of a refine report's ``multilevel`` entry, finest first."""
    parts = []
    while ml.get("used"):
        cp = ml["coarse_polish"]
        parts.append(f"coarse {ml['coarse_vertices']} vertices, {cp['iterations']} it {cp['seconds']:.1f} s, "
                     f"{ml['prolongation_flips']} prolongated faces flipped, repaired in {ml['repair_rounds']} "
                     f"round(s) ({ml.get('repair_weights', 'start layout')} weights)")
        ml = ml.get("coarse_multilevel") or {}
    return "; then ".join(parts)


def _heatparam_rows(path: Path, out: Path, options: dict, repeats: int) -> dict:
    """Run heatparam ``repeats`` times in fresh processes: the first run's fields, timings as lists."""
    runs = [run_isolated(HEATPARAM, {"mesh": str(path), "out": str(out), "options": options}) for _ in range(repeats)]
    bad = [r for r in runs if "error" in r]
    if bad:
        return bad[0]
    r = dict(runs[0])
    r["times"] = {k: [x["end_to_end"] if k == "end_to_end" else x.get(k, x["stages"].get(k)) for x in runs]
                  for k in STAGES if k in r or k in r["stages"]}
    r["peak_mb"] = max(x["peak_mb"] for x in runs)
    return r


def scale_table(args, save_uv_obj) -> None:
    print("| mesh | n | tool | seconds | ratio to LSCM | peak RSS MB | flips | crossings | iso mean | notes |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    stage_rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            if args.surface == "camelhead":
                V, F = upsampled_camelhead(size)
                label = "camelhead↑"
            else:
                from heatparam import datasets

                sh = datasets.cylinder_patch(h=0.04 * float(np.sqrt(2213 / size)))  # 2213 vertices at h = 0.04
                V, F, label = sh.V, sh.F, "cylinder_patch"
            path = Path(tmp) / f"{args.surface}{len(V)}.obj"
            save_uv_obj(path, V, F, np.zeros((len(V), 2)))
            lscm = run_isolated(PEER, {"mesh": str(path), "peer": "lscm"})
            rows = [("libigl LSCM", lscm, "")]
            out = Path(tmp) / "o.obj"
            raw = _heatparam_rows(path, out, {"refine": "none"}, args.repeats)
            rows[:0] = [("heatparam --refine none (end to end, I/O incl.)", raw, "")]
            stage_rows.append((len(V), raw))
            if not args.raw_only:
                hp = _heatparam_rows(path, out, {}, args.repeats)
                rows[:0] = [("heatparam default (end to end, I/O incl.)", hp, "")]
                if len(V) <= args.slim_max:
                    rows.append((f"libigl SLIM ({args.slim_iters} it, Tutte start)",
                                 run_isolated(PEER, {"mesh": str(path), "peer": "slim", "iters": args.slim_iters}),
                                 ""))
                else:
                    rows.append(("libigl SLIM", {"error": f"skipped above {args.slim_max} vertices"}, ""))
            for name, r, note in rows:
                if "error" in r:
                    print(f"| {label} | {len(V)} | {name} | — | — | — | — | — | — | {r['error']} |")
                    continue
                sec = float(np.median(r["times"]["end_to_end"])) if "times" in r else r["seconds"]
                ratio = sec / lscm["seconds"] if "seconds" in lscm else float("nan")
                if "stages" in r:
                    why = "coarse MDS folds" if "coarse mesh" in str(r["mode"]) else "LSCM start near-isometric"
                    heat_note = (f"heat stage skipped ({why})" if r["k"] is None
                                 else f"{r['mode']} k={r['k']}, {r['backend']}")
                    note = (f"{heat_note}; load {r['load']:.2f} s, save {r['save']:.2f} s; "
                            + ", ".join(f"{k} {v:.2f}" for k, v in r["stages"].items()))
                    pol = r.get("polish") or {}
                    if pol:
                        note += (f"; polish: {pol['iterations']} it, {pol['factorizations']} factorizations "
                                 f"({pol['backend']})")
                    ml = r.get("multilevel") or {}
                    if ml.get("used"):
                        note += "; coarse-to-fine: " + _levels_note(ml)
                    elif ml:
                        note += f"; single level ({ml.get('reason', '')})"
                    if len(r["times"]["end_to_end"]) > 1:
                        note = f"median of {len(r['times']['end_to_end'])} runs; first run: " + note
                print(f"| {label} | {len(V)} | {name} | {sec:.2f} | {ratio:.2f} | {r['peak_mb']:.0f} | {r['flips']} "
                      f"| {r['crossings']} | {r['iso']:.3f} | {note} |")
    if args.repeats > 1:
        print(f"\n### heatparam --refine none, seconds per stage: median [min-max] of {args.repeats} fresh processes\n")
        print("| n | " + " | ".join(STAGES) + " |")
        print("|---|" + "---|" * len(STAGES))
        for n, r in stage_rows:
            if "error" in r:
                continue
            print(f"| {n} | " + " | ".join(_spread(r["times"][k]) if k in r["times"] else "–" for k in STAGES) + " |")


if __name__ == "__main__":
    main()
