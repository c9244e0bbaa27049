"""Issue 17's benchmark set: parts of >= 150k vertices with holes, curvature and scan noise, end to end with I/O,
beside libigl LSCM in the same run.

Meshes (generated here from what the repo has; written to a temporary OBJ first):
  halftunnel_up   halftunnel.off midpoint-upsampled (igl.upsample) to >= 150k vertices (2 holes)
  camelhead_up    camelhead.off upsampled (strongly curved disk)
  beetle_up       beetle.off upsampled (10 holes; 316k vertices: the slowest, run it with --only beetle_up)
  cylinder_noisy  datasets.cylinder_with_holes at ~200k vertices, scanner noise 0.1 x the mean edge length
  cylinder_noisy02  the same with noise 0.2 x the mean edge length (the top of issue 17's range; its conformal
                  layout has 7 flipped faces)
  demo_up         the demo's noisy scan-like part (datasets.noisy_scan_part) generated at ~200k vertices

Each run is a fresh process (its own peak RSS): heatparam = ``heatparam.unwrap.unwrap_file`` (load, default options,
write the OBJ with vt); LSCM = load, ``igl.lscm`` with two boundary vertices pinned, write the OBJ with
``formats.save_uv_obj``. Prints a markdown table: seconds, ratio to LSCM, peak RSS, heatparam's stage seconds, the
polish's start (and, when the heat stage's MDS layout was computed but not usable, its flips and why) and Newton
iterations, iso mean / flips / boundary crossings of both maps.

Run: ``python bench/bench_large.py [--only NAME ...]``

``--family SEEDS`` (``1000-1019``, ``0,3,7`` or both mixed) runs issue 42's family instead (``large_family.draw``:
scan-like parts of 150k-400k faces drawn per seed; tune on seeds 0-99, report on 1000-1019, which nothing is tuned
on). Per part, written as binary PLY: heatparam end to end through the CLI (``heatparam unwrap part.ply -o out.obj
--report r.json``, default options, I/O included; peak RSS of the child from ``/usr/bin/time -v``); in another fresh
process ``igl.lscm`` with two pins (two far boundary vertices) on the part's largest edge-connected piece without
its zero-area faces, the solve alone timed (I/O excluded), then ``--slim-iters`` SLIM iterations (symmetric
Dirichlet) from LSCM scaled to true area where LSCM is flip-free (SLIM needs a flip-free start; none otherwise).
Prints one row per part, then the distribution: median and worst ratio to LSCM, peak memory, flips, crossings, and
iso mean against the best bijective of LSCM / SLIM. ``--jsonl FILE`` appends every part's measurements as a JSON
line.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import large_family
import numpy as np
from common import PEAK_RSS, SHARED, machine, run_isolated, seeds

OURS = PEAK_RSS + """
import json, time
t0 = time.perf_counter()
from heatparam.unwrap import unwrap_file
p = json.load(open(sys.argv[1]))
rep = unwrap_file(p["mesh"], [p["out"]], report=p["report"])
t1 = time.perf_counter()
r = json.load(open(p["report"]))
m = r["metrics"]
ref = r["method"].get("refine", {})
st = ref.get("start", {})
start = st.get("layout")
if start and st.get("flips", 0):  # the MDS layout was computed but not usable: say why
    start += f" (MDS: {st['flips']} flipped" + (f", {st['repair']['reason']}" if "repair" in st else "") + ")"
print(json.dumps({"seconds": t1 - t0, "peak_mb": peak_mb(), "iso": m["iso_mean"], "flips": m["flips"],
                  "crossings": m.get("boundary_crossings", 0), "stages": r.get("timings_s", {}),
                  "iterations": ref.get("polish", {}).get("iterations"), "start": start,
                  "seams": r["method"].get("seams", {}).get("used")}))
"""

LSCM = PEAK_RSS + """
import json, time
t0 = time.perf_counter()
import numpy as np, igl
from heatparam.formats import load_mesh, save_uv_obj
from heatparam import metrics
p = json.load(open(sys.argv[1]))
V, F = load_mesh(p["mesh"])
bnd = igl.boundary_loop(F)
uv = igl.lscm(V, F, np.array([bnd[0], bnd[len(bnd) // 2]]), np.array([[0.0, 0.0], [1.0, 0.0]]))
uv = np.asarray(uv[0] if isinstance(uv, tuple) else uv)
save_uv_obj(p["out"], V, F, uv)
t1 = time.perf_counter()
s = metrics.summary(V, F, uv)
print(json.dumps({"seconds": t1 - t0, "peak_mb": peak_mb(), "iso": s["iso_mean"], "flips": s["flips"],
                  "crossings": s["boundary_crossings"]}))
"""

PEER = PEAK_RSS + """
import json, time
import numpy as np, igl
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from heatparam.formats import load_mesh
from heatparam import metrics
p = json.load(open(sys.argv[1]))
V, F = load_mesh(p["mesh"])
d = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
F = F[d > 1e-12 * d.max()]  # zero-area faces would leave LSCM singular
E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
key = np.minimum(E[:, 0], E[:, 1]) * len(V) + np.maximum(E[:, 0], E[:, 1])
_, ek = np.unique(key, return_inverse=True)
m = len(F)
face = np.tile(np.arange(m), 3)
A = coo_matrix((np.ones(3 * m), (face, ek)), shape=(m, ek.max() + 1)).tocsr()
_, lab = connected_components(A @ A.T, directed=False)
F = F[lab == np.bincount(lab).argmax()]
used = np.unique(F)
remap = np.full(len(V), -1)
remap[used] = np.arange(len(used))
V, F = V[used], remap[F]
E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
n = len(V)
bnd = np.unique(E[~np.isin(E[:, 0] * n + E[:, 1], E[:, 1] * n + E[:, 0])])
b0 = bnd[0]
b1 = bnd[np.argmax(np.linalg.norm(V[bnd] - V[b0], axis=1))]
t0, c0 = time.perf_counter(), time.process_time()
uv = igl.lscm(V, F, np.array([b0, b1]), np.array([[0.0, 0.0], [1.0, 0.0]]))
t1, c1 = time.perf_counter(), time.process_time()
uv = np.asarray(uv[0] if isinstance(uv, tuple) else uv)
s = metrics.summary(V, F, uv)
out = {"seconds": t1 - t0, "cpu_s": c1 - c0, "faces": len(F), "iso": s["iso_mean"], "flips": s["flips"],
       "crossings": s["boundary_crossings"], "bijective": s["bijective"]}
if s["flips"] == 0 and p["slim_iters"] > 0:
    uv0 = uv * s["uv_scale"]
    t2 = time.perf_counter()
    data = igl.slim_precompute(V, F.astype(np.int32), uv0, igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                               np.zeros(0, np.int32), np.zeros((0, 2)))
    uvs = np.asarray(igl.slim_solve(data, p["slim_iters"]))[:, :2]
    t3 = time.perf_counter()
    q = metrics.summary(V, F, uvs)
    out.update(slim_seconds=t3 - t2, slim_iso=q["iso_mean"], slim_flips=q["flips"],
               slim_crossings=q["boundary_crossings"], slim_bijective=q["bijective"])
out["peak_mb"] = peak_mb()
print(json.dumps(out))
"""

NAMES = ["halftunnel_up", "camelhead_up", "cylinder_noisy", "cylinder_noisy02", "demo_up", "beetle_up"]


def _upsampled(name: str, target: int = 150_000):
    import igl

    from heatparam.formats import load_mesh

    V, F = load_mesh(SHARED / name)
    while len(V) < target:
        V, F = igl.upsample(V, F)
    return V, F


def make(name: str) -> tuple[np.ndarray, np.ndarray]:
    from heatparam import datasets

    if name.endswith("_up") and name != "demo_up":
        return _upsampled(name[:-3] + ".off")
    if name.startswith("cylinder_noisy"):
        s = datasets.cylinder_with_holes(h=0.045 * np.sqrt(2101 / 200_000))
        h = float(np.mean(np.linalg.norm(s.V[s.F[:, 1]] - s.V[s.F[:, 0]], axis=1)))
        noise = 0.2 if name == "cylinder_noisy02" else 0.1
        return s.V + noise * h * np.random.default_rng(0).standard_normal(s.V.shape), s.F
    s = datasets.noisy_scan_part(h=0.03 * np.sqrt(4800 / 200_000))
    return s.V, s.F


def _write_obj(path: str, V: np.ndarray, F: np.ndarray) -> None:
    with open(path, "w") as fh:
        fh.write("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist()))
        fh.write("".join(f"f {a} {b} {c}\n" for a, b, c in (F + 1).tolist()))


def run_cli(mesh: Path, tmp: Path) -> dict:
    """``heatparam unwrap mesh -o out.obj --report r.json`` in a child (default options): wall seconds, the child's
    peak RSS (``/usr/bin/time -v``, else none), and what the report says."""
    exe = Path(sys.executable).parent / "heatparam"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "heatparam"]
    cmd += ["unwrap", str(mesh), "-o", str(tmp / "out.obj"), "--report", str(tmp / "r.json")]
    timer = ["/usr/bin/time", "-v"] if shutil.which("/usr/bin/time") else []
    t0 = time.perf_counter()
    r = subprocess.run(timer + cmd, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if r.returncode != 0:
        return {"error": (r.stderr.strip().splitlines() or ["failed"])[-1][:200]}
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr)
    rep = json.loads((tmp / "r.json").read_text())
    m, method = rep["metrics"], rep.get("method", {})
    seams = _kept_seams(method)
    cpu = sum(float(x) for x in re.findall(r"(?:User|System) time \(seconds\): ([\d.]+)", r.stderr))
    # each pass of a stage as the progress lines name it ("refine (map with seams): 33.96 s"): what a trial cost
    passes = [[k, float(v)] for k, v in re.findall(r"^heatparam: ([^:]+): ([\d.]+) s$", r.stderr, re.M)]
    return {"seconds": seconds, "cpu_s": cpu or None, "peak_mb": int(rss.group(1)) / 1024 if rss else None,
            "iso": m["iso_mean"], "flips": m["flips"], "crossings": m.get("boundary_crossings", 0),
            "stages": rep.get("timings_s", {}), "passes": passes, "seams_reason": seams.get("reason", ""),
            "seams": "used" if seams.get("used") else ("tried" if "iso_mean_with" in seams else "no"),
            **_seam_levels(method)}


def _kept_seams(method: dict) -> dict:
    """The seams decision of the map that makes the part: a scan's main piece kept whole by the atlas (its own
    pipeline's: the atlas's top level says "charts of an atlas" for any scan), else the report's own."""
    atlas = method.get("atlas", {})
    scan = atlas.get("repair", {}).get("scan")
    if scan:
        return atlas["components"][scan["main_component"]].get("pipeline", {}).get("seams", {})
    return method.get("seams", {})


def _seam_levels(method: dict) -> dict:
    """The seams decision's inputs at both levels, where the report has them: fine iso means without / with seams,
    and the coarse levels' iso means of the kept map and (seams used) of the map without seams — whether a coarse
    comparison would have decided as the fine one did (issue 42's item 2)."""
    seams = _kept_seams(method)
    coarse = method.get("refine", {}).get("multilevel", {}).get("coarse_iso_mean")
    without = method.get("without_seams", {}).get("refine", {}).get("multilevel", {}).get("coarse_iso_mean")
    return {"iso_without": seams.get("iso_mean_without"), "iso_with": seams.get("iso_mean_with"),
            "coarse_iso_kept": coarse, "coarse_iso_without": without}


def _best_peer(peer: dict) -> tuple[str, float]:
    """The best bijective of LSCM / SLIM by iso mean: (name, iso), or ("none", inf)."""
    cands = [("LSCM", peer["iso"])] if peer.get("bijective") else []
    if peer.get("slim_bijective"):
        cands.append(("SLIM", peer["slim_iso"]))
    return min(cands, key=lambda c: c[1]) if cands else ("none", float("inf"))


def family_row(seed: int, desc: dict, ours: dict, peer: dict) -> str:
    """One markdown row of a family part."""
    name, best = _best_peer(peer)
    stages = ", ".join(f"{k} {v:.0f}" for k, v in ours["stages"].items() if v >= 1.0)
    slim = (f"{peer['slim_iso']:.4f} / {peer['slim_flips']} / {peer['slim_crossings']} ({peer['slim_seconds']:.0f} s)"
            if "slim_iso" in peer else "–")
    delta = f"{100 * (ours['iso'] / best - 1):+.2f}% vs {name}" if np.isfinite(best) else "no bijective peer"
    return (f"| {seed} | {desc['kind']} | {desc['faces']} | {desc.get('holes', desc.get('dropouts'))} | "
            f"{desc.get('noise', '')} | {', '.join(desc.get('defects', {})) or '–'} | {ours['seconds']:.1f} | "
            f"{peer['seconds']:.1f} | {ours['seconds'] / peer['seconds']:.1f}× | {ours['peak_mb']:.0f} | "
            f"{stages} | {ours['seams']} | {ours['iso']:.4f} / {ours['flips']} / {ours['crossings']} | "
            f"{peer['iso']:.4f} / {peer['flips']} / {peer['crossings']} | {slim} | {delta} |")


def family_summary(rows: list[dict]) -> str:
    """The distribution over the parts measured: ratio to LSCM (median, worst), peak memory, flips, crossings,
    iso mean against the best bijective peer."""
    ratios = np.array([r["ours"]["seconds"] / r["peer"]["seconds"] for r in rows])
    mem = np.array([r["ours"]["peak_mb"] or np.nan for r in rows])
    best = [_best_peer(r["peer"])[1] for r in rows]
    deltas = np.array([r["ours"]["iso"] / b - 1 for r, b in zip(rows, best, strict=True) if np.isfinite(b)])
    worst = rows[int(np.argmax(ratios))]["seed"]
    return (f"parts: {len(rows)}; ratio to LSCM median {np.median(ratios):.1f}×, worst {ratios.max():.1f}× (seed "
            f"{worst}); within 2×: {int((ratios <= 2).sum())}; peak RSS median {np.nanmedian(mem):.0f} MB, max "
            f"{np.nanmax(mem):.0f} MB; parts with flips {sum(r['ours']['flips'] > 0 for r in rows)}, with boundary "
            f"crossings {sum(r['ours']['crossings'] > 0 for r in rows)}; iso mean vs the best bijective peer: median "
            f"{100 * np.median(deltas) if len(deltas) else float('nan'):+.2f}%, worst "
            f"{100 * deltas.max() if len(deltas) else float('nan'):+.2f}% ({len(deltas)} parts with a bijective peer)"
            + _cpu_ratios(rows) + _not_kept(rows))


def not_kept_seconds(ours: dict) -> float:
    """Seconds spent on the map the seams stage did not keep, from the progress lines' passes: the map without
    seams when the cut map was kept, else the cut trial (cut, conformal start, its passes); 0 when none was tried."""
    if ours["seams"] == "used":
        return sum(s for name, s in ours["passes"] if "(map without seams" in name)
    if ours["seams"] == "tried":
        return sum(s for name, s in ours["passes"] if "(map with seams" in name or name.startswith("seams ("))
    return 0.0


def _not_kept(rows: list[dict]) -> str:
    """The seconds spent on maps not kept, over the parts where the seams stage made two maps."""
    t = np.array([not_kept_seconds(r["ours"]) for r in rows if r["ours"]["seams"] in ("used", "tried")])
    total = sum(r["ours"]["seconds"] for r in rows)
    return (f"; on maps not kept ({len(t)} parts with two maps): median {np.median(t):.1f} s, max {t.max():.1f} s, "
            f"{t.sum():.0f} of {total:.0f} s in all" if len(t) else "")


def _cpu_ratios(rows: list[dict]) -> str:
    """CPU seconds (user + system) of heatparam's child over LSCM's solve, less sensitive than wall time to what
    else the machine runs, where both were measured."""
    c = np.array([r["ours"]["cpu_s"] / r["peer"]["cpu_s"] for r in rows
                  if r["ours"].get("cpu_s") and r["peer"].get("cpu_s")])
    return f"; CPU-time ratio median {np.median(c):.1f}×, worst {c.max():.1f}×" if len(c) else ""


def run_family(spec: str, slim_iters: int, jsonl: str | None) -> None:
    """Issue 42's family: one row per seed, then the distribution."""
    print("| seed | kind | faces | holes | noise | defects | heatparam s | LSCM s | ratio | heatparam MB | stages (s) "
          "| seams | iso / flips / crossings (heatparam) | iso / flips / crossings (LSCM) | SLIM iso / flips / "
          "crossings | iso vs best bijective peer |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for seed in seeds(spec):
        V, F, desc = large_family.draw(seed)
        with tempfile.TemporaryDirectory() as tmp:
            mesh = Path(tmp) / f"part{seed}.ply"
            large_family.write_ply(mesh, V, F)
            del V, F
            ours = run_cli(mesh, Path(tmp))
            peer = run_isolated(PEER, {"mesh": str(mesh), "slim_iters": slim_iters})
        if "error" in ours or "error" in peer:
            print(f"| {seed} | {desc['kind']} | {desc['faces']} | failed: {ours.get('error') or peer.get('error')} "
                  "||||||||||||", flush=True)
            continue
        rows.append({"seed": seed, "desc": desc, "ours": ours, "peer": peer})
        print(family_row(seed, desc, ours, peer), flush=True)
        if jsonl:
            with open(jsonl, "a") as fh:
                fh.write(json.dumps(rows[-1]) + "\n")
    if rows:
        print("\n" + family_summary(rows))


def warm_compiled() -> None:
    """Compile numba's loops into its on-disk cache once, untimed: the first run in a fresh checkout or install
    compiles them (~12 s, measured on held-out seed 1000: 34 s against 22 s), which every later run loads."""
    code = ("import heatparam.atlas.grow, heatparam.atlas.overlap, heatparam.mesh.nest\n"
            "from heatparam.compiled import warm_all\nwarm_all()")
    subprocess.run([sys.executable, "-c", code], check=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, choices=NAMES)
    ap.add_argument("--family", default=None, help="issue 42's family: seeds such as 1000-1019 (held out) or 0-99")
    ap.add_argument("--slim-iters", type=int, default=5, help="SLIM iterations from LSCM in --family (0: none)")
    ap.add_argument("--jsonl", default=None, help="--family: append each part's measurements to this file")
    args = ap.parse_args()
    print(f"machine: {machine()}\n")
    warm_compiled()
    if args.family:
        run_family(args.family, args.slim_iters, args.jsonl)
        return
    print("| mesh | vertices | heatparam s | LSCM s | ratio | heatparam MB | LSCM MB | stages (s) | start "
          "| Newton its | seams | iso / flips / crossings (heatparam) | iso / flips / crossings (LSCM) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only or NAMES[:-1]:
            V, F = make(name)
            mesh = str(Path(tmp) / f"{name}.obj")
            _write_obj(mesh, V, F)
            ours = run_isolated(OURS, {"mesh": mesh, "out": str(Path(tmp) / "o.obj"),
                                       "report": str(Path(tmp) / "r.json")})
            peer = run_isolated(LSCM, {"mesh": mesh, "out": str(Path(tmp) / "l.obj")})
            if "error" in ours or "error" in peer:
                print(f"| {name} | {len(V)} | failed: {ours.get('error') or peer.get('error')} ||||||||||||")
                continue
            stages = ", ".join(f"{k} {v:.1f}" for k, v in ours["stages"].items() if v >= 0.5)
            print(f"| {name} | {len(V)} | {ours['seconds']:.1f} | {peer['seconds']:.1f} | "
                  f"{ours['seconds'] / peer['seconds']:.1f}× | {ours['peak_mb']:.0f} | {peer['peak_mb']:.0f} | "
                  f"{stages} | {ours['start']} | {ours['iterations']} | {ours['seams']} | "
                  f"{ours['iso']:.4f} / {ours['flips']} / {ours['crossings']} | "
                  f"{peer['iso']:.4f} / {peer['flips']} / {peer['crossings']} |", flush=True)


if __name__ == "__main__":
    main()
