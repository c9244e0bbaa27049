"""Packing: texture atlases against xatlas, sheets nested by outlines against the shelf packing (issue 44).

For each mesh the atlas is made once (true scale; open meshes with max_distortion 1.05, as bench_atlas), then
* texture: heatparam's packer (``atlas.pack``, texture mode) and xatlas's packer on the SAME charts (xatlas
  ``add_uv_mesh``), and xatlas's whole pipeline (its own charts), all with the same padding and resolution.
  Utilization = UV area / the square; for xatlas over max(width, height)² of the atlas it made (it may stop short of
  the resolution: the kinder measure), times in the same run;
* sheets: the charts on square sheets of area (3D area) / 0.55: sheets used and the use of each, shelves of boxes
  (``--nest-time 0``) and the nesting by outlines (default gap, grain free, the default time budget).

    python bench/bench_pack.py [--meshes cow.off ...] [--padding 4] [--resolution 1024] [--no-xatlas-own]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from heatparam.atlas.pack import pack_charts
from heatparam.errors import HeatparamError
from heatparam.formats import load_mesh
from heatparam.formats.pattern import build_pattern, layout_charts
from heatparam.options import NEST_TIME, make_options
from heatparam.pipeline import parameterize

MESHES = Path(__file__).resolve().parents[2] / "shared" / "meshes"
OPEN = {"camelhead.off": 1.05, "beetle.off": 1.05}  # open meshes: an atlas asked for, as in bench_atlas


def _area(P, F):
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    return 0.5 * float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())


def charts_of(uv, Fuv, chart):
    uvs, Fs = [], []
    for c in range(int(chart.max()) + 1):
        f = np.flatnonzero(chart == c)
        rows = np.unique(Fuv[f])
        loc = np.full(len(uv), -1)
        loc[rows] = np.arange(len(rows))
        uvs.append(uv[rows])
        Fs.append(loc[Fuv[f]])
    return uvs, Fs


def xatlas_run(padding, resolution, *, uv=None, Fuv=None, V=None, F=None):
    """(utilization over max(w,h)², seconds, charts, atlases) of one xatlas generate: of our charts (``uv, Fuv``:
    xatlas's packer alone) or of the mesh (``V, F``: its own charts)."""
    import xatlas

    at = xatlas.Atlas()
    if uv is not None:
        at.add_uv_mesh(uv.astype(np.float32), Fuv.astype(np.uint32))
    else:
        at.add_mesh(V.astype(np.float32), F.astype(np.uint32))
    po = xatlas.PackOptions()
    po.padding, po.resolution, po.bilinear = int(padding), int(resolution), True
    t = time.perf_counter()
    at.generate(pack_options=po)
    s = time.perf_counter() - t
    _, idx, uv = at.get_mesh(0)
    T = uv[idx].astype(np.float64)
    area = _area(T.reshape(-1, 2), np.arange(3 * len(T)).reshape(-1, 3))
    return area * at.width * at.height / max(at.width, at.height) ** 2, s, int(at.chart_count), int(at.atlas_count)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["cow.off", "camelhead.off", "stanford-bunny.obj", "beetle.off"])
    ap.add_argument("--padding", type=float, default=4)
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--no-xatlas-own", action="store_true", help="skip xatlas's own charts (slow on big meshes)")
    a = ap.parse_args()
    tex, sheets = [], []
    for name in a.meshes:
        V, F = load_mesh(MESHES / name)
        r = parameterize(V, F, make_options(max_distortion=OPEN.get(name, 0.0)))
        chart = r.chart if r.chart is not None else np.zeros(len(F), dtype=np.int64)
        Fuv = r.Fuv if r.Fuv is not None else F
        uvs, Fs = charts_of(r.uv, Fuv, chart)
        t = time.perf_counter()
        _, info = pack_charts(uvs, Fs, "texture", a.padding, a.resolution)
        ours_s = time.perf_counter() - t
        same = xatlas_run(a.padding, a.resolution, uv=r.uv, Fuv=Fuv)
        own = None if a.no_xatlas_own else xatlas_run(a.padding, a.resolution, V=V, F=F)
        tex.append((name, len(uvs), info["utilization"], ours_s, same, own))
        a3 = 0.5 * float(np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum())
        side = float(np.sqrt(a3 / 0.55))
        row = [name, len(uvs)]
        for nest_time in (0.0, NEST_TIME):
            pat = build_pattern(V, F, r.uv, Fuv, r.uv_vertex, chart)
            t = time.perf_counter()
            try:
                pat = layout_charts(pat, (side, side), nest_time=nest_time, seed=0)
            except HeatparamError:  # a chart larger than the sheet
                row.append(("-", [], time.perf_counter() - t))
                continue
            row.append((len(pat.sheets), pat.sheet_use, time.perf_counter() - t))
        sheets.append(row)
    print(f"texture: padding {a.padding:g} px at {a.resolution} px; utilization = UV area / square")
    print(f"{'mesh':20s} {'charts':>6s} {'ours':>6s} {'s':>6s} | {'xatlas same charts':>18s} {'s':>5s} {'ratio':>5s} "
          f"| {'xatlas own charts':>17s} {'charts':>6s} {'s':>6s} {'ratio':>5s}")
    for name, n, u, s, same, own in tex:
        o = (f"{own[0]:17.3f} {own[2]:6d} {own[1]:6.2f} {u / own[0]:5.2f}" if own else f"{'-':>17s}")
        print(f"{name:20s} {n:6d} {u:6.3f} {s:6.2f} | {same[0]:18.3f} {same[1]:5.2f} {u / same[0]:5.2f} | {o}")
    print(f"\nsheets: square sheets of area (3D area)/0.55, default gap, grain free, nest time {NEST_TIME:g} s")
    print(f"{'mesh':20s} {'charts':>6s} | {'shelves: sheets, use per sheet':>34s} {'s':>5s} | "
          f"{'outlines: sheets, use per sheet':>34s} {'s':>5s}")
    for name, n, shelf, nest in sheets:
        fmt = [f"{k}: " + (" ".join(f"{u:.3f}" for u in use) or "a chart exceeds the sheet")
               for k, use, _ in (shelf, nest)]
        print(f"{name:20s} {n:6d} | {fmt[0]:>34s} {shelf[2]:5.2f} | {fmt[1]:>34s} {nest[2]:5.2f}")


if __name__ == "__main__":
    main()
