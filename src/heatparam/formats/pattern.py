"""Flat patterns: the cut outline, holes and seams of a map, chart by chart, laid out without overlap.

A map is given as arrays: ``uv (k,2)`` rows, ``Fuv (m,3)`` the rows at each face's corners, ``uv_vertex (k,)``
the 3D vertex of each row, and optionally ``chart (m,)`` a chart id per face (an atlas). :func:`build_pattern`
finds per chart its UV boundary loops (outer = the largest enclosed area, the others are holes) and the seams:
UV boundary edges whose 3D edge is interior to the mesh (two faces share it in ``F``), with the two sides of each
seam curve paired and labelled ``S1, S2, ...`` at both sides. The DXF and SVG writers draw a :class:`Pattern`.

Layout (:func:`layout_charts`): charts whose UV bounding boxes overlap are moved apart by a shelf arrangement of
their bounding boxes (tallest first, rows of a width chosen to give a roughly square pattern), with a gap; with a
sheet size the same shelves fill sheets of that size, opening a new sheet when a chart fits on no open shelf and
under no existing one (first-fit decreasing height). Why shelves: charts are translated only — never rotated or
mirrored, so each chart keeps the orientation of the map (and of the OBJ's UVs) and its grain direction; the
bounding boxes of a pattern of a few to a few hundred charts are packed in O(c log c) with a waste that is small
next to the gap the cutter needs anyway (FFDH uses at most 1.7 x the optimal height plus one shelf). A chart that
is larger than the sheet is refused (one-line error) rather than split or scaled: the pattern must stay at true
scale.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.mesh.nest import Piece, SheetNester, orientations
from heatparam.mesh.planar import covered_area, polygon_area
from heatparam.options import GRAIN_RULES, NEST_TIME

#: Gap between laid-out charts (and to the sheet's edge), as a fraction of the largest chart's bounding-box
#: diagonal.
GAP_FRACTION = 0.04
#: With sheets, the gap is at most this fraction of the sheet's shorter side.
SHEET_GAP_FRACTION = 0.02
#: With sheets nested by outlines, the default gap is at most this fraction of the sheet's shorter side (a cutter's
#: spacing: 5 mm on a 1 m sheet).
NEST_GAP_FRACTION = 0.005


@dataclass
class Loop:
    """One closed UV boundary loop of a chart.

    rows : (p,) int64 uv rows in order (the last connects back to the first), counter-clockwise for the
        outer loop and clockwise for holes when the chart is not mirrored.
    kind : ``"outer"`` or ``"hole"``.
    length_3d : length of the loop on the surface (sum of the 3D edge lengths).
    length_uv : length of the loop in the plane.
    """

    rows: np.ndarray
    kind: str
    length_3d: float
    length_uv: float
    signed_area: float

    @property
    def stretch(self) -> float:
        """length_uv / length_3d (1 = the loop keeps its length)."""
        return self.length_uv / self.length_3d if self.length_3d > 0 else float("nan")


@dataclass
class SeamSide:
    """One side of a seam curve: the uv rows along it (an open chain), its chart and where its label goes."""

    label: str
    chart: int
    rows: np.ndarray
    label_at: np.ndarray  # (2,) UV point: the midpoint of the middle edge of the chain
    angle: float  # direction of that edge, degrees (for text placed along the seam)
    inward: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) unit normal of that edge into the chart

    def label_point(self, offset: float) -> np.ndarray:
        """Where to put the label: ``offset`` from the seam into the chart, so the text does not sit on the cut."""
        return self.label_at + offset * self.inward


@dataclass
class Chart:
    """One piece of the pattern: its faces, boundary loops (outer first), distortion and placement."""

    id: int
    faces: np.ndarray  # (mc,) int64 face indices
    rows: np.ndarray  # (kc,) int64 uv rows used by the chart
    loops: list[Loop]
    area_3d: float
    iso_mean: float  # area-weighted mean of max(sigma1, 1/sigma2), true scale (no normalization)
    iso_max: float
    offset: np.ndarray = field(default_factory=lambda: np.zeros(2))  # translation applied by the layout
    sheet: int = 0
    turn: np.ndarray = field(default_factory=lambda: np.eye(2))  # (2,2) rotation applied by the layout, first

    @property
    def outer(self) -> Loop:
        return self.loops[0]

    @property
    def holes(self) -> list[Loop]:
        return self.loops[1:]


@dataclass
class Pattern:
    """A flat pattern: charts (loops in ``uv`` rows), seams and the laid-out coordinates.

    uv : (k,2) float64 the laid-out UV (each chart translated by its ``offset``; a single chart or charts whose
        bounding boxes do not overlap are not moved).
    sheets : (s,4) float64 sheet frames ``x0, y0, width, height`` in UV units, or an empty (0,4) array.
    sheet_use : (s,) float64 the fraction of each sheet's area its pieces cover.
    nesting : how the sheets were filled (``"shelf"`` or the nesting's search facts), empty without sheets.
    """

    charts: list[Chart]
    seams: list[SeamSide]
    uv: np.ndarray
    uv_vertex: np.ndarray
    F: np.ndarray
    Fuv: np.ndarray
    chart_of_face: np.ndarray
    sheets: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    sheet_use: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nesting: dict = field(default_factory=dict)

    @property
    def bbox(self) -> np.ndarray:
        """(2,2) lower-left and upper-right corner of everything drawn (charts and sheets)."""
        used = np.unique(self.Fuv)
        lo, hi = self.uv[used].min(axis=0), self.uv[used].max(axis=0)
        if len(self.sheets):
            lo = np.minimum(lo, self.sheets[:, :2].min(axis=0))
            hi = np.maximum(hi, (self.sheets[:, :2] + self.sheets[:, 2:]).max(axis=0))
        return np.array([lo, hi])

    def loop_points(self, loop: Loop) -> np.ndarray:
        """(p,2) laid-out points of a loop."""
        return self.uv[loop.rows]


def _closed_length(P: np.ndarray) -> float:
    return float(np.linalg.norm(P - np.roll(P, -1, axis=0), axis=1).sum())


def build_pattern(V: np.ndarray, F: np.ndarray, uv: np.ndarray, Fuv: np.ndarray, uv_vertex: np.ndarray,
                  chart: np.ndarray | None = None) -> Pattern:
    """Boundary loops (outer and holes) per chart, and the seams between chart borders.

    Parameters
    ----------
    V : (n,3) float64 vertex positions.
    F : (m,3) int64 triangles.
    uv : (k,2) float64 map rows (model units).
    Fuv : (m,3) int64 rows of ``uv`` at each face's corners.
    uv_vertex : (k,) int64 the vertex of ``V`` each uv row is the image of.
    chart : (m,) int chart id per face, or None (one chart).

    Returns
    -------
    Pattern
        Charts sorted by id, each with its loops (outer first, then holes by decreasing length), seam sides
        labelled ``S1, S2, ...`` (each label on exactly two sides), ``uv`` not yet laid out (a copy).

    Raises
    ------
    HeatparamError
        When the arrays disagree in shape, a uv row is used by two charts, or a chart's UV boundary is not a set
        of closed loops.
    """
    V, F, uv, Fuv, uv_vertex, chart = _checked_map(V, F, uv, Fuv, uv_vertex, chart)
    interior = _interior_edge_keys(V, F)
    from heatparam.metrics import true_scale_iso

    iso, a3, _ = true_scale_iso(V, F, uv, Fuv)
    charts: list[Chart] = []
    seam_edges = []  # (3D key, chart, row a, row b) for each UV boundary half-edge on an interior 3D edge
    order = np.argsort(chart, kind="stable")  # each chart's faces, in order, without a pass over all per chart
    ids, starts = np.unique(chart[order], return_index=True)
    for c, faces in zip(ids.tolist(), np.split(order, starts[1:]), strict=True):
        loops = _chart_loops(c, Fuv[faces], V, uv, uv_vertex, interior, seam_edges)
        rows_c = np.unique(Fuv[faces])
        good = np.isfinite(iso[faces])
        w = a3[faces]
        iso_mean = float(np.dot(w[good], iso[faces][good]) / w[good].sum()) if good.any() else float("inf")
        charts.append(Chart(int(c), faces, rows_c, loops, float(w.sum()), iso_mean, float(iso[faces].max())))
    orientation = {c.id: 1.0 if c.outer.signed_area >= 0 else -1.0 for c in charts}
    seams = _pair_seams(seam_edges, uv, uv_vertex, orientation)
    return Pattern(charts, seams, uv, uv_vertex, F, Fuv, chart)


def _checked_map(V, F, uv, Fuv, uv_vertex, chart) -> tuple:
    """:func:`build_pattern`'s arrays with their dtypes (``uv`` copied), checked, and ``chart`` filled in (None ->
    zeros): (V, F, uv, Fuv, uv_vertex, chart). Raises HeatparamError."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    uv = np.array(uv, dtype=np.float64)
    Fuv = np.asarray(Fuv, dtype=np.int64)
    uv_vertex = np.asarray(uv_vertex, dtype=np.int64)
    m = len(F)
    if Fuv.shape != F.shape or uv.ndim != 2 or uv.shape[1] != 2 or uv_vertex.shape != (len(uv),):
        raise HeatparamError(f"pattern: inconsistent map arrays (F {F.shape}, Fuv {Fuv.shape}, uv {uv.shape}, "
                             f"uv_vertex {uv_vertex.shape})")
    if not np.array_equal(uv_vertex[Fuv], F):
        raise HeatparamError("pattern: uv_vertex[Fuv] must equal F (each uv row is the image of its face's vertex)")
    chart = np.zeros(m, dtype=np.int64) if chart is None else np.asarray(chart, dtype=np.int64)
    if chart.shape != (m,):
        raise HeatparamError(f"pattern: chart must have one id per face ({m}), got shape {chart.shape}")
    row_chart = np.full(len(uv), -1, dtype=np.int64)
    row_chart[Fuv.ravel()] = np.repeat(chart, 3)
    if not np.array_equal(row_chart[Fuv], np.repeat(chart, 3).reshape(-1, 3)):
        raise HeatparamError("pattern: a uv row is shared by faces of two charts (give each chart its own rows)")
    return V, F, uv, Fuv, uv_vertex, chart


def _interior_edge_keys(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Sorted keys ``a * len(V) + b`` (a < b) of the interior 3D edges: those used by two faces of F."""
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key3 = np.sort(he, axis=1) @ np.array([len(V), 1], dtype=np.int64)
    k_unique, k_count = np.unique(key3, return_counts=True)
    return k_unique[k_count >= 2]


def _chart_loops(c: int, Fc: np.ndarray, V: np.ndarray, uv: np.ndarray, uv_vertex: np.ndarray,
                 interior: np.ndarray, seam_edges: list) -> list[Loop]:
    """The boundary loops of chart ``c`` (faces Fc (mc,3) of uv rows): outer first, then the holes by decreasing 3D
    length. Appends its boundary half-edges on interior 3D edges to ``seam_edges``. Raises HeatparamError."""
    from heatparam.mesh.topology import boundary_edges, boundary_loops

    loops_rows = boundary_loops(Fc)
    if sum(len(r) for r in loops_rows) != len(boundary_edges(Fc)):  # an open chain has one row more
        raise HeatparamError(f"pattern: the UV boundary of chart {c} is not a set of closed loops "
                             "(inconsistently oriented faces?)")
    loops = []
    for rows in loops_rows:
        nxt = np.roll(rows, -1)
        P = uv[rows]
        L3 = float(np.linalg.norm(V[uv_vertex[rows]] - V[uv_vertex[nxt]], axis=1).sum())
        loops.append(Loop(rows.astype(np.int64), "hole", L3, _closed_length(P), polygon_area(P)))
        k = np.sort(np.stack([uv_vertex[rows], uv_vertex[nxt]], axis=1), axis=1) @ np.array([len(V), 1])
        pos = np.minimum(np.searchsorted(interior, k), len(interior) - 1)  # interior is sorted
        for i in np.flatnonzero(interior[pos] == k) if len(interior) else []:
            seam_edges.append((int(k[i]), c, int(rows[i]), int(nxt[i])))
    if not loops:
        raise HeatparamError(f"pattern: chart {c} has no boundary (a closed surface cannot be laid flat)")
    outer = int(np.argmax([abs(lp.signed_area) for lp in loops]))
    loops[outer].kind = "outer"
    return [loops[outer]] + sorted((lp for i, lp in enumerate(loops) if i != outer), key=lambda lp: -lp.length_3d)


def _pair_seams(seam_edges: list, uv: np.ndarray, uv_vertex: np.ndarray, orientation: dict) -> list[SeamSide]:
    """Group seam half-edges into curves (chains of 3D seam edges between branch points or chart changes) and
    label each curve's two sides alike."""
    if not seam_edges:
        return []
    by_key: dict[int, list] = {}
    for e in seam_edges:
        by_key.setdefault(e[0], []).append(e)
    sides = []
    for n, chain in enumerate(_seam_curves(by_key, uv_vertex), start=1):
        picked = _chain_sides(chain, by_key)
        for side in range(2):
            sides.append(_seam_side(f"S{n}", [pk[side] for pk in picked], uv, orientation))
    return sides


def _seam_curves(by_key: dict[int, list], uv_vertex: np.ndarray) -> list[list[int]]:
    """The seam edges (keys of ``by_key``: their two half-edges) chained into curves: each chain runs through
    vertices of seam degree 2 while the pair of charts on its sides stays the same."""
    keys = sorted(k for k, sides in by_key.items() if len(sides) == 2)  # a seam edge has exactly two sides
    vert_edges: dict[int, list[int]] = {}  # 3D vertex → its seam edges
    for k in keys:
        a, b = (int(x) for x in sorted(uv_vertex[[by_key[k][0][2], by_key[k][0][3]]]))
        for v in (a, b):
            vert_edges.setdefault(v, []).append(k)

    def ends(k):
        e = by_key[k][0]
        return int(uv_vertex[e[2]]), int(uv_vertex[e[3]])

    def charts_of(k):
        return tuple(sorted(s[1] for s in by_key[k]))

    seen: set[int] = set()
    curves = []
    for k0 in keys:
        if k0 in seen:
            continue
        seen.add(k0)
        chain = [k0]
        for direction in (0, 1):
            v = ends(k0)[direction]
            while len(vert_edges[v]) == 2:
                k = next(x for x in vert_edges[v] if x != (chain[-1] if direction == 1 else chain[0]))
                if k in seen or charts_of(k) != charts_of(k0):
                    break
                seen.add(k)
                if direction == 1:
                    chain.append(k)
                else:
                    chain.insert(0, k)
                a, b = ends(k)
                v = b if a == v else a
        curves.append(chain)
    return curves


def _chain_sides(chain: list[int], by_key: dict[int, list]) -> list[list]:
    """The two half-edges of each edge of a chain, ordered so that position 0 (and 1) is one side all along.

    The side of the next edge is the one that shares a uv row with this side's previous edge (both sides of an
    edge are in one chart or in two: ordering by chart is not enough for a seam inside one chart).
    """
    picked = [list(by_key[chain[0]])]
    for k in chain[1:]:
        e, f = by_key[k]
        p0, p1 = picked[-1]
        keep = {e[2], e[3]} & {p0[2], p0[3]} or {f[2], f[3]} & {p1[2], p1[3]}
        swap = {f[2], f[3]} & {p0[2], p0[3]} or {e[2], e[3]} & {p1[2], p1[3]}
        picked.append([f, e] if swap and not keep else [e, f])
    return picked


def _seam_side(label: str, edges: list, uv: np.ndarray, orientation: dict) -> SeamSide:
    """One side of a seam curve (its half-edges in curve order), labelled at its middle edge."""
    e_mid = edges[len(edges) // 2]
    p, q = uv[e_mid[2]], uv[e_mid[3]]
    d = q - p
    # a boundary half-edge runs with the chart on its left (counter-clockwise faces); sign = orientation of the
    # chart's faces in the plane, so a mirrored chart gets the right side too
    left = np.array([-d[1], d[0]]) / (np.linalg.norm(d) or 1.0)
    return SeamSide(label, int(e_mid[1]), _chain_rows([(e[2], e[3]) for e in edges]), (p + q) / 2,
                    float(np.degrees(np.arctan2(d[1], d[0]))), left * orientation[int(e_mid[1])])


def _chain_rows(edges: list[tuple[int, int]]) -> np.ndarray:
    """Rows of a chain of directed row-edges given in curve order (each side may run either way)."""
    if len(edges) == 1:
        return np.array(edges[0], dtype=np.int64)
    out = []
    for i, (a, b) in enumerate(edges):
        if i == 0:
            na, nb = edges[1]
            out = [a, b] if b in (na, nb) else [b, a]
        else:
            out.append(b if a == out[-1] else a)
    return np.array(out, dtype=np.int64)


def layout_charts(pattern: Pattern, sheet: tuple[float, float] | None = None, gap: float | None = None, *,
                  units: str = "model units", grain: str = "free", nest_time: float = NEST_TIME,
                  seed: int = 0) -> Pattern:
    """Move charts apart (in place; returns the pattern): rigid motions only, each chart's shape unchanged.

    Without ``sheet``, charts whose bounding boxes are already pairwise disjoint keep their positions (a single
    chart is never moved, so the pattern matches the map's UVs exactly); otherwise all charts are placed on
    shelves (tallest first) of a width that makes the arrangement roughly square. With ``sheet = (W, H)`` (UV
    units) charts are nested onto sheets of that size by their true outlines (``mesh.nest.SheetNester``: rasters
    of the pieces, ``gap`` apart and from the sheet's edge, turned as ``grain`` allows, the best of the orderings
    tried within ``nest_time`` seconds, seeded by ``seed``), one sheet filled before the next; ``nest_time`` 0:
    the boxes on shelves, translated only (first-fit decreasing height). A chart larger than the sheet raises
    HeatparamError (its lengths named in ``units``). ``pattern.sheet_use``: the covered fraction of each sheet.
    """
    _check_sheet_args(sheet, gap, nest_time)
    charts = pattern.charts
    lo = np.array([pattern.uv[c.rows].min(axis=0) for c in charts])
    hi = np.array([pattern.uv[c.rows].max(axis=0) for c in charts])
    size = hi - lo
    if gap is None:
        gap = GAP_FRACTION * float(np.linalg.norm(size, axis=1).max())
        if sheet is not None:
            gap = min(gap, (NEST_GAP_FRACTION if nest_time > 0 else SHEET_GAP_FRACTION) * min(sheet))
    turns = [np.eye(2)] * len(charts)
    if sheet is None:
        if len(charts) == 1 or not _any_overlap(lo, hi, gap / 2):
            pattern.sheets = np.zeros((0, 4))
            return pattern
        width = max(float(size[:, 0].max()), float(np.sqrt(((size + gap) ** 2).prod(axis=1).sum())))
        pos, sheet_of = _shelves(size, width, np.inf, gap, margin=0.0)
        offsets, frames = pos - lo, np.zeros((0, 4))
    elif nest_time > 0:
        turns, offsets, sheet_of, frames = _nested(pattern, sheet, gap, units, grain, nest_time, seed)
    else:
        W, H = (float(x) for x in sheet)
        too_big = np.flatnonzero((size[:, 0] + 2 * gap > W) | (size[:, 1] + 2 * gap > H))
        if len(too_big):
            c = too_big[0]
            _refuse(charts[c].id, size[c], sheet, gap, units)
        pos, sheet_of = _shelves(size, W - 2 * gap, H - 2 * gap, gap, margin=gap)
        stride = W + 2 * gap
        pos[:, 0] += sheet_of * stride
        offsets = pos - lo
        frames = np.array([[s * stride, 0.0, W, H] for s in range(int(sheet_of.max()) + 1)])
        pattern.nesting = {"method": "shelf", "gap": gap}
    _move(pattern, turns, offsets, sheet_of)
    pattern.sheets = frames
    pattern.sheet_use = _sheet_use(pattern, len(frames))
    return pattern


def _check_sheet_args(sheet, gap, nest_time) -> None:
    """One line naming the argument for a sheet size or gap that is not a positive finite number, or a time that
    is negative or not finite."""
    def bad(x, low_ok: bool) -> bool:
        try:
            v = float(x)
        except (TypeError, ValueError):
            return True
        return not (np.isfinite(v) and (v >= 0 if low_ok else v > 0))

    if sheet is not None and (len(sheet) != 2 or any(bad(x, False) for x in sheet)):
        raise HeatparamError(f"sheet must be two positive finite sizes (W, H), got {sheet!r}")
    if gap is not None and bad(gap, False):
        raise HeatparamError(f"gap must be a positive finite length, got {gap!r}")
    if bad(nest_time, True):
        raise HeatparamError(f"nest_time must be a finite number of seconds, at least 0, got {nest_time!r}")


def _refuse(chart: int, size: np.ndarray, sheet: tuple[float, float], gap: float, units: str) -> None:
    W, H = sheet
    raise HeatparamError(f"chart {chart} ({size[0]:.4g} x {size[1]:.4g} {units}) does not fit on a {W:g} x {H:g} "
                         f"{units} sheet with a {gap:.3g} {units} margin — use a larger --sheet")


def _nested(pattern: Pattern, sheet: tuple[float, float], gap: float, units: str, grain: str, seconds: float,
            seed: int) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """The charts nested on sheets by their outlines: (rotation (2,2) of each, offsets (c,2), sheet of each (c,),
    frames (s,4)); the search facts go to ``pattern.nesting``."""
    if grain not in GRAIN_RULES:
        raise HeatparamError(f"grain must be one of {', '.join(GRAIN_RULES)}, got {grain!r}")
    W, H = (float(x) for x in sheet)
    pieces = []
    for c in pattern.charts:
        local = np.full(len(pattern.uv), -1, dtype=np.int64)
        local[c.rows] = np.arange(len(c.rows))
        P = pattern.uv[c.rows]
        pieces.append(Piece(P, local[pattern.Fuv[c.faces]], orientations(P, grain)))
    nester = SheetNester(pieces, W, H, gap)
    big = nester.too_big()
    if big:
        i = big[0]
        ext = [np.ptp(pieces[i].P @ R.T, axis=0) for R in pieces[i].rotations]
        _refuse(pattern.charts[i].id, min(ext, key=lambda e: max(e[0] / W, e[1] / H)), sheet, gap, units)
    placed, grids, facts = nester.nested(seconds, seed)
    stride = W + 2 * gap
    offsets = np.array([p.t + np.array([p.sheet * stride, 0.0]) for p in placed])
    pattern.nesting = {"method": "outlines", "gap": gap, "grain": grain, "seed": seed, **facts}
    return ([p.R for p in placed], offsets, np.array([p.sheet for p in placed], dtype=np.int64),
            np.array([[s * stride, 0.0, W, H] for s in range(len(grids))]))


def _move(pattern: Pattern, turns: list[np.ndarray], offsets: np.ndarray, sheet_of: np.ndarray) -> None:
    """Each chart's rows x -> x @ R.T + offset, its seam labels with it."""
    new_uv = pattern.uv.copy()
    for i, c in enumerate(pattern.charts):
        c.offset, c.turn, c.sheet = offsets[i], turns[i], int(sheet_of[i])
        new_uv[c.rows] = pattern.uv[c.rows] @ turns[i].T + offsets[i]
    pattern.uv = new_uv
    by_id = {c.id: c for c in pattern.charts}
    for s in pattern.seams:
        ch = by_id[s.chart]
        s.label_at = ch.turn @ s.label_at + ch.offset
        s.inward = ch.turn @ s.inward
        s.angle = s.angle + float(np.degrees(np.arctan2(ch.turn[1, 0], ch.turn[0, 0])))


def _sheet_use(pattern: Pattern, n_sheets: int) -> np.ndarray:
    """(s,) the fraction of each sheet's area covered by its charts' faces."""
    use = np.zeros(n_sheets)
    for c in pattern.charts if n_sheets else ():
        use[c.sheet] += covered_area(pattern.uv, pattern.Fuv[c.faces])
    return use / (pattern.sheets[:, 2] * pattern.sheets[:, 3]) if n_sheets else use


def _any_overlap(lo: np.ndarray, hi: np.ndarray, pad: float) -> bool:
    a_lo, a_hi = lo[:, None] - pad, hi[:, None] + pad
    sep = (a_hi < lo[None] - pad).any(axis=2) | (hi[None] + pad < a_lo).any(axis=2)
    np.fill_diagonal(sep, True)
    return not bool(sep.all())


def _shelves(size: np.ndarray, width: float, height: float, gap: float, margin: float):
    """First-fit decreasing-height shelf packing of boxes (c,2) into bins of (width, height).

    Returns the lower-left corner of each box (c,2) inside its bin (offset by ``margin``) and its bin index.
    """
    order = sorted(range(len(size)), key=lambda i: (-size[i, 1], -size[i, 0], i))
    shelves: list[list[float]] = []  # [bin, y, shelf height, x used]
    bin_top: list[float] = []
    pos = np.zeros((len(size), 2))
    bin_of = np.zeros(len(size), dtype=np.int64)
    for i in order:
        w, h = size[i]
        for sh in shelves:
            if sh[3] + w <= width + 1e-12 and h <= sh[2] + 1e-12:
                pos[i] = (margin + sh[3], margin + sh[1])
                bin_of[i] = int(sh[0])
                sh[3] += w + gap
                break
        else:
            b = next((j for j, top in enumerate(bin_top) if top + h <= height + 1e-12), None)
            if b is None:
                bin_top.append(0.0)
                b = len(bin_top) - 1
            y = bin_top[b]
            shelves.append([b, y, h, w + gap])
            bin_top[b] = y + h + gap
            pos[i] = (margin, margin + y)
            bin_of[i] = b
    return pos, bin_of


@dataclass
class Sheets:
    """How pattern pieces go on sheets (``unwrap --sheet``): the sheet's size (W, H), the ``gap`` between pieces and
    to the edge (None: the default), the ``grain`` rule, the nesting's time budget (s) and seed."""

    size: tuple[float, float]
    gap: float | None = None
    grain: str = "free"
    nest_time: float = NEST_TIME
    seed: int = 0


def sheet_notes(pattern: Pattern) -> list[str]:
    """One annotation line per sheet: how much of it the pieces cover."""
    n = len(pattern.sheet_use)
    return [f"sheet {i + 1} of {n}: {u:.1%} used" for i, u in enumerate(pattern.sheet_use)]


def parse_sheet(text: str) -> tuple[float, float]:
    """``"WxH"`` (e.g. ``1200x600``) → (W, H) positive floats; HeatparamError (one line) otherwise."""
    parts = text.lower().replace("×", "x").split("x")
    try:
        W, H = (float(p) for p in parts)
    except ValueError:
        raise HeatparamError(f"--sheet expects WIDTHxHEIGHT in model units (e.g. 1200x600), got {text!r}") from None
    if not (W > 0 and H > 0 and np.isfinite(W) and np.isfinite(H)):
        raise HeatparamError(f"--sheet sizes must be positive, got {text!r}")
    return W, H


def face_iso(pattern: Pattern, V: np.ndarray) -> np.ndarray:
    """(m,) true-scale isometric distortion max(sigma1, 1/sigma2) per face (inf for flipped/degenerate faces)."""
    from heatparam.metrics import true_scale_iso

    return true_scale_iso(V, pattern.F, pattern.uv, pattern.Fuv)[0]
