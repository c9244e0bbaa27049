"""Issue 4: choose the sparse backend by measurement — factorization and multi-column solve times.

For the two systems heatparam factorizes (heat: t·L + B; Poisson: L with one vertex pinned), on camelhead
upsampled to ~45k vertices, solve 64 right-hand sides at once. Also reports whether CHOLMOD through
scikit-sparse is importable (it needs SuiteSparse headers to build; it is not a dependency).

Second table: heat-method geodesic time per source on beetle.off by batch width (``heat.MAX_BLOCK``, columns
per multi-column solve), the runs interleaved and repeated (median [min-max]), to choose MAX_BLOCK.

``--conformal``: instead, the spectral conformal layout (``layout.conformal.spectral_conformal``: one factorization
of Q + εB, 2 unknowns per vertex, and its Krylov solves) with each backend on ``datasets.cylinder_with_holes`` from
1k to 330k vertices, the runs interleaved and repeated (median), to choose ``conformal.SCP_PARDISO_MIN_UNKNOWNS``.

Run: python bench/bench_solvers.py [--target 45000] [--blocks 8 16 32 64] [--repeats 5] [--conformal]
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import time

import numpy as np
from common import SHARED, machine, upsampled_camelhead

from heatparam import heat
from heatparam.formats import load_mesh
from heatparam.heat import time_step
from heatparam.operators import build_operators
from heatparam.solvers import Factor, available_backends


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--target", type=int, default=45000)
    ap.add_argument("--rhs", type=int, default=64)
    ap.add_argument("--blocks", type=int, nargs="*", default=[8, 16, 32, 64])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--block-mesh", default=str(SHARED / "beetle.off"))
    ap.add_argument("--conformal", action="store_true", help="the conformal layout's time by backend and size")
    args = ap.parse_args()
    if args.conformal:
        conformal_table(min(args.repeats, 3))
        return
    V, F = upsampled_camelhead(args.target)
    op = build_operators(V, F)
    heat = (time_step(op) * op.L + op.B).tocsc()
    poisson = op.L[1:, 1:].tocsc()
    rng = np.random.default_rng(0)
    print(f"# Sparse backends — {datetime.date.today()} — {machine()}\n")
    print(f"camelhead↑ {len(V)} vertices, {args.rhs} right-hand sides per solve call\n")
    print("| backend | system | factorize s | solve s (all columns) | ms per column | max residual |")
    print("|---|---|---|---|---|---|")
    for backend in available_backends():
        for name, A in (("heat tL+B", heat), ("Poisson L", poisson)):
            b = rng.standard_normal((A.shape[0], args.rhs))
            t0 = time.perf_counter()
            f = Factor(A, backend)
            t1 = time.perf_counter()
            f.solve(b[:, :2])  # warm-up (threads, first touch)
            t2 = time.perf_counter()
            x = f.solve(b)
            t3 = time.perf_counter()
            res = np.abs(A @ x - b).max() / np.abs(b).max()
            per = (t3 - t2) / args.rhs * 1e3
            print(f"| {backend} | {name} | {t1 - t0:.3f} | {t3 - t2:.3f} | {per:.2f} | {res:.1e} |")
    sks = importlib.util.find_spec("sksparse") is not None
    print(f"\nscikit-sparse (CHOLMOD) importable here: {sks}")
    if args.blocks:
        block_table(args.block_mesh, args.blocks, args.repeats)


def block_table(mesh: str, blocks: list[int], repeats: int, sources: int = 256) -> None:
    """Per-source geodesic time by batch width; each repeat runs every width once (interleaved, same load)."""
    V, F = load_mesh(mesh)
    op = build_operators(V, F)
    src = np.linspace(0, len(V) - 1, sources).astype(np.int64)
    solvers = {}
    for b in blocks:
        solvers[b] = heat.HeatGeodesics(op, time_step(op), block_bytes=float("inf"))
        solvers[b].block = b
        solvers[b].distances(src[:8])  # warm-up
    per = {b: [] for b in blocks}
    for _ in range(repeats):
        for b in blocks:
            t0 = time.perf_counter()
            solvers[b].distances(src)
            per[b].append((time.perf_counter() - t0) / sources * 1e3)
    print(f"\n## Geodesics per source by batch width — {mesh.split('/')[-1]}, {len(V)} vertices, {sources} sources, "
          f"{repeats} interleaved repeats (backend {solvers[blocks[0]].backend}; default MAX_BLOCK {heat.MAX_BLOCK})\n")
    print("| columns per batch | ms per source: median | min | max |")
    print("|---|---|---|---|")
    for b in blocks:
        print(f"| {b} | {np.median(per[b]):.2f} | {min(per[b]):.2f} | {max(per[b]):.2f} |")


def conformal_table(repeats: int) -> None:
    """The spectral conformal layout's seconds with CHOLMOD (cholespy) and PARDISO, by mesh size."""
    from heatparam import datasets
    from heatparam.layout.conformal import spectral_conformal

    if "pardiso" not in available_backends():
        print("PARDISO (pypardiso) is not installed here: nothing to compare")
        return
    print(f"# The conformal layout by backend — {datetime.date.today()} — {machine()}\n")
    print(f"datasets.cylinder_with_holes(h), spectral_conformal (krylov), median of {repeats} interleaved runs\n")
    print("| vertices | unknowns | solves | cholespy s | pardiso s | cholespy / pardiso |")
    print("|---|---|---|---|---|---|")
    for h in (0.06, 0.03, 0.02, 0.016, 0.013, 0.011, 0.008, 0.006, 0.0042, 0.0035):
        s = datasets.cylinder_with_holes(h=h)
        secs: dict[str, list[float]] = {"cholespy": [], "pardiso": []}
        for _ in range(repeats):
            for backend in secs:
                t0 = time.perf_counter()
                _, solves = spectral_conformal(s.V, s.F, backend)
                secs[backend].append(time.perf_counter() - t0)
        c, p = (float(np.median(secs[b])) for b in ("cholespy", "pardiso"))
        print(f"| {len(s.V)} | {2 * len(s.V)} | {solves} | {c:.3f} | {p:.3f} | {c / p:.2f} |", flush=True)


if __name__ == "__main__":
    main()
