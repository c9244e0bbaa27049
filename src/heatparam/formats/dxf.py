"""DXF flat pattern (ezdxf): cut outlines, holes, seams and annotations at true scale.

Layers: ``OUTLINE`` (each chart's outer loop, a closed LWPOLYLINE), ``HOLES`` (each hole loop, closed),
``SEAMS`` (each side of each seam as an open polyline with its label ``S1, S2, ...`` — the same label on both
sides), ``ANNOTATION`` (chart ids, a distortion summary per chart, the units), and ``SHEET`` (sheet frames with
``--sheet``). Coordinates are the laid-out UVs in model units; ``$INSUNITS`` declares the units. The file is
byte-for-byte deterministic (ezdxf's fixed header dates and GUIDs instead of the save time and random GUIDs).
"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from heatparam.formats.labels import place_labels
from heatparam.formats.pattern import Pattern, sheet_notes
from heatparam.formats.units import insunits

LAYERS = {"OUTLINE": 7, "HOLES": 1, "SEAMS": 5, "ANNOTATION": 3, "SHEET": 8}  # layer → ACI colour


def text_height(pattern: Pattern) -> float:
    """Annotation text height: 1.5% of the pattern's bounding-box diagonal."""
    lo, hi = pattern.bbox
    return 0.015 * float(np.linalg.norm(hi - lo)) or 1.0


def chart_summary(chart, units: str) -> list[str]:
    """Two lines: the chart's true-scale isometric distortion, and its outline length in the plane and in 3D."""
    return [f"iso mean {chart.iso_mean:.4f} max {chart.iso_max:.4f}",
            f"outline {chart.outer.length_uv:.6g} {units} (3D {chart.outer.length_3d:.6g}, stretch "
            f"{chart.outer.stretch:.4f})"]


def write_dxf(path: str | os.PathLike, pattern: Pattern, units: str = "mm", title: str = "") -> dict:
    """Write ``pattern`` (already laid out) as a DXF R2010 file.

    Parameters
    ----------
    path : output file (written directly: use ``formats.outputs.commit_outputs`` for the all-or-nothing commit).
    pattern : a laid-out :class:`~heatparam.formats.pattern.Pattern`.
    units : one of ``formats.units.UNITS``; sets ``$INSUNITS`` and ``$MEASUREMENT`` and is stated on ANNOTATION.
    title : a line written on ANNOTATION below the pattern (e.g. the input name).

    Returns
    -------
    dict
        ``{"format": "dxf", "units", "charts", "outlines", "holes", "seam_labels", "sheets"}`` counts.
    """
    import ezdxf
    from ezdxf.enums import TextEntityAlignment

    with _fixed_metadata():
        doc = ezdxf.new("R2010", setup=False)
    doc.header["$INSUNITS"] = insunits(units)
    doc.header["$MEASUREMENT"] = 0 if units in ("in", "ft") else 1
    for name, color in LAYERS.items():
        doc.layers.add(name, color=color)
    msp = doc.modelspace()
    th = text_height(pattern)
    uv = pattern.uv
    n_holes = 0
    for ch in pattern.charts:
        for lp in ch.loops:
            layer = "OUTLINE" if lp.kind == "outer" else "HOLES"
            msp.add_lwpolyline(uv[lp.rows].tolist(), format="xy", close=True, dxfattribs={"layer": layer})
            n_holes += lp.kind == "hole"
    for s in pattern.seams:
        msp.add_lwpolyline(uv[s.rows].tolist(), format="xy", close=False, dxfattribs={"layer": "SEAMS"})
    for x0, y0, w, h in pattern.sheets:
        msp.add_lwpolyline([(x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h)], format="xy", close=True,
                           dxfattribs={"layer": "SHEET"})
    labels = place_labels(pattern, th, {ch.id: chart_summary(ch, units) for ch in pattern.charts}, readable_angle)
    for lb in labels.placed:
        msp.add_text(lb.text, height=lb.size, rotation=lb.angle,
                     dxfattribs={"layer": "SEAMS" if lb.kind == "seam" else "ANNOTATION"}).set_placement(
            (lb.x, lb.y), align=TextEntityAlignment.MIDDLE_CENTER)
    lo, _ = pattern.bbox
    left = ", ".join(f"{n} {what}" for what, n in labels.left_out.items() if n)
    lines = [f"units: {units}", *([f"left out (no room): {left}"] if left else []), *([title] if title else []),
             *sheet_notes(pattern)]
    for i, line in enumerate(lines):
        msp.add_text(line, height=th, dxfattribs={"layer": "ANNOTATION"}).set_placement(
            (lo[0], lo[1] - (2 + 1.5 * i) * th), align=TextEntityAlignment.LEFT)
    # the CLASSES section in a fixed order: ezdxf registers classes in an order that depends on the documents this
    # process made before (the same map gave different bytes in a fresh process and after other DXFs)
    doc.classes.add_required_classes(doc.dxfversion)
    doc.classes.classes = type(doc.classes.classes)(sorted(doc.classes.classes.items()))
    with _fixed_metadata():
        doc.saveas(os.fspath(path))
    return {"format": "dxf", "units": units, "charts": len(pattern.charts), "outlines": len(pattern.charts),
            "holes": n_holes, "seam_labels": sum(lb.kind == "seam" for lb in labels.placed),
            "labels_left_out": labels.left_out, "sheets": len(pattern.sheets)}


@contextlib.contextmanager
def _fixed_metadata():
    """Deterministic bytes: ezdxf otherwise stamps the creation/save time and random GUIDs into the file."""
    import ezdxf

    fixed = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True
    try:
        yield
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = fixed


def readable_angle(angle: float) -> float:
    """Text rotation along a seam, turned so the text never reads upside down."""
    a = (angle + 180.0) % 360.0 - 180.0
    return a + 180.0 if a < -90 else a - 180.0 if a > 90 else a
