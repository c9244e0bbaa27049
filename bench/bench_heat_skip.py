"""Is the heat stage worth computing on large meshes whose conformal layout is bijective? (``mds_start`` rule (b),
``options.CONFORMAL_START_MIN_VERTICES``.)

Each part is flattened with ``mds_start="always"`` (the heat stage computed; the lower-energy bijective start wins)
and with the default (``auto``: on these parts the heat stage is skipped when the conformal layout is bijective),
in this process, one after the other: seconds, the kept map's start and energies, Newton iterations of the kept
map's polish, iso mean, flips, seams.

Parts (generated here, 38k-78k vertices): beetle.off upsampled once, halftunnel.off upsampled three times, a
cylinder patch with scanner noise 0.05 / 0.1 / 0.2 × the edge length, the demo's noisy part at ~49k.

Run: ``python bench/bench_heat_skip.py [--only NAME ...]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import SHARED, machine


def cases():
    import igl

    from heatparam import datasets
    from heatparam.formats import load_mesh

    V, F = load_mesh(SHARED / "beetle.off")
    yield "beetle_up78k", *igl.upsample(V, F)
    V, F = load_mesh(SHARED / "halftunnel.off")
    for _ in range(3):
        V, F = igl.upsample(V, F)
    yield "halftunnel_up50k", V, F
    s = datasets.cylinder_patch(h=0.045 * np.sqrt(2213 / 49000))
    h = float(np.mean(np.linalg.norm(s.V[s.F[:, 1]] - s.V[s.F[:, 0]], axis=1)))
    for noise in (0.05, 0.1, 0.2):
        yield f"cylinder_noise{noise}", s.V + noise * h * np.random.default_rng(0).standard_normal(s.V.shape), s.F
    s = datasets.noisy_scan_part(h=0.03 * np.sqrt(4800 / 50_000))
    yield "demo_part_50k", s.V, s.F


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="*", default=None)
    args = ap.parse_args()
    import heatparam

    print(f"machine: {machine()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")
    print("| part | vertices | mds_start | s | heat stage | start (energies) | Newton its | iso mean | flips | seams |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, V, F in cases():
        if args.only and name not in args.only:
            continue
        for mode in ("always", "auto"):
            t = time.perf_counter()
            r = heatparam.parameterize(np.asarray(V), np.asarray(F), mds_start=mode)
            dt = time.perf_counter() - t
            ref = r.report["method"]["refine"]
            st = ref["start"]
            en = ", ".join(f"{k} {v:.4f}" for k, v in (st.get("energy") or {}).items())
            heat = "skipped" if str(r.report["method"]["geodesics"]).startswith("skipped") else "ran"
            seams = (r.report["method"].get("seams") or {}).get("used")
            print(f"| {name} | {len(V)} | {mode} | {dt:.1f} | {heat} | {st.get('layout')} ({en}) | "
                  f"{ref['polish']['iterations']} | {r.report['metrics']['iso_mean']:.6f} | "
                  f"{r.report['metrics']['flips']} | {seams} |", flush=True)


if __name__ == "__main__":
    main()
