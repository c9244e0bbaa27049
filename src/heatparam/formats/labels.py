"""Where a flat pattern's labels go (the SVG's and the DXF's chart ids, chart summaries and seam labels):
inside their chart, sized to it, never over one another.

A label is a box centred on its point, :data:`GLYPH_WIDTH` × its size wide per character and its size tall, with
:data:`PAD` around it, turned by its angle; boxes are compared by their axis-aligned bounds (a turned label claims
a little more room than it covers). Chart ids are placed first, then the charts' summaries, then the seam labels:
each at its size or smaller (down to :data:`MIN_SIZE` of the annotation height), inside its chart (every corner
for an id or a summary, the centre for a seam label, which sits beside the cut), clear of every label already
placed. A label that fits nowhere is left out and counted (:class:`Labels`), for a note under the pattern.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from heatparam.formats.pattern import Pattern

#: Mean advance of a sans-serif glyph in font sizes (DejaVu Sans: digits 0.64, capitals up to 0.72, lower case
#: about 0.6): a label's box is this wide per character.
GLYPH_WIDTH = 0.65
#: Clearance around each box, in font sizes, so that neighbouring labels do not touch.
PAD = 0.1
#: The smallest label, as a fraction of the annotation height: smaller text is not read, so it is left out.
MIN_SIZE = 0.3
#: The sizes tried, as fractions of a label's own size, largest first.
SHRINK = (1.0, 0.7, 0.5, 0.35)
#: Points tried for a chart's id: the face centroids nearest its bounding box's centre.
CANDIDATES = 12


class Label(NamedTuple):
    """One placed label: its text, centre (u, v), font size and angle (degrees, counter-clockwise, readable)."""

    text: str
    x: float
    y: float
    size: float
    angle: float
    kind: str  # "chart", "summary" or "seam"


class Labels(NamedTuple):
    """The labels placed and how many of each kind were left out (no room, or a chart too small for them)."""

    placed: list[Label]
    left_out: dict[str, int]


def label_box(text: str, x: float, y: float, size: float, angle: float = 0.0, pad: float = PAD) -> np.ndarray:
    """(4,) ``x0, y0, x1, y1``: the axis-aligned bounds of a label's box (``pad`` font sizes around it)."""
    w, h = (GLYPH_WIDTH * len(text) + 2 * pad) * size, (1 + 2 * pad) * size
    c, s = abs(math.cos(math.radians(angle))), abs(math.sin(math.radians(angle)))
    hx, hy = (c * w + s * h) / 2, (s * w + c * h) / 2
    return np.array([x - hx, y - hy, x + hx, y + hy])


def place_labels(pattern: Pattern, th: float, summaries: dict[int, list[str]], seam_angle) -> Labels:
    """Every label of ``pattern`` placed (module docstring). ``th``: the annotation height (a seam label's size, half
    a chart id's); ``summaries``: each chart's summary lines by chart id; ``seam_angle``: a seam side's angle →
    its readable text angle."""
    from matplotlib.path import Path

    room = _Room()
    left = {"chart": 0, "summary": 0, "seam": 0}
    outlines = {c.id: Path(pattern.uv[c.outer.rows]) for c in pattern.charts}
    placed: list[Label] = []
    ids = {}
    for ch in pattern.charts:
        label = _chart_id(pattern, ch, th, outlines[ch.id], room)
        ids[ch.id] = label
        placed += [label] if label else []
        left["chart"] += label is None
    for ch in pattern.charts:
        lines = _summary(ids[ch.id], summaries.get(ch.id, []), pattern, ch, th, outlines[ch.id], room)
        placed += lines
        left["summary"] += bool(summaries.get(ch.id)) and not lines
    smaller_side = {c.id: float(_extent(pattern, c).min()) for c in pattern.charts}
    for s in pattern.seams:
        label = _seam_label(s, th, smaller_side.get(s.chart), seam_angle(s.angle), outlines.get(s.chart), room)
        placed += [label] if label else []
        left["seam"] += label is None
    return Labels(placed, left)


class _Room:
    """The boxes of the labels placed so far."""

    def __init__(self):
        self.boxes = np.zeros((0, 4))

    def take(self, box: np.ndarray) -> bool:
        """Claim ``box`` when it overlaps no box claimed before."""
        b = self.boxes
        if np.any((b[:, 0] < box[2]) & (box[0] < b[:, 2]) & (b[:, 1] < box[3]) & (box[1] < b[:, 3])):
            return False
        self.boxes = np.vstack([b, box])
        return True


def _extent(pattern: Pattern, chart) -> np.ndarray:
    """(2,) the chart's width and height."""
    P = pattern.uv[chart.rows]
    return P.max(axis=0) - P.min(axis=0)


def _inside(outline, box: np.ndarray) -> bool:
    x0, y0, x1, y1 = box
    return bool(outline.contains_points([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]).all())


def _chart_id(pattern: Pattern, ch, th: float, outline, room: _Room) -> Label | None:
    """The chart's id ``C<n>``: 2 × ``th`` tall or smaller, inside the chart, near its middle."""
    text = f"C{ch.id}"
    w, h = _extent(pattern, ch)
    size = min(2 * th, 0.9 * w / (GLYPH_WIDTH * len(text) + 2 * PAD), 0.5 * h)
    P = pattern.uv[pattern.Fuv[ch.faces]].mean(axis=1)
    lo, hi = pattern.uv[ch.rows].min(axis=0), pattern.uv[ch.rows].max(axis=0)
    points = P[np.argsort(np.linalg.norm(P - (lo + hi) / 2, axis=1), kind="stable")[:CANDIDATES]]
    for f in SHRINK:
        if size * f < MIN_SIZE * th:
            break
        for x, y in points:
            box = label_box(text, x, y, size * f)
            if _inside(outline, box) and room.take(box):
                return Label(text, float(x), float(y), size * f, 0.0, "chart")
    return None


def _summary(chart_label: Label | None, lines: list[str], pattern: Pattern, ch, th: float, outline,
             room: _Room) -> list[Label]:
    """The chart's summary lines under its id (or over it), as large as fits (at most 0.6 × ``th``), all of them or
    none."""
    if chart_label is None or not lines:
        return []
    w = _extent(pattern, ch)[0]
    size = min(0.6 * th, 0.9 * w / (GLYPH_WIDTH * max(len(t) for t in lines) + 2 * PAD))
    for f in SHRINK:
        sh = size * f
        if sh < MIN_SIZE * th:
            break
        step = sh * (1 + 2 * PAD)
        below = chart_label.y - chart_label.size * (0.5 + PAD) - sh * (0.5 + PAD)
        above = chart_label.y + chart_label.size * (0.5 + PAD) + (len(lines) - 1) * step + sh * (0.5 + PAD)
        for y0 in (below, above):
            out = [Label(t, chart_label.x, y0 - i * step, sh, 0.0, "summary") for i, t in enumerate(lines)]
            boxes = [label_box(lb.text, lb.x, lb.y, sh) for lb in out]
            if all(_inside(outline, b) for b in boxes) and _take_all(room, boxes):
                return out
    return []


def _take_all(room: _Room, boxes: list[np.ndarray]) -> bool:
    """Claim every box of ``boxes`` or none."""
    before = room.boxes
    if all(room.take(b) for b in boxes):
        return True
    room.boxes = before
    return False


def _seam_label(s, th: float, limit: float | None, angle: float, outline, room: _Room) -> Label | None:
    """A seam side's label beside the cut, inside its chart: ``th`` tall or smaller (a quarter of the chart's
    smaller side at most)."""
    size = th if limit is None else min(th, 0.25 * limit)
    for f in SHRINK:
        sz = size * f
        if sz < MIN_SIZE * th:
            break
        x, y = s.label_point(0.8 * sz)
        box = label_box(s.label, x, y, sz, angle)
        if (outline is None or outline.contains_point((x, y))) and room.take(box):
            return Label(s.label, float(x), float(y), sz, angle, "seam")
    return None
