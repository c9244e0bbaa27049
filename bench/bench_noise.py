"""Scan noise: which start wins the refinement, and does ``--mds-start auto`` keep the map? A markdown table.

Usage: ``python bench/bench_noise.py [vertices]`` (default 50000).
A generated cylinder patch of about that many vertices (developable, known flat layout) with Gaussian noise of
σ = 0, 0.02, 0.05, 0.1, 0.2 × the mean edge length added to every vertex coordinate (seeded), as a scanner would.
For each: the refinement's start energies (symmetric Dirichlet per area / 4, 1 = isometry) of the MDS and
conformal layouts (the spectral map since 2026-12-02, LSCM with two pins before) and the one chosen, Newton
iterations, iso mean, true-scale layout error (``metrics.layout_error`` against the noise-free flat layout),
seconds with ``--mds-start always`` and with the default ``auto`` (and what ``auto`` skipped), and whether both
maps are bit-identical.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from common import machine, noisy_cylinder_patch

from heatparam import metrics, pipeline

NOISE = (0.0, 0.02, 0.05, 0.1, 0.2)


def main() -> None:
    target = int(sys.argv[1]) if len(sys.argv) > 1 else 50_000
    V0, F, uv_true = noisy_cylinder_patch(target, 0.0, 0)
    h = float(np.mean(np.linalg.norm(V0[F[:, 1]] - V0[F[:, 0]], axis=1)))
    print(f"# Scan noise on a developable part — {time.strftime('%Y-%m-%d')} — {machine()}\n")
    print(f"cylinder_patch, {len(V0)} vertices, mean edge h = {h:.4g}; noise σ per coordinate.\n")
    print("| σ / h | E start MDS | E start conformal | start | Newton it | iso mean | layout err | s always | s auto | "
          "auto skipped | same map |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for draw, sig in enumerate(NOISE):
        V, _, _ = noisy_cylinder_patch(target, sig, draw)
        t = time.perf_counter()
        uv, rep = pipeline.parameterize(V, F, mds_start="always")
        t_always = time.perf_counter() - t
        t = time.perf_counter()
        uv2, rep2 = pipeline.parameterize(V, F)
        t_auto = time.perf_counter() - t
        r = rep["method"]["refine"]
        e = r["start"].get("energy", {})
        e_mds, e_lscm = (f"{e[k]:.6f}" if k in e else "not bijective" for k in ("mds", "conformal"))
        skipped = rep2["method"]["geodesics"]
        why = ("nothing" if not skipped.startswith("skipped") else
               "heat stage (large, conformal bijective)" if "vertices, where" in skipped else
               "heat stage (conformal near-isometric)")
        print(f"| {sig:g} | {e_mds} | {e_lscm} | {r['start']['layout']} | {r['polish']['iterations']} | "
              f"{rep['metrics']['iso_mean']:.5f} | {metrics.layout_error(uv, uv_true):.2e} | {t_always:.2f} | "
              f"{t_auto:.2f} | {why} | {'yes' if np.array_equal(uv, uv2) else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
