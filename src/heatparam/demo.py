"""``heatparam demo``: unwrap an embedded, generated scan-like part and say which stages shaped the result.

The part (:func:`heatparam.datasets.noisy_scan_part`) is a cylinder patch with two holes, in mm, with
scanner noise of 0.1 × the mean edge length: there the heat-geodesic MDS layout is a far better start than LSCM
(``BENCHMARKS.md`` §8), so the paper's pipeline (fill, heat geodesics, MDS) runs and starts the refinement.
"""

from __future__ import annotations

from pathlib import Path

#: The demo's model unit (the generated part is 240 × 180 mm flat).
UNITS = "mm"

#: Scanner noise of the part (× its mean edge length) and its seed.
NOISE, SEED = 0.1, 0

#: Files the demo writes today, in ``outdir``.
OUTPUTS = ("demo.obj", "demo-report.json", "demo-preview.png")

# TODO(lead, issue 15 items 1-3): once heatparam.formats.dxf / svg / step exist, the demo also writes
#   demo.dxf   <- heatparam.formats.dxf.write_dxf(path, pattern, units)
#   demo.svg   <- heatparam.formats.svg.write_svg(path, pattern, units)
#   demo.step  <- heatparam.formats.step.write_step(path, pattern, units)
# with units=UNITS: wire them in `write_flat_patterns` below (it lists what is pending until then).
PENDING_OUTPUTS = {"demo.dxf": "heatparam.formats.dxf", "demo.svg": "heatparam.formats.svg",
                   "demo.step": "heatparam.formats.step"}


def write_flat_patterns(outdir: Path, V, F, result) -> tuple[list[str], list[str]]:
    """Hook for the DXF / SVG / STEP writers (issue 15): returns (written, pending) file names. Today it writes
    nothing: the writers' ``pattern`` argument is defined by their own modules, which the lead wires here."""
    import importlib.util

    pending = []
    for name, module in PENDING_OUTPUTS.items():
        try:
            found = importlib.util.find_spec(module) is not None
        except ModuleNotFoundError:
            found = False
        pending.append(f"{name} ({module} {'found, not wired yet' if found else 'not available'})")
    return [], pending


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
        lscm = energy.get("lscm")
        why = (f"LSCM's layout is not near-isometric (energy {lscm:.4f})" if lscm is not None
               else "requested or needed")
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
    """Generate the part, unwrap it, write :data:`OUTPUTS` into ``outdir`` (atomically, each). Returns the
    pipeline ``Result`` and the demo's summary (``report["demo"]``)."""
    from heatparam import datasets
    from heatparam.pipeline import parameterize
    from heatparam.unwrap import write_results

    shape = datasets.noisy_scan_part(noise=NOISE, seed=SEED)
    result = parameterize(shape.V, shape.F, progress=not quiet)
    uv, report = result
    report["input"] = f"generated:{shape.name}"
    report["metrics"]["layout_error_rel"] = datasets.layout_error(uv, shape.uv_true[result.uv_vertex])
    written, pending = write_flat_patterns(outdir, shape.V, shape.F, result)
    report["demo"] = {"surface": shape.name, "vertices": len(shape.V), "units": UNITS,
                      "noise": f"{NOISE:g} x mean edge, Gaussian, seed {SEED}", "stages": stages(report),
                      "outputs": [*OUTPUTS, *written], "pending_outputs": pending}
    write_results(shape.V, shape.F, result, outdir / "demo.obj", outdir / "demo-report.json",
                   outdir / "demo-preview.png", quiet=quiet, units=UNITS)
    return result, report["demo"]
