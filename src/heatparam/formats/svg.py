"""SVG flat pattern: the DXF's content as styled groups, at its physical size.

Groups (``<g id=...>``): ``strain`` (with ``strain_map``: every face filled by its true-scale isometric distortion,
and a ``legend``), ``sheet`` (sheet frames), ``outline`` (one closed ``<polygon>`` per chart outer loop: the cut),
``holes`` (one ``<polygon>`` per hole), ``seams`` (one ``<polyline>`` per seam side with its label) and
``annotation`` (chart ids, distortion summary, units). The root's ``width``/``height`` are physical lengths in
the declared units (m → mm, ft → in) and its ``viewBox`` is in model units, so one user unit = one model unit;
the UV ``v`` axis points up (the SVG y axis is flipped). An atlas packed into texture space ([0,1]², ``pack
texture``) is drawn at the texture's size in pixels instead, and says so.

Labels never overlap (``formats.labels``): each sits inside its chart, sized to it; those that fit nowhere are left
out and a note under the pattern counts them.
"""

from __future__ import annotations

import os
import textwrap
from xml.sax.saxutils import escape

import numpy as np

from heatparam.formats.dxf import text_height
from heatparam.formats.labels import GLYPH_WIDTH, Labels, place_labels
from heatparam.formats.pattern import Pattern, face_iso, sheet_notes
from heatparam.formats.preview import distortion_range
from heatparam.formats.units import svg_length, uv_unit

STYLE = """
  .cut { fill: none; stroke: #000000; }
  .hole { fill: none; stroke: #d62728; }
  .seam { fill: none; stroke: #1f5fd6; stroke-dasharray: DASH; }
  .sheet { fill: none; stroke: #888888; }
  .label { font-family: sans-serif; fill: #1f5fd6; text-anchor: middle; dominant-baseline: middle; }
  .note { font-family: sans-serif; fill: #2a7d2a; }
  .chart { text-anchor: middle; dominant-baseline: middle; }
"""


def _fmt(P: np.ndarray) -> str:
    return " ".join(f"{x:.9g},{y:.9g}" for x, y in P)


def write_svg(path: str | os.PathLike, pattern: Pattern, units: str = "mm", title: str = "",
              V: np.ndarray | None = None, strain_map: bool = False, vmax: float | None = None,
              texture: int | None = None) -> dict:
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
    vmax : top of the colour scale (default: the preview's, ``preview.distortion_range``).
    texture : the texture's size in pixels when the pattern's UVs are texture space ([0,1]²): the SVG is that many
        pixels across per UV unit, and its notes and chart summaries say texture space instead of ``units``.

    Returns
    -------
    dict
        ``{"format": "svg", "units", "width", "height", "outlines", "holes", "seam_labels", "labels_left_out",
        "strain_map"}``.
    """
    th = text_height(pattern)
    lo, hi = pattern.bbox
    margin = 2 * th
    labels = place_labels(pattern, th, {ch.id: _summary(ch, units, texture) for ch in pattern.charts}, _upright)
    legend_w = 12 * th if strain_map else 0.0
    x0, y_top = lo[0] - margin, hi[1] + margin
    W = float(hi[0] - lo[0] + 2 * margin + legend_w)
    notes = _notes(units, texture, title, labels, chars=max(20, int((W - 2 * margin) / (GLYPH_WIDTH * th))))
    H = float(hi[1] - lo[1] + 2 * margin + (1.5 * len(notes) + 1) * th)

    def tr(P):  # model (u, v) → SVG user units (x right, y down)
        P = np.atleast_2d(P)
        return np.column_stack([P[:, 0] - x0, y_top - P[:, 1]])

    sw = th / 8
    width, height = (f"{x * texture:.6g}px" if texture else svg_length(x, units) for x in (W, H))
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {W:.9g} {H:.9g}" '
           f'data-units="{"texture" if texture else units}">',
           f"<title>{escape(title or 'heatparam flat pattern')} (units: {uv_unit(units, texture)})</title>",
           f"<style>{STYLE.replace('DASH', f'{2 * th:.4g} {th:.4g}')}</style>"]
    if strain_map:
        if V is None:
            raise ValueError("strain_map needs V")
        out += _strain_group(pattern, V, tr, vmax, th, W, margin, sw)
    out += _sheet_group(pattern, tr, sw)
    loops, n_holes = _loop_groups(pattern, tr, sw)
    out += loops
    out += _seam_group(pattern, tr, sw, labels)
    out += _annotation_group(tr, th, notes, H, margin, labels)
    out.append("</svg>")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(out) + "\n")
    return {"format": "svg", "units": units, "width": width, "height": height, "outlines": len(pattern.charts),
            "holes": n_holes, "seam_labels": sum(lb.kind == "seam" for lb in labels.placed),
            "labels_left_out": labels.left_out, "strain_map": bool(strain_map)}


def _summary(ch, units: str, texture: int | None) -> list[str]:
    """A chart's summary lines, short enough to fit inside it: its distortion and outline (in texture space the
    outline in pixels; the distortion at the texture's common scale is no isometric distortion: see the report)."""
    if texture:
        return [f"outline {ch.outer.length_uv * texture:.0f} px, 3D {ch.outer.length_3d:.4g} {units}"]
    return [f"iso mean {ch.iso_mean:.4f}, max {ch.iso_max:.4f}",
            f"outline {ch.outer.length_uv:.4g} {units}, 3D {ch.outer.length_3d:.4g} {units}"]


def _notes(units: str, texture: int | None, title: str, labels: Labels, *, chars: int) -> list[str]:
    """The lines under the pattern, at most ``chars`` characters each: its units, what labels were left out, the
    title."""
    out = [f"units: {uv_unit(units, texture)}"]
    left = [f"{n} {what}" for what, n in (("chart ids", labels.left_out["chart"]),
                                           ("chart summaries", labels.left_out["summary"]),
                                           ("seam labels", labels.left_out["seam"])) if n]
    if left:
        out += textwrap.wrap(f"not drawn, no room: {', '.join(left)} (the DXF has all)", chars)
    return out + ([title] if title else [])


def _sheet_group(pattern: Pattern, tr, sw: float) -> list[str]:
    """The ``sheet`` group (one rectangle per sheet frame), or nothing without sheets."""
    if not len(pattern.sheets):
        return []
    out = [f'<g id="sheet" class="sheet" stroke-width="{sw:.4g}">']
    th = text_height(pattern)
    for (sx, sy, w, h), note in zip(pattern.sheets, sheet_notes(pattern), strict=True):
        P = tr(np.array([[sx, sy], [sx + w, sy], [sx + w, sy + h], [sx, sy + h]]))
        out.append(f'<polygon points="{_fmt(P)}"/>')
        x, y = tr(np.array([sx, sy - 1.2 * th]))[0]  # under the frame, in the drawing's margin
        out.append(f'<text x="{x:.6g}" y="{y:.6g}" font-size="{th:.4g}" stroke="none" fill="#888888">'
                   f'{escape(note)}</text>')
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


def _seam_group(pattern: Pattern, tr, sw: float, labels: Labels) -> list[str]:
    """The ``seams`` group: one polyline per seam side, and the seam labels placed, turned along their seam."""
    out = [f'<g id="seams" stroke-width="{sw:.4g}">']
    for s in pattern.seams:
        out.append(f'<polyline class="seam" data-label="{s.label}" points="{_fmt(tr(pattern.uv[s.rows]))}"/>')
    for lb in labels.placed:
        if lb.kind == "seam":
            x, y = tr([lb.x, lb.y])[0]
            out.append(f'<text class="label" x="{x:.9g}" y="{y:.9g}" font-size="{lb.size:.4g}" '
                       f'transform="rotate({-lb.angle:.4g} {x:.9g} {y:.9g})">{lb.text}</text>')
    out.append("</g>")
    return out


def _annotation_group(tr, th: float, notes: list[str], H: float, margin: float, labels: Labels) -> list[str]:
    """The ``annotation`` group: chart ids and their distortion summaries where placed, then the notes (units,
    labels left out, title)."""
    n_notes = len(notes)
    out = ['<g id="annotation" class="note">']
    for lb in labels.placed:
        if lb.kind != "seam":
            x, y = tr([lb.x, lb.y])[0]
            out.append(f'<text class="chart" x="{x:.9g}" y="{y:.9g}" font-size="{lb.size:.4g}">{escape(lb.text)}'
                       "</text>")
    for i, line in enumerate(notes):
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
    if vmax is None:  # the preview's scale: the two pictures of one map read alike
        vmax = distortion_range(iso)
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
