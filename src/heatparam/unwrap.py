"""The unwrap job, file to files: plan the outputs, :func:`heatparam.parameterize`, write every output at once.

``heatparam unwrap``, ``heatparam demo`` and the batch runner all call these, so that the same input and options
give the same bytes whichever way it is run. The writing contract (``formats.outputs``): every path is checked
before the computation, every output goes to a temporary, and all are renamed into place only when all succeeded.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from heatparam.formats.units import DEFAULT_UNITS
from heatparam.progress import print_warning


def plan(outputs, report=None, preview=None, inputs=()) -> list:
    """Check every output path before any computation (``formats.outputs.plan_outputs``): the map's outputs
    (format by extension), the report (.json) and the preview (.png). Returns the plans; HeatparamError (one line)
    for a path that cannot be written or a format this installation cannot write."""
    from heatparam.formats.exporters import BY_NAME
    from heatparam.formats.outputs import plan_outputs

    paths = [*outputs, *([(report, {"json"})] if report else []), *([(preview, {"png"})] if preview else [])]
    plans = plan_outputs(paths, inputs=inputs)
    for fmt in dict.fromkeys(pl.format for pl in plans):
        BY_NAME[fmt].check_importable()
    return plans


def write_outputs(V, F, result, plans, *, units: str = DEFAULT_UNITS, sheet=None, strain_map: bool = False,
                  quiet: bool = False, fit_tolerance: float | None = None) -> None:
    """Every planned output of a pipeline ``Result`` (each written by its ``formats.exporters`` entry), all or
    nothing (``formats.outputs.commit_outputs``); the report comes last and lists the others."""
    from heatparam import interrupt
    from heatparam.formats.exporters import BY_NAME, Run
    from heatparam.formats.outputs import commit_outputs

    report = result.report
    report["units"] = units
    needs_pattern = any(BY_NAME[pl.format].pattern for pl in plans)
    run = Run(V, F, result, units, pattern=_pattern(V, F, result, sheet=sheet, units=units) if needs_pattern else None,
              strain_map=strain_map, fit_tolerance=fit_tolerance, names={pl.format: pl.path.name for pl in plans})
    written: list[dict] = []

    def recorded(pl):
        def write(tmp):
            if not quiet and pl.format == "step":  # the B-spline fit can take a minute: say so before
                print(f"heatparam: write {pl.path.name}: fitting B-spline faces ...", file=sys.stderr, flush=True)
            t0 = time.perf_counter()
            info = BY_NAME[pl.format].write(tmp, run)
            dt = time.perf_counter() - t0
            report["timings_s"][f"write {pl.format}"] = round(dt, 4)
            if not quiet:
                print(f"heatparam: write {pl.path.name}: {dt:.2f} s", file=sys.stderr)
            written.append({"path": str(pl.path), **(info if isinstance(info, dict) else {"format": pl.format})})
            return info
        return write

    order = sorted(plans, key=lambda pl: pl.format == "json")  # the report last: it lists the other outputs
    report["outputs"] = written
    known = len(report.setdefault("warnings", []))
    with interrupt.deferred():  # all the outputs or none: an interrupt waits until they are complete
        commit_outputs([(pl.path, recorded(pl)) for pl in order])
    if not quiet:
        for w in report["warnings"][known:]:  # what writing found (a STEP face off its fit tolerance)
            print_warning(w)
        m = report["metrics"]
        names = ", ".join(str(pl.path) for pl in plans)
        print(f"wrote {names} ({units}): {m['flips']} flipped, {m['boundary_crossings']} boundary crossings, "
              f"isometric distortion mean {m['iso_mean']:.4f} / p95 {m['iso_p95']:.4f}, "
              f"{sum(report['timings_s'].values()):.2f} s", file=sys.stderr)


def _pattern(V, F, result, *, sheet, units: str):
    """The flat pattern (charts, loops, seams, laid out) that the DXF and SVG draw; its summary goes into the
    report."""
    from heatparam.formats.pattern import Sheets, build_pattern, layout_charts

    pattern = build_pattern(V, F, result.uv, result.Fuv, result.uv_vertex, chart=getattr(result, "chart", None))
    if sheet is None:
        pattern = layout_charts(pattern, units=units)
    else:
        sheet = sheet if isinstance(sheet, Sheets) else Sheets(tuple(sheet))
        pattern = layout_charts(pattern, sheet.size, sheet.gap, units=units, grain=sheet.grain,
                                nest_time=sheet.nest_time, seed=sheet.seed)
    result.report["pattern"] = {
        "charts": len(pattern.charts), "sheets": len(pattern.sheets), "seams": len(pattern.seams) // 2,
        "sheet_use": [float(u) for u in pattern.sheet_use],
        "nesting": {k: (float(v) if isinstance(v, float) else v) for k, v in pattern.nesting.items()},
        "loops": [{"chart": c.id, "kind": lp.kind, "length_3d": lp.length_3d, "length_uv": lp.length_uv,
                   "stretch": lp.stretch} for c in pattern.charts for lp in c.loops],
    }
    return pattern


def unwrap_file(input, outputs, *, report=None, preview=None, options=None, quiet: bool = True,
                units: str | None = None, sheet=None, strain_map: bool = False, fit_tolerance: float | None = None):
    """What ``heatparam unwrap`` does, as a function: check every output path, load ``input``, flatten it, write
    every output (all or nothing).

    Parameters
    ----------
    input : mesh file (.obj .off .ply .stl .glb .gltf).
    outputs : a path or a list of paths; the format follows each extension (.obj .ply .glb .dxf .svg .step).
    report, preview : optional JSON report and PNG preview paths.
    options : pipeline :class:`~heatparam.options.Options` (progress on stderr per ``options.progress``).
    quiet : do not print the one-line summary on stderr.
    units : the model's unit, as ``--units``; None: ``options.unit_name`` if set, else mm assumed (with a warning when
        the part is implausibly sized in mm: ``formats.units.assumed_units_warning``; the report's
        ``units_assumed``). It becomes ``options.unit_name``, which the pipeline's messages name.
    sheet, strain_map, fit_tolerance : as ``heatparam unwrap``'s flags of the same names; ``sheet``: (W, H) or a
        ``formats.pattern.Sheets`` (size, gap, grain, nest_time, seed).

    Returns
    -------
    The pipeline's ``Result`` (``uv, report``), its report's ``input`` set to ``str(input)``. Raises
    ``HeatparamError`` (one line) for bad input; nothing is written then.
    """
    outputs = [outputs] if isinstance(outputs, (str, Path)) else list(outputs)
    plans = plan([str(o) for o in outputs], str(report) if report else None, str(preview) if preview else None,
                 inputs=(str(input),))
    return unwrap_planned(input, plans, options=options, quiet=quiet, units=units, sheet=sheet,
                          strain_map=strain_map, fit_tolerance=fit_tolerance)


def unwrap_planned(input, plans, *, options=None, quiet: bool = True, units: str | None = None, sheet=None,
                   strain_map: bool = False, fit_tolerance: float | None = None):
    """:func:`unwrap_file` with its outputs already checked (``plans`` from :func:`plan`)."""
    from heatparam.formats import load_mesh
    from heatparam.options import make_options
    from heatparam.pipeline import parameterize

    V, F = load_mesh(input)
    F, left_out = _without_point_faces(F)
    opts = make_options(options)
    given = units or (opts.unit_name if opts.unit_name != "model units" else None)
    opts = opts.replace(unit_name=given or DEFAULT_UNITS)  # the unit the pipeline's messages name
    # texture space has no length unit: the assumed one matters to true-scale outputs only
    sized = given or opts.pack == "texture"
    notes = [n for n in (None if sized else _assumed_units(V, F), left_out) if n]
    for note in notes if opts.progress else []:
        print_warning(note)
    result = parameterize(V, F, opts)
    result.report["input"] = str(input)
    result.report["units_assumed"] = not given
    result.report["warnings"][:0] = notes
    write_outputs(V, F, result, plans, units=opts.unit_name, sheet=sheet, strain_map=strain_map, quiet=quiet,
                  fit_tolerance=fit_tolerance)
    return result


def _without_point_faces(F):
    """F without the faces that repeat a vertex index, and the warning saying how many (None when none). Such a
    face is a segment or a point (an STL triangle whose corners merged, an OBJ 'f 1 1 2'): no surface to lay out,
    so a file keeps its surface; a file of nothing else is left to the pipeline's refusal."""
    import numpy as np

    from heatparam.mesh.topology import repeated_vertex_faces

    F = np.asarray(F)
    if F.ndim != 2 or F.shape[1] != 3 or F.dtype.kind not in "iu":
        return F, None
    rep = repeated_vertex_faces(F)
    if not rep.any() or rep.all():
        return F, None
    return F[~rep], (f"{int(rep.sum())} faces repeat a vertex index (segments or points, no surface): left out of "
                     "the map and of the outputs")


def _assumed_units(V, F) -> str | None:
    """The warning when the default unit makes the part implausibly small or large (``formats.units``). The mesh is
    not validated yet: only face indices in range and finite points count (a bad mesh is refused by the pipeline)."""
    import numpy as np

    from heatparam.formats.units import assumed_units_warning

    idx = np.asarray(F).ravel()
    if idx.dtype.kind in "iu":  # the points faces reference, each once (a corner gather is 6x the rows)
        used = np.zeros(len(V), dtype=bool)
        used[idx[(idx >= 0) & (idx < len(V))]] = True
    else:
        used = np.ones(len(V), dtype=bool)
    P = np.asarray(V, dtype=np.float64)[used] if used.any() else np.zeros((0, 3))
    P = P[np.isfinite(P).all(axis=1)] if P.ndim == 2 else np.zeros((0, 3))
    return assumed_units_warning(float((P.max(axis=0) - P.min(axis=0)).max())) if len(P) else None
