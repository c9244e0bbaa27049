"""Progressive reference shapes (Liu et al. 2018) for the cut mesh's polish from Tutte: do they cut the
Newton iterations to a third?

Usage: ``python bench/bench_progressive.py [K ...]`` (default 2 4). beetle.off from ../shared/meshes, default options,
end to end (``heatparam.parameterize``); the polish of any layout whose energy is above 2 (the cut mesh's Tutte start)
is replaced by: outer iterations, each one Newton step (``refine.newton.polish``, max_iters=1) towards reference
triangles J_R = U Σ^(1-w) Vᵀ (J = U Σ Vᵀ the current map's Jacobian on the 3D triangle), w chosen so that the
95th percentile of the current map's distortion max(σ1, 1/σ2) relative to the reference is K, until that percentile
is below K; then the ordinary polish to convergence. Without K: today's polish. A markdown table on stdout.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from common import SHARED, machine

import heatparam
import heatparam.refine as refine_pkg
from heatparam.formats import load_mesh
from heatparam.operators import edge_lengths, local_triangles, mollify
from heatparam.refine import energy as E
from heatparam.refine.newton import polish

ORIGINAL = refine_pkg.multilevel_polish


def progressive(K: float, log: dict):
    def run(V, F, x, loops, g, area, settings, **kw):
        if E.normalized_energy(x, F, g, area) < 2.0:
            return ORIGINAL(V, F, x, loops, g, area, settings, **kw)
        raw = edge_lengths(V, F)
        P = local_triangles(mollify(raw, 1e-4 * float(raw.mean()))[0])
        outer, t0 = 0, time.perf_counter()
        while outer < 40:
            U, s, Vr = E.svd2(E.jacobians(x, F, g))
            D = float(np.percentile(np.maximum(s[:, 0], 1 / s[:, 1]), 95))
            if D <= K:
                break
            w = np.log(K) / np.log(D)
            JR = np.matmul(U * (s ** (1 - w))[:, None, :], Vr.transpose(0, 2, 1))
            gR = E.hat_gradients(np.einsum("mab,mib->mia", JR, P))
            x, _ = polish(x, F, gR, area, loops, max_iters=1, tol=settings.tol, backend=settings.backend)
            outer += 1
        log.update(outer=outer, outer_s=time.perf_counter() - t0)
        return ORIGINAL(V, F, x, loops, g, area, settings, **kw)
    return run


def main(argv: list[str]) -> None:
    ks = [float(a) for a in argv] or [2.0, 4.0]
    V, F = load_mesh(SHARED / "beetle.off")
    print(f"machine: {machine()}\n")
    print("| polish of the cut mesh | outer steps | final Newton iterations | total | energy | iso mean | bijective "
          "| end to end s |")
    print("|---|---|---|---|---|---|---|---|")
    for K in [None, *ks]:
        log: dict = {}
        refine_pkg.multilevel_polish = ORIGINAL if K is None else progressive(K, log)
        t = time.perf_counter()
        r = heatparam.parameterize(V, F)
        s = time.perf_counter() - t
        pol = r.report["method"]["refine"]["polish"]
        m = r.report["metrics"]
        name = "today (Tutte start)" if K is None else f"progressive, K = {K:g}"
        outer = log.get("outer", 0)
        print(f"| {name} | {outer} | {pol['iterations']} | {outer + pol['iterations']} | {pol['energy_end']:.5f} "
              f"| {m['iso_mean']:.4f} | {m['bijective']} | {s:.1f} |", flush=True)
    refine_pkg.multilevel_polish = ORIGINAL


if __name__ == "__main__":
    main(sys.argv[1:])
