"""The conformal layout (the fill's provisional layout and the refinement's conformal start candidate): the spectral
conformal map without pins (``layout.conformal.conformal_layout``, Mullen et al. 2008) against LSCM with two far
boundary vertices pinned (``igl.lscm``, the layout used before 2026-12-02), on the same meshes in the same run; the
spectral map solved both ways (``spectral_conformal``'s ``method``: ``inverse`` iteration, and ``krylov``, Rayleigh-Ritz
on the block Krylov space of [x, J x]; the pipeline uses ``krylov`` except on the seams stage's cut-open meshes).

For each mesh (and, when it has holes, the seams stage's cut-open mesh): the start candidate's judgement
(``refine.start.lscm_start``: flipped faces, boundary crossings, energy per area / 4 with 1 = isometry, only when
bijective), the layout's bounding box against the true flat layout's where one is known, and seconds.

Run: ``python bench/bench_conformal.py [--large] [--only NAME ...]`` (``--large``: also the >= 150k parts of
bench_large.py)
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import SHARED, machine

MESHES = ["camelhead.off", "halftunnel.off", "beetle.off", "bump-domain.obj", "woody.obj"]
SHAPES = ["cylinder_patch", "cylinder_with_holes", "cone_s_strip", "curved_cap_with_holes", "noisy_scan_part"]
LARGE = ["cylinder_noisy", "demo_up", "camelhead_up", "halftunnel_up", "beetle_up"]


def cases(large: bool, only: list[str] | None):
    from heatparam import datasets
    from heatparam.formats import load_mesh

    for m in MESHES:
        if not only or m in only:
            yield m, *load_mesh(SHARED / m)
    for s in SHAPES:
        if not only or s in only:
            sh = getattr(datasets, s)()
            yield s, sh.V, sh.F
    if large:
        from bench_large import make

        for name in LARGE:
            if not only or name in only:
                yield name, *make(name)


def pinned_lscm(V: np.ndarray, F: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """igl.lscm with outer[0] and the outer vertex farthest from it pinned, scaled to the 3D area and centred."""
    import igl

    from heatparam.mesh.planar import signed_areas
    from heatparam.mesh.topology import face_areas

    a = int(outer[0])
    b = int(outer[np.argmax(np.linalg.norm(V[outer] - V[a], axis=1))])
    uv, _ = igl.lscm(V, F, np.array([a, b]), np.array([[0.0, 0.0], [1.0, 0.0]]))
    uv = np.asarray(uv, dtype=np.float64)
    s = signed_areas(uv, F).sum()
    if s < 0:
        uv[:, 1] *= -1
    return uv * np.sqrt(face_areas(V, F).sum() / abs(s))  # not centred: that changes no judgement


def judge(V, F, uv) -> str:
    from heatparam.refine.start import lscm_start

    st = lscm_start(V, F, lambda: uv)
    e = "—" if st.energy is None else f"{st.energy:.5f}"
    return f"{e} | {st.flips} | {max(st.crossings, 0)}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--large", action="store_true")
    ap.add_argument("--only", nargs="*")
    args = ap.parse_args()
    from heatparam.layout.conformal import conformal_layout
    from heatparam.mesh.seams import cut_open, hole_seams
    from heatparam.pipeline.surface import Surface

    print(f"machine: {machine()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")
    print("| mesh | vertices | LSCM 2 pins: energy | flips | crossings | s | spectral, inverse iteration: energy | "
          "flips | crossings | s | solves | spectral, Krylov: energy | flips | crossings | s | solves | layouts differ "
          "(of the extent) |")
    print("|---" * 17 + "|")
    for name, V, F in cases(args.large, args.only):
        s = Surface.validated(V, F)[0]
        variants = [(name, s)]
        if s.info.n_holes:
            Vc, Fc, _ = cut_open(s.V, s.F, hole_seams(s.V, s.F, s.info.boundary_loops))
            variants.append((f"{name} (cut open)", Surface.validated(Vc, Fc)[0]))
        for label, sf in variants:
            t = time.perf_counter()
            ul = pinned_lscm(sf.V, sf.F, sf.info.boundary_loops[0])
            tl = time.perf_counter() - t
            cells, uvs = [], []
            for method in ("inverse", "krylov"):
                solves = _count_solves()
                t = time.perf_counter()
                us = conformal_layout(sf.V, sf.F, method=method)
                ts = time.perf_counter() - t
                uvs.append(us)
                cells.append(f"{judge(sf.V, sf.F, us)} | {ts:.2f} | {solves()}")
            diff = np.abs(uvs[0] - uvs[1]).max() / np.ptp(uvs[0], axis=0).max()
            print(f"| {label} | {len(sf.V)} | {judge(sf.V, sf.F, ul)} | {tl:.2f} | {cells[0]} | {cells[1]} | "
                  f"{diff:.1e} |", flush=True)


def _count_solves():
    """Count the solves of the next spectral conformal layout (wraps ``solvers.Factor.solve`` until read)."""
    from heatparam import solvers

    orig = solvers.Factor.solve
    n = [0]

    def solve(self, *a, **k):
        n[0] += 1
        return orig(self, *a, **k)

    solvers.Factor.solve = solve

    def read() -> int:
        solvers.Factor.solve = orig
        return n[0]

    return read


if __name__ == "__main__":
    main()
