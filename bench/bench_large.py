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
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from common import PEAK_RSS, SHARED, machine, run_isolated

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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, choices=NAMES)
    args = ap.parse_args()
    print(f"machine: {machine()}\n")
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
