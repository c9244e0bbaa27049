"""``heatparam demo``: unwrap an embedded, generated scan-like part and say which stages shaped the result.

The part (:func:`heatparam.datasets.noisy_scan_part`) is a cylinder patch with two holes, in mm, with
scanner noise of 0.1 × the mean edge length: the conformal layout is not near-isometric there, so the paper's
pipeline (fill, heat geodesics, MDS) runs and its layout competes with the conformal one as the refinement's start
(the spectral conformal map wins here: energy 1.0029 against MDS's 1.0066).
"""

from __future__ import annotations

from pathlib import Path

from heatparam.options import ISOMETRIC_START_EXCESS

#: The demo's model unit (the generated part is 240 × 180 mm flat).
UNITS = "mm"

#: Scanner noise of the part (× its mean edge length) and its seed.
NOISE, SEED = 0.1, 0

#: Files the demo writes in ``outdir``: the map (OBJ), its flat pattern (DXF, SVG with the strain map), the fitted
#: trimmed B-spline faces (STEP), the report and the preview.
OUTPUTS = ("demo.obj", "demo.dxf", "demo.svg", "demo.step", "demo-report.json", "demo-preview.png")


def stages(report: dict) -> dict[str, str]:
    """Which stages ran and why, from a ``parameterize`` report: fill, geodesics, start, seams (one phrase
    each)."""
    method = report["method"]
    fill = method.get("fill") or {}
    if fill.get("used"):
        fill_s = f"{fill.get('method', '?')} ({fill.get('reason', '')})"
    else:
        fill_s = f"not used ({fill.get('skipped') or fill.get('reason') or 'not needed'})"
    geo = method.get("geodesics")
    start = (method.get("refine") or {}).get("start") or {}
    energy = start.get("energy") or {}
    if isinstance(geo, str) and geo.startswith("skipped"):
        geo_s = geo
    elif geo is None:
        geo_s = "not run"
    else:
        conf = energy.get("conformal")
        why = (f"the conformal layout's energy {conf:.4f} (1 = isometry) is above the bar at which it starts alone, "
               f"1 + {ISOMETRIC_START_EXCESS:g}" if conf is not None else "requested or needed")
        geo_s = f"ran ({geo}; MDS): {why}"
    layout = start.get("layout")
    if layout is None:
        start_s = "none (--refine none: the raw MDS map)" if method.get("refine", {}).get("method") == "none" else "?"
    else:
        es = ", ".join(f"{k.upper()} {v:.4f}" for k, v in energy.items() if v is not None)
        start_s = f"{layout.upper()} layout" + (f" (lower energy, 1 = isometry: {es})" if es else "")
    seams = method.get("seams") or {}
    seams_s = ("used" if seams.get("used") else "none") + (f": {seams['reason']}" if seams.get("reason") else "")
    return {"fill": fill_s, "geodesics": geo_s, "start": start_s, "seams": seams_s}


def run(outdir: Path, quiet: bool = False) -> tuple[object, dict]:
    """Generate the part, unwrap it, write :data:`OUTPUTS` into ``outdir`` (all or nothing). Returns the
    pipeline ``Result`` and the demo's summary (``report["demo"]``)."""
    from heatparam import datasets, metrics
    from heatparam.pipeline import parameterize
    from heatparam.unwrap import plan, write_outputs

    shape = datasets.noisy_scan_part(noise=NOISE, seed=SEED)
    result = parameterize(shape.V, shape.F, progress=not quiet, unit_name=UNITS)
    uv, report = result
    report["input"] = f"generated:{shape.name}"
    report["metrics"]["layout_error_rel"] = metrics.layout_error(uv, shape.uv_true[result.uv_vertex])
    report["demo"] = {"surface": shape.name, "vertices": len(shape.V), "units": UNITS,
                      "noise": f"{NOISE:g} x mean edge, Gaussian, seed {SEED}", "stages": stages(report),
                      "outputs": list(OUTPUTS)}
    plans = plan([outdir / f for f in OUTPUTS if not f.endswith((".json", ".png"))], outdir / "demo-report.json",
                 outdir / "demo-preview.png")
    write_outputs(shape.V, shape.F, result, plans, units=UNITS, strain_map=True, quiet=quiet)
    return result, report["demo"]
