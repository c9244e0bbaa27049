"""PARDISO's parallel factorization control (iparm 24, 1-based): the classic algorithm (0, MKL's default) against
the improved two-level one (10) on the large systems of issue 17 (BENCHMARKS §23f).

The matrices: camelhead.off upsampled to >= 150k vertices (as ``bench_large.py``'s camelhead_up): its conformal
energy Q + εB (``layout.conformal``: what the spectral conformal layout factorizes) and the polish's Hessian at
that layout (``refine.newton.HessianPattern``, the upper triangle PARDISO reads, no scaffold: a fine level's first
Hessian). For each: METIS's analysis (PARDISO's own ordering), a factorization, a solve, a refactorization with new
values on the same pattern and a solve, twice each in fresh solvers (the least time), and whether both solvers
gave the same bits; then the same with METIS's permutation given (iparm 5 = 1), as a new analysis of a changed
pattern gets it.

Usage: ``python bench/bench_pardiso.py [--target N]`` (vertices, default 150000).
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np
import scipy.sparse as sp
from common import machine, upsampled_camelhead


def matrices(target: int) -> dict[str, sp.csr_matrix]:
    from heatparam.layout.conformal import SCP_SHIFT, _conformal_energy, spectral_conformal
    from heatparam.refine.energy import jacobians, surface_gradients
    from heatparam.refine.newton import HessianPattern

    V, F = upsampled_camelhead(target)
    Q, mass, _ = _conformal_energy(V, F)
    B = np.concatenate([mass, mass])
    eps = SCP_SHIFT * np.abs(Q.diagonal()).mean() / mass[mass > 0].mean()  # spectral_conformal's shift
    uv, _ = spectral_conformal(V, F)
    g, area = surface_gradients(V, F)
    pat = HessianPattern(F, len(V), upper=True)
    _, H = pat.assemble(jacobians(uv, F, g), g, area / area.sum())
    H = (H + sp.diags(1e-9 * H.diagonal().mean() * np.ones(H.shape[0]))).tocsr()
    return {f"conformal Q + εB ({len(V)} vertices)": sp.triu(Q + sp.diags(eps * B), format="csr"),
            "Hessian at the conformal layout": sp.triu(H, format="csr")}


def run(T: sp.csr_matrix, iparm24: int, perm: np.ndarray | None) -> tuple[dict, bytes, np.ndarray]:
    import pypardiso

    from heatparam import solvers

    n = T.shape[0]
    b = np.random.default_rng(0).standard_normal(n)
    T2 = (T + sp.diags(0.01 * T.diagonal())).tocsr()  # new values on the same pattern
    T2.sort_indices()
    f = pypardiso.PyPardisoSolver(mtype=2)
    f.iparm[:] = solvers._pardiso_defaults(pypardiso)
    f.iparm[7], f.iparm[1], f.iparm[23] = 0, 3, iparm24
    f.perm, f.iparm[4] = (np.zeros(n, dtype=np.int32), 2) if perm is None else (perm.copy(), 1)
    out = {}
    for phase, A, name in ((11, T, "analysis"), (22, T, "factorization"), (33, T, "solve"),
                           (22, T2, "refactorization"), (33, T2, "solve again")):
        f.set_phase(phase)
        t = time.perf_counter()
        x = f._call_pardiso(A, b if phase == 33 else np.zeros((n, 1)))
        out[name] = time.perf_counter() - t
    resid = float(np.linalg.norm(T2 @ x + T2.T @ x - T2.diagonal() * x - b) / np.linalg.norm(b))
    out["residual"] = resid
    new_perm = f.perm.copy()
    f.free_memory(everything=True)
    return out, x.tobytes(), new_perm


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--target", type=int, default=150_000)
    args = ap.parse_args()
    from heatparam import solvers

    solvers.prepare_mkl()
    print(f"machine: {machine()}\n")
    print("| matrix | unknowns | ordering | iparm 24 | analysis s | factorization s | solve s | refactorization s "
          "| solve s | residual | same bits twice |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, T in matrices(args.target).items():
        T.sort_indices()
        _, _, metis = run(T, 0, None)
        for given in (False, True):
            for ip in (0, 10):
                (a, xa, _), (b, xb, _) = (run(T, ip, metis if given else None) for _ in range(2))
                t = {k: min(a[k], b[k]) for k in a}
                print(f"| {name} | {T.shape[0]} | {'METIS given' if given else 'its own METIS'} | {ip} | "
                      f"{t['analysis']:.3f} | {t['factorization']:.3f} | {t['solve']:.3f} | "
                      f"{t['refactorization']:.3f} | {t['solve again']:.3f} | {a['residual']:.1e} | "
                      f"{'yes' if hashlib.sha1(xa).digest() == hashlib.sha1(xb).digest() else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
