"""The unwrap job, file to files: plan the outputs, :func:`heatparam.parameterize`, write every output at once.

``heatparam unwrap``, ``heatparam demo`` and the batch runner all call these, so that the same input and options
give the same bytes whichever way it is run. The writing contract (``formats.outputs``): every path is checked
before the computation, every output goes to a temporary, and all are renamed into place only when all succeeded.
"""

from __future__ import annotations

import sys
from pathlib import Path

from heatparam import __version__
from heatparam.errors import HeatparamError
from heatparam.formats.units import DEFAULT_UNITS


def plan(outputs, report=None, preview=None, inputs=()) -> list:
    """Check every output path before any computation (``formats.outputs.plan_outputs``): the map's outputs
    (format by extension), the report (.json) and the preview (.png). Returns the plans; HeatparamError (one line)
    for a path that cannot be written."""
    from heatparam.formats.outputs import plan_outputs

    paths = [*outputs, *([(report, {"json"})] if report else []), *([(preview, {"png"})] if preview else [])]
    plans = plan_outputs(paths, inputs=inputs)
    if any(pl.format == "step" for pl in plans):
        step_writer()  # unavailable → one-line error before the computation
    return plans


def step_writer():
    """``heatparam.formats.step.write_step``, or a one-line error when this installation has no STEP writer."""
    try:
        from heatparam.formats.step import write_step
    except ImportError as exc:
        raise HeatparamError(f"STEP output (.step/.stp) is unavailable in this installation ({exc})") from None
    return write_step


def write_outputs(V, F, result, plans, units: str = DEFAULT_UNITS, sheet=None, strain_map: bool = False,
                  quiet: bool = False, fit_tolerance: float | None = None) -> None:
    """Every planned output of a pipeline ``Result`` (OBJ, PLY, GLB, DXF, SVG, STEP, report JSON, preview PNG),
    all or nothing (``formats.outputs.commit_outputs``); the report comes last and lists the others."""
    from heatparam.formats.outputs import commit_outputs

    report = result.report
    report["units"] = units
    pattern = _pattern(V, F, result, plans, sheet)
    written: list[dict] = []

    def recorded(pl, fn):
        def run(tmp):
            info = fn(tmp)
            written.append({"path": str(pl.path), **(info if isinstance(info, dict) else {"format": pl.format})})
            return info
        return run

    order = sorted(plans, key=lambda pl: pl.format == "json")  # the report last: it lists the other outputs
    report["outputs"] = written
    ctx = {"units": units, "pattern": pattern, "strain_map": strain_map, "fit_tolerance": fit_tolerance,
           "names": {pl.format: pl.path.name for pl in plans}}
    from heatparam import interrupt

    with interrupt.deferred():  # all the outputs or none: an interrupt waits until they are complete
        commit_outputs([(pl.path, recorded(pl, _writer(pl.format, V, F, result, ctx))) for pl in order])
    if not quiet:
        m = report["metrics"]
        names = ", ".join(str(pl.path) for pl in plans)
        print(f"wrote {names} ({units}): {m['flips']} flipped, {m['boundary_crossings']} boundary crossings, "
              f"isometric distortion mean {m['iso_mean']:.4f} / p95 {m['iso_p95']:.4f}, "
              f"{sum(report['timings_s'].values()):.2f} s", file=sys.stderr)


def _pattern(V, F, result, plans, sheet):
    """The flat pattern (charts, loops, seams, laid out) when a DXF or SVG is asked for; its summary goes into
    the report."""
    if not any(pl.format in ("dxf", "svg") for pl in plans):
        return None
    from heatparam.formats.pattern import build_pattern, layout_charts

    pattern = layout_charts(build_pattern(V, F, result.uv, result.Fuv, result.uv_vertex,
                                          getattr(result, "chart", None)), sheet=sheet)
    result.report["pattern"] = {
        "charts": len(pattern.charts), "sheets": len(pattern.sheets), "seams": len(pattern.seams) // 2,
        "loops": [{"chart": c.id, "kind": lp.kind, "length_3d": lp.length_3d, "length_uv": lp.length_uv,
                   "stretch": lp.stretch} for c in pattern.charts for lp in c.loops],
    }
    return pattern


def _writer(fmt: str, V, F, result, ctx: dict):
    """The function that writes ``fmt`` to a temporary path (returns a dict of facts for the report, or None)."""
    uv, Fuv, uv_vertex, report, units = result.uv, result.Fuv, result.uv_vertex, result.report, ctx["units"]
    chart = getattr(result, "chart", None)
    title = Path(report.get("input", "")).name
    header = f"heatparam {__version__}: vt = true-scale UV in {units} (model units: {units})"
    if fmt == "obj":
        from heatparam.formats import save_uv_obj

        return lambda tmp: save_uv_obj(tmp, V, F, uv, header=header, Fuv=Fuv) or {"format": "obj", "units": units}
    if fmt in ("ply", "glb"):
        from heatparam.formats import meshuv

        write = meshuv.write_ply if fmt == "ply" else meshuv.write_glb
        return lambda tmp: write(tmp, V, uv, Fuv, uv_vertex, units=units, comment=header)
    if fmt == "dxf":
        from heatparam.formats.dxf import write_dxf

        return lambda tmp: write_dxf(tmp, ctx["pattern"], units=units, title=title)
    if fmt == "svg":
        from heatparam.formats.svg import write_svg

        return lambda tmp: write_svg(tmp, ctx["pattern"], units=units, title=title, V=V, strain_map=ctx["strain_map"])
    if fmt == "step":
        write_step = step_writer()
        return lambda tmp: write_step(tmp, V, F, uv, Fuv, uv_vertex, chart=chart, units=units,
                                      tolerance=ctx["fit_tolerance"], name=ctx["names"]["step"])
    if fmt == "png":
        from heatparam import render

        return lambda tmp: render.save_preview(tmp, V[uv_vertex], Fuv, uv, title=title or "map",
                                               fill_surface=result.fill_surface, units=units,
                                               metrics=report["metrics"], vertex=uv_vertex,
                                               chart=chart) or {"format": "png"}
    from heatparam.formats import save_json

    return lambda tmp: save_json(tmp, report) or {"format": "json"}


def unwrap_file(input, outputs, report=None, preview=None, options=None, quiet: bool = True,
                units: str = DEFAULT_UNITS, sheet=None, strain_map: bool = False, fit_tolerance: float | None = None):
    """What ``heatparam unwrap`` does, as a function: check every output path, load ``input``, flatten it, write
    every output (all or nothing).

    Parameters
    ----------
    input : mesh file (.obj .off .ply .stl .glb .gltf).
    outputs : a path or a list of paths; the format follows each extension (.obj .ply .glb .dxf .svg .step).
    report, preview : optional JSON report and PNG preview paths.
    options : pipeline :class:`~heatparam.options.Options` (progress on stderr per ``options.progress``).
    quiet : do not print the one-line summary on stderr.
    units, sheet, strain_map, fit_tolerance : as ``heatparam unwrap``'s flags of the same names.

    Returns
    -------
    The pipeline's ``Result`` (``uv, report``), its report's ``input`` set to ``str(input)``. Raises
    ``HeatparamError`` (one line) for bad input; nothing is written then.
    """
    outputs = [outputs] if isinstance(outputs, (str, Path)) else list(outputs)
    plans = plan([str(o) for o in outputs], str(report) if report else None, str(preview) if preview else None,
                 inputs=(str(input),))
    return unwrap_planned(input, plans, options, quiet, units, sheet, strain_map, fit_tolerance)


def unwrap_planned(input, plans, options=None, quiet: bool = True, units: str = DEFAULT_UNITS, sheet=None,
                   strain_map: bool = False, fit_tolerance: float | None = None):
    """:func:`unwrap_file` with its outputs already checked (``plans`` from :func:`plan`)."""
    from heatparam.formats import load_mesh
    from heatparam.options import make_options
    from heatparam.pipeline import parameterize

    V, F = load_mesh(input)
    result = parameterize(V, F, make_options(options))
    result.report["input"] = str(input)
    write_outputs(V, F, result, plans, units=units, sheet=sheet, strain_map=strain_map, quiet=quiet,
                  fit_tolerance=fit_tolerance)
    return result
