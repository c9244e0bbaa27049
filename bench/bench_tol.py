"""The refinement's stopping tolerance (``refine_tol``) against time and map quality. A markdown table on stdout.

Usage: ``python bench/bench_tol.py`` — camelhead, beetle and halftunnel (../shared/meshes), camelhead.off upsampled
to ~182k vertices, and a generated cylinder patch of ~196k vertices with Gaussian noise of 0.05 and 0.1 × the mean
edge length, each at ``refine_tol`` 1e-6 (the default) and 1e-5: seconds of ``parameterize``, the last polish's
Newton iterations, its symmetric Dirichlet energy (per area / 4), iso mean and 95th percentile.
"""

from __future__ import annotations

import time

from common import load, machine, noisy_cylinder_patch, upsampled_camelhead

from heatparam import pipeline

TOLS = (1e-6, 1e-5)


def main() -> None:
    cases = [(name, *load(name)[:2]) for name in ("camelhead.off", "beetle.off", "halftunnel.off")]
    cases.append(("camelhead↑182k", *upsampled_camelhead(200_000)))
    cases.append(("cylinder_patch 196k, noise 0.05 h", *noisy_cylinder_patch(200_000, 0.05, 2)[:2]))
    cases.append(("cylinder_patch 196k, noise 0.1 h", *noisy_cylinder_patch(200_000, 0.1, 3)[:2]))
    print(f"# Refinement tolerance — {time.strftime('%Y-%m-%d')} — {machine()}\n")
    print("| mesh | refine_tol | s | Newton it (last level) | SD energy | iso mean | iso p95 |")
    print("|---|---|---|---|---|---|---|")
    for name, V, F in cases:
        for tol in TOLS:
            t = time.perf_counter()
            _, rep = pipeline.parameterize(V, F, refine_tol=tol)
            dt = time.perf_counter() - t
            pol, m = rep["method"]["refine"]["polish"], rep["metrics"]
            print(f"| {name} | {tol:g} | {dt:.2f} | {pol['iterations']} | {pol['energy_end']:.7f} | "
                  f"{m['iso_mean']:.5f} | {m['iso_p95']:.5f} |", flush=True)


if __name__ == "__main__":
    main()
