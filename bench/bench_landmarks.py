"""Issue 4: choose the landmark count k and the all-pairs threshold by the measured error/time trade-off.

Raw MDS maps (fill none, refine none). For the cylinder patch (known flat layout) and a flat square: mean
isometric distortion and true-scale layout error for all-pairs and for k landmarks; for camelhead↑ meshes the
geodesic stage time for each k.

Run: python bench/bench_landmarks.py
"""

from __future__ import annotations

import datetime
import time

from common import machine, upsampled_camelhead

from heatparam import datasets, metrics
from heatparam.pipeline import parameterize

KS = (25, 50, 100, 200, 400)


def main() -> None:
    print(f"# Landmark count trade-off — {datetime.date.today()} — {machine()}\n")
    print("| mesh | n | geodesics | k | iso mean | layout error / diameter | geodesics s | total s |")
    print("|---|---|---|---|---|---|---|---|")
    for sh in (datasets.cylinder_patch(), datasets.flat_square()):
        for mode, k in [("all-pairs", 0)] + [("landmarks", k) for k in KS]:
            t0 = time.perf_counter()
            uv, rep = parameterize(sh.V, sh.F, geodesics=mode, landmarks=k, fill="none", refine="none")
            tt = time.perf_counter() - t0
            err = metrics.layout_error(uv, sh.uv_true)
            print(f"| {sh.name} | {len(sh.V)} | {mode} | {rep['parameters']['landmarks_used']} | "
                  f"{rep['metrics']['iso_mean']:.4f} | {err:.4f} | {rep['timings_s']['geodesics']:.2f} | {tt:.2f} |")
    for target in (50000, 200000):
        V, F = upsampled_camelhead(target)
        for k in (100, 200, 400):
            t0 = time.perf_counter()
            _, rep = parameterize(V, F, geodesics="landmarks", landmarks=k, fill="none", refine="none")
            tt = time.perf_counter() - t0
            print(f"| camelhead↑ | {len(V)} | landmarks | {k} | {rep['metrics']['iso_mean']:.3f} | n/a | "
                  f"{rep['timings_s']['geodesics']:.2f} | {tt:.2f} |")


if __name__ == "__main__":
    main()
