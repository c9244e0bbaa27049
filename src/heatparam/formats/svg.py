"""SVG flat pattern: the DXF's content as styled groups, at its physical size.

Groups (``<g id=...>``): ``strain`` (with ``strain_map``: every face filled by its true-scale isometric distortion,
and a ``legend``), ``sheet`` (sheet frames), ``outline`` (one closed ``<polygon>`` per chart outer loop: the cut),
``holes`` (one ``<polygon>`` per hole), ``seams`` (one ``<polyline>`` per seam side with its label) and
``annotation`` (chart ids, distortion summary, units). The root's ``width``/``height`` are physical lengths in
the declared units (m → mm, ft → in) and its ``viewBox`` is in model units, so one user unit = one model unit;
the UV ``v`` axis points up (the SVG y axis is flipped).
"""

from __future__ import annotations

import os
from xml.sax.saxutils import escape

import numpy as np

from heatparam.formats.dxf import chart_summary, summary_height, text_height
from heatparam.formats.pattern import Pattern, face_iso
from heatparam.formats.units import svg_length

STYLE = """
  .cut { fill: none; stroke: #000000; }
  .hole { fill: none; stroke: #d62728; }
  .seam { fill: none; stroke: #1f5fd6; stroke-dasharray: DASH; }
  .sheet { fill: none; stroke: #888888; }
  .label { font-family: sans-serif; fill: #1f5fd6; text-anchor: middle; dominant-baseline: middle; }
  .note { font-family: sans-serif; fill: #2a7d2a; }
"""


def _fmt(P: np.ndarray) -> str:
    return " ".join(f"{x:.9g},{y:.9g}" for x, y in P)


def write_svg(path: str | os.PathLike, pattern: Pattern, units: str = "mm", title: str = "",
              V: np.ndarray | None = None, strain_map: bool = False, vmax: float | None = None) -> dict:
    """Write ``pattern`` (already laid out) as an SVG of physical size.

    Parameters
    ----------
    path : output file (written directly; ``formats.outputs.commit_outputs`` gives the all-or-nothing commit).
    pattern : a laid-out :class:`~heatparam.formats.pattern.Pattern`.
    units : model units (``formats.units.UNITS``): the physical width/height and the annotation.
    title : a line of annotation below the pattern.
    V : (n,3) float64 the mesh's vertices, needed for ``strain_map``.
    strain_map : fill faces by isometric distortion max(sigma1, 1/sigma2) (viridis, flipped faces red) and draw
        a legend.
    vmax : top of the colour scale (default: the 99th area percentile clipped to [1.01, 2]).

    Returns
    -------
    dict
        ``{"format": "svg", "units", "width", "height", "outlines", "holes", "seam_labels", "strain_map"}``.
    """
    th = text_height(pattern)
    lo, hi = pattern.bbox
    margin = 2 * th
    n_notes = 2 if title else 1
    legend_w = 12 * th if strain_map else 0.0
    x0, y_top = lo[0] - margin, hi[1] + margin
    W = float(hi[0] - lo[0] + 2 * margin + legend_w)
    H = float(hi[1] - lo[1] + 2 * margin + (1.5 * n_notes + 1) * th)

    def tr(P):  # model (u, v) → SVG user units (x right, y down)
        P = np.atleast_2d(P)
        return np.column_stack([P[:, 0] - x0, y_top - P[:, 1]])

    sw = th / 8
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<svg xmlns="http://www.w3.org/2000/svg" width="{svg_length(W, units)}" '
           f'height="{svg_length(H, units)}" viewBox="0 0 {W:.9g} {H:.9g}" data-units="{units}">',
           f"<title>{escape(title or 'heatparam flat pattern')} (units: {units})</title>",
           f"<style>{STYLE.replace('DASH', f'{2 * th:.4g} {th:.4g}')}</style>"]
    if strain_map:
        if V is None:
            raise ValueError("strain_map needs V")
        out += _strain_group(pattern, V, tr, vmax, th, W, margin, sw)
    out += _sheet_group(pattern, tr, sw)
    loops, n_holes = _loop_groups(pattern, tr, sw)
    out += loops
    out += _seam_group(pattern, tr, th, sw)
    out += _annotation_group(pattern, tr, th, units, title, H, margin)
    out.append("</svg>")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(out) + "\n")
    return {"format": "svg", "units": units, "width": svg_length(W, units), "height": svg_length(H, units),
            "outlines": len(pattern.charts), "holes": n_holes, "seam_labels": len(pattern.seams),
            "strain_map": bool(strain_map)}


def _sheet_group(pattern: Pattern, tr, sw: float) -> list[str]:
    """The ``sheet`` group (one rectangle per sheet frame), or nothing without sheets."""
    if not len(pattern.sheets):
        return []
    out = [f'<g id="sheet" class="sheet" stroke-width="{sw:.4g}">']
    for sx, sy, w, h in pattern.sheets:
        P = tr(np.array([[sx, sy], [sx + w, sy], [sx + w, sy + h], [sx, sy + h]]))
        out.append(f'<polygon points="{_fmt(P)}"/>')
    out.append("</g>")
    return out


def _loop_groups(pattern: Pattern, tr, sw: float) -> tuple[list[str], int]:
    """The ``outline`` and ``holes`` groups (one polygon per loop) and the number of holes."""
    out = []
    n_holes = 0
    for gid, kind, cls in (("outline", "outer", "cut"), ("holes", "hole", "hole")):
        out.append(f'<g id="{gid}" class="{cls}" stroke-width="{sw:.4g}">')
        for ch in pattern.charts:
            for lp in ch.loops:
                if lp.kind == kind:
                    n_holes += kind == "hole"
                    out.append(f'<polygon data-chart="{ch.id}" points="{_fmt(tr(pattern.uv[lp.rows]))}"/>')
        out.append("</g>")
    return out, n_holes


def _seam_group(pattern: Pattern, tr, th: float, sw: float) -> list[str]:
    """The ``seams`` group: one polyline per seam side and its label, turned along the seam."""
    out = [f'<g id="seams" stroke-width="{sw:.4g}">']
    for s in pattern.seams:
        x, y = tr(s.label_point(0.8 * th))[0]
        out.append(f'<polyline class="seam" data-label="{s.label}" points="{_fmt(tr(pattern.uv[s.rows]))}"/>')
        out.append(f'<text class="label" x="{x:.9g}" y="{y:.9g}" font-size="{th:.4g}" '
                   f'transform="rotate({-_upright(s.angle):.4g} {x:.9g} {y:.9g})">{s.label}</text>')
    out.append("</g>")
    return out


def _annotation_group(pattern: Pattern, tr, th: float, units: str, title: str, H: float,
                      margin: float) -> list[str]:
    """The ``annotation`` group: chart ids with their distortion summaries, then the units and title lines."""
    from heatparam.formats.dxf import label_point

    n_notes = 2 if title else 1
    out = ['<g id="annotation" class="note">']
    for ch in pattern.charts:
        x, y = tr(label_point(pattern, ch))[0]
        out.append(f'<text x="{x:.9g}" y="{y:.9g}" font-size="{2 * th:.4g}" text-anchor="middle">C{ch.id}</text>')
        lines = chart_summary(ch, units)
        sh = summary_height(pattern, ch, lines, th)
        for i, line in enumerate(lines):
            out.append(f'<text x="{x:.9g}" y="{y + 1.5 * th + 1.5 * i * sh:.9g}" font-size="{sh:.4g}" '
                       f'text-anchor="middle">{escape(line)}</text>')
    for i, line in enumerate([f"units: {units}", *([title] if title else [])]):
        y = H - (1.5 * (n_notes - 1 - i) + 1) * th
        out.append(f'<text x="{margin:.9g}" y="{y:.9g}" font-size="{th:.4g}">{escape(line)}</text>')
    out.append("</g>")
    return out


def _upright(angle: float) -> float:
    from heatparam.formats.dxf import readable_angle

    return readable_angle(angle)


def _strain_group(pattern: Pattern, V, tr, vmax, th, W, margin, sw) -> list[str]:
    import matplotlib

    iso = face_iso(pattern, V)
    finite = np.isfinite(iso)
    if vmax is None:
        vmax = float(np.clip(np.percentile(iso[finite], 99), 1.01, 2.0)) if finite.any() else 2.0
    cmap = matplotlib.colormaps["viridis"]
    t = np.clip((np.where(finite, iso, vmax) - 1.0) / (vmax - 1.0), 0, 1)
    rgb = (cmap(t)[:, :3] * 255).round().astype(int)
    rgb[~finite] = (230, 0, 0)
    out = [f'<g id="strain" stroke-width="{sw / 4:.4g}">']  # a hairline of the fill colour hides AA seams
    # one %-format over all faces (a Python f-string per face is ~10x slower on 100k faces)
    xy = tr(pattern.uv[pattern.Fuv].reshape(-1, 2)).reshape(-1, 6)
    col = np.array([f"#{r:02x}{g:02x}{b:02x}" for r, g, b in rgb.tolist()], dtype=object)
    table = np.empty((len(xy), 8), dtype=object)
    table[:, :6] = xy
    table[:, 6] = table[:, 7] = col
    out.append(('<polygon points="%.8g,%.8g %.8g,%.8g %.8g,%.8g" fill="%s" stroke="%s"/>\n' * len(xy)
                % tuple(table.ravel().tolist())).rstrip("\n"))
    out.append("</g>")
    # legend: ten swatches from 1 to vmax, top to bottom, right of the pattern
    x = W - 10 * th
    out.append(f'<g id="legend" font-family="sans-serif" font-size="{0.8 * th:.4g}">')
    out.append(f'<text x="{x:.9g}" y="{margin:.9g}">isometric distortion</text>')
    out.append(f'<text x="{x:.9g}" y="{margin + th:.9g}">max(σ1, 1/σ2)</text>')
    steps = 10
    for i in range(steps + 1):
        v = 1.0 + (vmax - 1.0) * (steps - i) / steps
        r, g, b = (np.array(cmap((v - 1.0) / (vmax - 1.0))[:3]) * 255).round().astype(int)
        y = margin + (2 + i) * th
        out.append(f'<rect x="{x:.9g}" y="{y:.9g}" width="{2 * th:.4g}" height="{th:.4g}" '
                   f'fill="#{r:02x}{g:02x}{b:02x}"/>')
        out.append(f'<text x="{x + 2.5 * th:.9g}" y="{y + 0.8 * th:.9g}">{v:.3f}{"+" if i == 0 else ""}</text>')
    y = margin + (3 + steps + 0.5) * th
    out.append(f'<rect x="{x:.9g}" y="{y:.9g}" width="{2 * th:.4g}" height="{th:.4g}" fill="#e60000"/>')
    out.append(f'<text x="{x + 2.5 * th:.9g}" y="{y + 0.8 * th:.9g}">flipped ({int((~finite).sum())})</text>')
    out.append("</g>")
    return out
