"""Atlases of closed, higher-genus and strongly curved meshes: heatparam's atlas stage vs xatlas vs uvunwrap vs
libigl (cut_to_disk + Tutte + SLIM), in the same run, judged by the same independent checks: a markdown table.

Usage: ``python bench/bench_atlas.py [--slim-iters N] [--repeat R] [name ...]`` (../shared/meshes files or the closed
generated datasets closed_cube, capped_cylinder, cone_with_base, torus).
Columns: charts; seam length / sqrt(3D area) (interior mesh edges whose sides have different UV rows, each once);
iso mean and p95 (``metrics.distortion``: area-weighted max(s1, 1/s2) after one global area scale; flipped faces
count as inf in p95); flips; overlapping triangle pairs (``atlas.overlap``, exact); faces of zero UV area; packing
efficiency (UV triangle area / area of the atlas's bounding rectangle); seconds (wall, this process, after one
untimed warm-up call of every method on the generated torus: imports and the libraries' first-call loading, e.g.
MKL's, are left out for all three, as xatlas's import always was; until 2026-12-03 heatparam's first mesh paid them;
with ``--repeat R`` each method runs R times on each mesh, the least seconds reported, the rest from the first run).
heatparam runs with defaults (true-scale packing), open meshes with ``max_distortion=1.05``; xatlas 0.0.11 with
its default options; uvunwrap (pip, Rust) with its defaults (``uvunwrap.generate``, 1024² page, shape packing);
libigl: ``igl.cut_to_disk`` (a genus-0 closed mesh gets no cut from it: it is slit along
the shortest path between two far vertices), ``igl.cut_mesh``, Tutte start, SLIM symmetric Dirichlet
(``--slim-iters``, default 100). Flips are faces whose UV orientation disagrees with the atlas's majority: xatlas
can mirror whole charts, which counts here (a mirrored texture on that chart).
"""

from __future__ import annotations

import sys
import time

import igl
import numpy as np
from common import SHARED, machine

from heatparam import datasets, formats
from heatparam.atlas.chart_seams import seam_length
from heatparam.atlas.overlap import count_overlaps, uv_degenerate_faces
from heatparam.mesh import cut_open
from heatparam.metrics import distortion
from heatparam.pipeline import parameterize_disk
from heatparam.pipeline.atlas_stage import atlas

CLOSED = ["cow.off", "stanford-bunny.obj", "3holes.off", "stanford-dragon-res3.ply"]
OPEN = ["camelhead.off", "beetle.off", "halftunnel.off"]
GENERATED = ["closed_cube", "capped_cylinder", "cone_with_base", "torus"]


def load(name):
    if hasattr(datasets, name):
        return getattr(datasets, name)()
    return formats.load_mesh(SHARED / name)


def judge(V, F, uv, Fuv, charts, seconds):
    d = distortion(V, F, uv, Fuv)
    A3 = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()
    T = uv[Fuv]
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    auv = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    ext = uv[np.unique(Fuv)].max(axis=0) - uv[np.unique(Fuv)].min(axis=0)
    return {"charts": charts, "seam": seam_length(V, F, Fuv) / np.sqrt(A3), "iso_mean": d["iso_mean"],
            "iso_p95": d["iso_p95"], "flips": d["flips"], "overlaps": count_overlaps(uv, Fuv),
            "collapsed": int(uv_degenerate_faces(uv, Fuv).sum()), "packing": auv / max(ext.prod(), 1e-300),
            "seconds": seconds}


def run_ours(V, F, name):
    t = time.perf_counter()
    res = atlas(V, F, parameterize_disk, max_distortion=1.05 if name in OPEN else None)
    s = time.perf_counter() - t
    return judge(V, F, res.uv, res.Fuv, res.report["totals"]["charts"], s)


def run_xatlas(V, F):
    import xatlas

    t = time.perf_counter()
    at = xatlas.Atlas()
    at.add_mesh(V.astype(np.float32), F.astype(np.uint32))
    at.generate()
    vmap, idx, uvs = at[0]
    s = time.perf_counter() - t
    idx = idx.astype(np.int64)
    Fx = vmap.astype(np.int64)[idx]
    if not np.array_equal(Fx, F):  # xatlas keeps faces in order; judge its own corners if not
        F = Fx
    return judge(V, F, uvs.astype(np.float64), idx, int(at.chart_count), s)


def run_uvunwrap(V, F):
    import uvunwrap

    t = time.perf_counter()
    at = uvunwrap.generate([uvunwrap.Mesh(np.ascontiguousarray(V, dtype=np.float32),
                                          np.ascontiguousarray(F, dtype=np.uint32))])
    s = time.perf_counter() - t
    m = at.meshes[0]
    uv = np.asarray(m.uv, dtype=np.float64).reshape(-1, 2)
    idx = np.asarray(m.indices, dtype=np.int64).reshape(-1, 3)
    Fu = np.asarray(m.xref, dtype=np.int64)[idx]
    return judge(V, F if np.array_equal(Fu, F) else Fu, uv, idx, int(at.chart_count), s)


def _far_path(V, F):
    """Shortest edge path between vertex 0's farthest vertex and that vertex's farthest one (a slit)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import dijkstra

    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    G = sp.csr_matrix((w, (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    a = int(np.argmax(dijkstra(G, directed=False, indices=0)))
    d, pred = dijkstra(G, directed=False, indices=a, return_predecessors=True)
    b = int(np.argmax(d))
    path = [b]
    while path[-1] != a:
        path.append(int(pred[path[-1]]))
    return np.array(path[::-1], dtype=np.int64)


def run_igl(V, F, iters):
    t = time.perf_counter()
    cuts = [np.asarray(c, dtype=np.int64) for c in igl.cut_to_disk(F)]
    bnd = igl.boundary_loop(F)
    if not cuts and len(np.asarray(bnd)) == 0:
        cuts = [_far_path(V, F)]  # a topological sphere: cut_to_disk leaves it whole; cut a slit
    Vs, Fs, source = cut_open(V, F, cuts)
    b = np.asarray(igl.boundary_loop(Fs), dtype=np.int64)
    bc = igl.map_vertices_to_circle(Vs, b)
    uv0 = igl.harmonic(Vs, Fs, b, bc, 1)
    A = igl.doublearea(Vs, Fs).sum() / 2
    uv0 = uv0 * np.sqrt(A / np.pi)
    data = igl.slim_precompute(Vs, Fs.astype(np.int32), uv0, igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                               np.zeros(0, np.int32), np.zeros((0, 2)))
    uv = np.asarray(igl.slim_solve(data, iters))[:, :2]
    s = time.perf_counter() - t
    return judge(V, F, uv, Fs, 1, s)


def fmt(name, method, r):
    return (f"| {name} | {method} | {r['charts']} | {r['seam']:.2f} | {r['iso_mean']:.4f} | {r['iso_p95']:.4f} | "
            f"{r['flips']} | {r['overlaps']} | {r['collapsed']} | {r['packing']:.2f} | {r['seconds']:.2f} |")


def best_of(fn, args, repeat):
    """fn(*args) ``repeat`` times: the first run's result with the least of the runs' seconds (this VM's run-to-run
    noise is up to 25%; every method gets the same number of runs)."""
    first = fn(*args)
    for _ in range(repeat - 1):
        first["seconds"] = min(first["seconds"], fn(*args)["seconds"])
    return first


def main(argv):
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("names", nargs="*", help="meshes under ../shared/meshes, a path, or a generated shape (torus); "
                    "default: the closed, open and generated set")
    ap.add_argument("--slim-iters", type=int, default=100, help="libigl's SLIM iterations after cut_to_disk")
    ap.add_argument("--repeat", type=int, default=1, help="runs per method; the least time is reported")
    args = ap.parse_args(argv)
    iters, repeat = args.slim_iters, args.repeat
    names = args.names or CLOSED + OPEN + GENERATED
    print(f"machine: {machine()}\n")
    Vw, Fw = load("torus")  # warm-up (module docstring), untimed
    run_ours(Vw, Fw, "torus"), run_xatlas(Vw, Fw), run_uvunwrap(Vw, Fw), run_igl(Vw, Fw, iters)
    print("| mesh | method | charts | seam/√A | iso mean | iso p95 | flips | overlaps | collapsed | packing | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        V, F = load(name)
        for method, fn, args in (("heatparam", run_ours, (V, F, name)), ("xatlas", run_xatlas, (V, F)),
                                 ("uvunwrap", run_uvunwrap, (V, F)),
                                 (f"libigl cut+SLIM{iters}", run_igl, (V, F, iters))):
            try:
                print(fmt(name, method, best_of(fn, args, repeat)), flush=True)
            except Exception as exc:  # noqa: BLE001 - a peer failing is a result
                print(f"| {name} | {method} | failed: {type(exc).__name__}: {str(exc)[:80]} |||||||||", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
