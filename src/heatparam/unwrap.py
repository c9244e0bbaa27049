"""The unwrap job, file to files: read a mesh, :func:`heatparam.parameterize` it, write its outputs.

``heatparam unwrap``, ``heatparam demo`` and the batch runner all call these, so that the same input and options
give the same bytes whichever way it is run.
"""

from __future__ import annotations

import sys
from pathlib import Path

from heatparam import __version__


def write_results(V, F, result, out: Path, rep: Path | None, prev: Path | None, quiet: bool,
                  units: str | None = None) -> None:
    """Preview (optional), OBJ and report (optional) of a pipeline ``Result``, each written atomically.
    ``units``: the model's length unit for the preview's axes and scale bar (None: "model units")."""
    from heatparam.formats import save_json, save_uv_obj

    uv, report = result
    if prev is not None:
        from heatparam import render

        render.save_preview(prev, V[result.uv_vertex], result.Fuv, uv, title=Path(report.get("input", out.stem)).name,
                            fill_surface=result.fill_surface, units=units, metrics=report["metrics"],
                            vertex=result.uv_vertex)
    save_uv_obj(out, V, F, uv, header=f"heatparam {__version__}: vt = true-scale UV (model units)", Fuv=result.Fuv)
    if rep is not None:
        save_json(rep, report)
    if not quiet:
        m = report["metrics"]
        print(
            f"wrote {out}: {m['flips']} flipped, {m['boundary_crossings']} boundary crossings, "
            f"isometric distortion mean {m['iso_mean']:.4f} / p95 {m['iso_p95']:.4f}, "
            f"{sum(report['timings_s'].values()):.2f} s",
            file=sys.stderr,
        )
