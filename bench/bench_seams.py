"""The seams stage's second flattening (issue 17): where its time goes and which start serves the cut mesh.

Usage: ``python bench/bench_seams.py [mesh ...]`` (default halftunnel.off beetle.off from ../shared/meshes, or a
``heatparam.datasets`` name). A markdown table on stdout. Per mesh:

* ``parameterize`` end to end with default options: wall and CPU seconds (``time.process_time``: this machine is
  shared, so wall time says little alone), Newton iterations of the kept map and of the map without seams;
* the cut mesh's flattening alone (``pipeline.flatten(cut, seamed=True)``), from the same uncut map, as
  - ``heat stage`` — ``mds_start="always"``: the fill / geodesics / MDS run on the cut mesh (before 2026-12-01),
  - ``no reopened start`` — the heat stage skipped on the cut mesh (``pipeline.shortcuts``, case (c)), the start
    candidates of ``flatten`` alone (the conformal layout, else Tutte): the cut mesh's default before stop 19,
  - ``conformal reopened`` — as the seams stage runs it since stop 19: its conformal layout with crossing slits
    reopened (``refine.seam_start.reopen_crossing_slits``) offered as a start,
  - ``+ uncut start`` — the uncut map with its slits opened (``refine.seam_start.open_slits``) offered as a start,
  - ``uncut start only`` / ``Tutte only`` — ``refine.refine`` from that start alone / from Tutte's embedding alone,
  each with its start layout and energy, Newton iterations, final energy, iso mean, flips and boundary crossings.
"""

from __future__ import annotations

import sys
import time

from common import load, machine

from heatparam import metrics
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.mesh.validate import validate_mesh
from heatparam.options import make_options
from heatparam.pipeline import flatten, parameterize
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine import LscmStart, refine
from heatparam.refine.seam_start import open_slits, reopen_crossing_slits

NO_LSCM = LscmStart(None, -1, -1, None, "left out by the benchmark")


def timed(fn, *args, **kwargs):
    t, c = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t, time.process_time() - c


def row(name: str, variant: str, wall: float, cpu: float, ref: dict, summary: dict) -> str:
    st, pol = ref["start"], ref["polish"]
    e = st.get("energy", {}).get(st["layout"])
    e = f"{e:.4f}" if e is not None else f"{pol['energy_start']:.4f}"
    return (f"| {name} | {variant} | {wall:.2f} | {cpu:.2f} | {st['layout']} | {e} | {pol['iterations']} | "
            f"{pol['energy_end']:.6f} | {summary['iso_mean']:.4f} | {summary['flips']} | "
            f"{summary['boundary_crossings']} |")


def main(names: list[str]) -> None:
    print(f"# Seams: the cut mesh's flattening — {time.strftime('%Y-%m-%d')} — {machine()}\n")
    print("| mesh | run | wall s | CPU s | start | start energy | Newton it | energy end | iso mean | flips | "
          "crossings |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    opts, quiet = make_options(None), Progress(False)
    for name in names:
        V, F, _ = load(name)
        r, wall, cpu = timed(parameterize, V, F)
        rep = r.report
        kept = rep["method"]["refine"]
        without = (rep["method"].get("without_seams") or {}).get("refine")
        note = f"seams used: {rep['method']['seams']['used']}"
        if without:
            note += f"; without seams: {without['start']['layout']}, {without['polish']['iterations']} it"
        print(row(name, f"parameterize, default ({note})", wall, cpu, kept, rep["metrics"]))
        surface = Surface.validated(V, F)[0]
        flat = flatten(surface, opts, quiet)
        paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
        if not paths:
            continue
        Vs, Fs, src = cut_open(surface.V, surface.F, paths)
        cut = Surface(Vs, Fs, validate_mesh(Vs, Fs))
        x, orep = open_slits(flat.uv[src], Fs, src)
        runs = [("cut: heat stage (before)", make_options(None, mds_start="always"), None),
                ("cut: no reopened start", opts, None)]
        xr, rrep = reopen_crossing_slits(cut.conformal(), Fs, src)
        if xr is not None:
            runs.append((f"cut: conformal reopened ({rrep['closed']} seam vertices)", opts,
                         {"conformal_reopened": xr}))
        else:
            print(f"| {name} | cut: conformal reopened | – | – | none: {rrep['reason']} |")
        if x is not None:
            runs.append(("cut: + uncut start", opts, {"uncut": x}))
        for variant, o, starts in runs:
            f, wall, cpu = timed(flatten, cut, o, quiet, True, starts)
            print(row(name, variant, wall, cpu, f.method["refine"], f.summary), flush=True)
        alone = [("cut: Tutte only", {"lscm": NO_LSCM})]
        if x is not None:
            alone.insert(0, ("cut: uncut start only", {"lscm": NO_LSCM, "extra_starts": {"uncut": x}}))
        else:
            print(f"| {name} | cut: uncut start | – | – | not bijective: {orep['reason']} |")
        for variant, kw in alone:
            (y, ref), wall, cpu = timed(refine, Vs, Fs, None, **kw)
            print(row(name, variant, wall, cpu, ref, metrics.summary(Vs, Fs, y)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["halftunnel.off", "beetle.off"])
