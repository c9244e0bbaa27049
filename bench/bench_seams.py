"""The seams stage's second flattening: where its time goes and which start serves the cut mesh.

Usage: ``python bench/bench_seams.py [mesh ...]`` (default halftunnel.off beetle.off from ../shared/meshes, or a
``heatparam.datasets`` name). A markdown table on stdout. Per mesh:

* ``parameterize`` end to end with default options: wall and CPU seconds (``time.process_time``: this machine is
  shared, so wall time says little alone), Newton iterations of the kept map and of the map without seams;
* the cut mesh's flattening alone (``pipeline.flatten(cut, seamed=True)``), from the same uncut map, as
  - ``heat stage`` — ``mds_start="always"``: the fill / geodesics / MDS run on the cut mesh,
  - ``no reopened start`` — the heat stage skipped on the cut mesh (``pipeline.shortcuts``, case (c)), the start
    candidates of ``flatten`` alone (the conformal layout, else Tutte),
  - ``conformal reopened`` — as the seams stage runs it: its conformal layout with crossing slits reopened
    (``refine.reopen_slits.reopen_crossing_slits``) offered as a start,
  - ``Tutte only`` — ``refine.refine`` from Tutte's embedding alone,
  each with its start layout and energy, Newton iterations, final energy, iso mean, flips and boundary crossings.
(The uncut map with its slits opened as a start lost on beetle and halftunnel: BENCHMARKS.md §14; git history.)
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
from heatparam.refine.reopen_slits import reopen_crossing_slits

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
        paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
        if not paths:
            continue
        Vs, Fs, src = cut_open(surface.V, surface.F, paths)
        cut = Surface(Vs, Fs, validate_mesh(Vs, Fs))
        runs = [("cut: heat stage (before)", make_options(None, mds_start="always"), None),
                ("cut: no reopened start", opts, None)]
        xr, rrep = reopen_crossing_slits(cut.conformal(), Fs, src)
        if xr is not None:
            runs.append((f"cut: conformal reopened ({rrep['closed']} seam vertices)", opts,
                         {"conformal_reopened": xr}))
        else:
            print(f"| {name} | cut: conformal reopened | – | – | none: {rrep['reason']} |")
        for variant, o, starts in runs:
            f, wall, cpu = timed(flatten, cut, o, quiet, seamed=True, starts=starts)
            print(row(name, variant, wall, cpu, f.method["refine"], f.summary), flush=True)
        (y, ref), wall, cpu = timed(refine, Vs, Fs, None, lscm=NO_LSCM)
        print(row(name, "cut: Tutte only", wall, cpu, ref, metrics.summary(Vs, Fs, y)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["halftunnel.off", "beetle.off"])
