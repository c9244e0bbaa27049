"""Raster nesting: pieces (sets of triangles in the plane) placed without overlap on pixel grids, moved and turned
only, as xatlas packs its charts (``BitImage``).

Each piece is rasterized conservatively (every pixel that any of its triangles touches, holes left empty), in each
orientation allowed. A grid keeps the pixels of the pieces already placed; a new piece's raster, dilated by the gap
in whole pixels (a square: Chebyshev distance), goes to the lowest, then leftmost, position where it meets no
occupied pixel, and of its orientations the one placed lowest, then leftmost, wins (bottom-left fill). Two pieces whose
pixel sets are ``k`` empty pixels apart in x or y are at least ``k`` pixel widths apart in the plane: the gap holds
exactly, whatever the rounding, and no two pieces overlap. Holes in a piece stay free for smaller pieces.

The scans run in numba-compiled loops (the placement scan skips past each occupied pixel it meets, so a full row
costs one step per occupied run); the rest is numpy.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from heatparam.compiled import compiled
from heatparam.mesh.planar import covered_area

__all__ = ["Grid", "Piece", "Placement", "SheetNester", "min_area_rotation", "orientations"]

#: Pixels touched within this fraction of a pixel count as touched: rounding never loses a pixel a piece touches.
TOUCH_EPS = 1e-7


def min_area_rotation(P: np.ndarray) -> np.ndarray:
    """(2,2) rotation that puts the points' minimum-area bounding rectangle axis-aligned, its long side along x
    (rotating calipers)."""
    try:
        H = P[ConvexHull(P).vertices]
    except (QhullError, ValueError):
        return np.eye(2)
    E = np.roll(H, -1, axis=0) - H
    ang = np.arctan2(E[:, 1], E[:, 0])
    t = np.unique(np.mod(ang, np.pi / 2))
    c, s = np.cos(t), np.sin(t)
    R = np.stack([np.column_stack([c, s]), np.column_stack([-s, c])], axis=1)  # (T,2,2): one rotation per angle
    Q = H @ R.transpose(0, 2, 1)  # (T,h,2): the hull in each frame, all at once
    ext = Q.max(axis=1) - Q.min(axis=1)
    best, R_best = np.inf, np.eye(2)
    for i, area in enumerate((ext[:, 0] * ext[:, 1]).tolist()):  # the first of the smallest, as one by one
        if area < best - 1e-12 * abs(best if np.isfinite(best) else 1):
            best, R_best = area, R[i] if ext[i, 0] >= ext[i, 1] else np.array([[0, 1], [-1, 0]]) @ R[i]
    return R_best


def _quarter_turns(R: np.ndarray) -> list[np.ndarray]:
    q = np.array([[0.0, -1.0], [1.0, 0.0]])
    out = [R]
    for _ in range(3):
        out.append(q @ out[-1])
    return out


def orientations(P: np.ndarray, rule: str) -> list[np.ndarray]:
    """The (2,2) rotations a piece with points P (n,2) may take: ``none`` the identity only (the grain kept),
    ``180`` also the half turn, ``free`` the quarter turns of the identity and of the minimum-area rectangle's frame,
    ``fine`` those and the quarter turns of that frame turned by 22.5, 45 and 67.5 degrees (large odd pieces)."""
    if rule == "none":
        return [np.eye(2)]
    if rule == "180":
        return [np.eye(2), -np.eye(2)]
    if rule not in ("free", "fine"):
        raise ValueError(f"rotation rule must be none, 180, free or fine, got {rule!r}")
    out = _quarter_turns(np.eye(2))
    R = min_area_rotation(P)
    if abs(abs(R[0, 0]) - 1.0) > 1e-9 and abs(R[0, 0]) > 1e-9:  # not already a quarter turn
        out += _quarter_turns(R)
    if rule == "fine":
        for a in np.radians([22.5, 45.0, 67.5]):
            c, s = np.cos(a), np.sin(a)
            out += _quarter_turns(np.array([[c, -s], [s, c]]) @ R)
    return out


@compiled()
def _raster(T, h, w):  # pragma: no cover - compiled
    """(h,w) uint8 conservative raster of triangles T (t,3,2) in pixel units: a pixel [j,j+1]x[i,i+1] is set
    when a triangle touches it (separating axes: the box's two, the triangle's three edge normals)."""
    img = np.zeros((h, w), dtype=np.uint8)
    for t in range(T.shape[0]):
        ax, ay, bx, by, cx, cy = T[t, 0, 0], T[t, 0, 1], T[t, 1, 0], T[t, 1, 1], T[t, 2, 0], T[t, 2, 1]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        sg = 1.0 if area >= 0 else -1.0
        x0 = max(int(math.floor(min(ax, bx, cx) - TOUCH_EPS)), 0)
        x1 = min(int(math.floor(max(ax, bx, cx) + TOUCH_EPS)), w - 1)
        y0 = max(int(math.floor(min(ay, by, cy) - TOUCH_EPS)), 0)
        y1 = min(int(math.floor(max(ay, by, cy) + TOUCH_EPS)), h - 1)
        P = ((ax, ay, bx, by), (bx, by, cx, cy), (cx, cy, ax, ay))
        for i in range(y0, y1 + 1):
            for j in range(x0, x1 + 1):
                inside = True
                for px, py, qx, qy in P:
                    nx, ny = sg * (py - qy), sg * (qx - px)  # inward normal of the edge p -> q
                    # the box corner farthest along the inward normal must not be behind the edge
                    cxm = j + 1.0 if nx > 0 else float(j)
                    cym = i + 1.0 if ny > 0 else float(i)
                    if nx * (cxm - px) + ny * (cym - py) < -TOUCH_EPS * (abs(nx) + abs(ny)):
                        inside = False
                        break
                if inside:
                    img[i, j] = 1
    return img


@compiled()
def _first_fit(nxt, free, runs, rows, h, w, margin, slack, ylim, y0, x0):  # pragma: no cover - compiled
    """Lowest (at most ``ylim``; from row ``y0``, column ``x0`` on), then leftmost (y, x) where no run (``runs``
    (k,3): row offset, first and last column, relative to the raster's corner) meets an occupied pixel, the raster
    (h,w) kept ``margin`` pixels inside the grid; (-1, -1) if none. ``nxt`` (H, W+1): the first occupied column at
    or right of each pixel (W where none); ``free`` (H,): each row's longest free run, which must hold each raster
    row's longest run (``rows`` (r,2): row offset, length) less ``slack`` (what the grid's edge may cut off)."""
    H, W = nxt.shape[0], nxt.shape[1] - 1
    n = runs.shape[0]
    k0 = 0
    for y in range(max(margin, y0), min(H - margin - h, ylim) + 1):
        room = True
        for q in range(rows.shape[0]):  # a row without a long enough free run rules this y out at once
            yy = y + rows[q, 0]
            if 0 <= yy < H and free[yy] < rows[q, 1] - slack:
                room = False
                break
        if not room:
            continue
        x = max(margin, x0) if y == y0 else margin
        while x <= W - margin - w:
            ok = True
            for i in range(n):
                k = (k0 + i) % n  # the run that failed last first: it most likely fails again
                yy = y + runs[k, 0]
                if yy < 0 or yy >= H:
                    continue
                a = max(x + runs[k, 1], 0)
                b = min(x + runs[k, 2], W - 1)
                if a > b:
                    continue
                c = nxt[yy, a]
                if c <= b:  # occupied at c: every x that keeps c within this run fails too
                    ok = False
                    k0 = k
                    x = max(x + 1, c - runs[k, 1] + 1)
                    break
            if ok:
                return y, x
    return -1, -1


@compiled()
def _stamp(occ, nxt, free, raster, y, x):  # pragma: no cover - compiled
    """Mark ``raster`` at (y, x) in ``occ`` and refresh ``nxt`` and ``free`` on its rows."""
    h, w = raster.shape
    W = occ.shape[1]
    for i in range(h):
        for j in range(w):
            if raster[i, j]:
                occ[y + i, x + j] = 1
        row = y + i
        nxt[row, W] = W
        longest = 0
        for c in range(W - 1, -1, -1):
            nxt[row, c] = c if occ[row, c] else nxt[row, c + 1]
            longest = max(longest, nxt[row, c] - c)
        free[row] = longest


@compiled()
def _dilated_runs(ras, g):  # pragma: no cover - compiled
    """The raster (h,w) dilated by a (2g+1)² square, as runs relative to the raster's corner: (k,3) int64 (row,
    first column, last column) and (r,2) int64 (row, longest run) for each row with a run."""
    h, w = ras.shape
    H, W = h + 2 * g, w + 2 * g
    cnt = np.zeros((H, W + 1), dtype=np.int32)  # per dilated row: prefix counts of the rows within g below/above
    for i in range(h):
        for j in range(w):
            if ras[i, j]:
                for di in range(2 * g + 1):
                    cnt[i + di, j + 1] += 1
    runs = np.empty((H * (w // 2 + 2), 3), dtype=np.int64)
    rows = np.empty((H, 2), dtype=np.int64)
    n = nr = 0
    for i in range(H):
        for j in range(W):
            cnt[i, j + 1] += cnt[i, j]
        longest = 0
        j = 0
        while j < W:  # column j of the dilation is set when a pixel of columns j-2g..j is set in the window
            if cnt[i, min(j + 1, w)] - cnt[i, max(j - 2 * g, 0)] > 0:
                start = j
                while j < W and cnt[i, min(j + 1, w)] - cnt[i, max(j - 2 * g, 0)] > 0:
                    j += 1
                runs[n, 0], runs[n, 1], runs[n, 2] = i - g, start - g, j - 1 - g
                n += 1
                longest = max(longest, j - start)
            j += 1
        if longest:
            rows[nr, 0], rows[nr, 1] = i - g, longest
            nr += 1
    return runs[:n].copy(), rows[:nr].copy()


@dataclass
class Shape:
    """One orientation of a piece at one pixel scale: rotation R (2,2), the rotated points' lower corner ``lo`` (2,)
    (model units), the raster (h,w) uint8, the runs of its dilation by ``gap`` pixels and their longest per row
    (:func:`_dilated_runs`)."""

    R: np.ndarray
    lo: np.ndarray
    raster: np.ndarray
    runs: np.ndarray
    rows: np.ndarray
    gap: int


class Piece:
    """A piece to nest: points P (n,2) and triangles T (t,3), with the rotations it may take (:func:`orientations`).

    :meth:`shapes` rasterizes it at a scale (pixels per model unit) with a dilation of ``gap_px`` pixels."""

    def __init__(self, P: np.ndarray, T: np.ndarray, rotations: list[np.ndarray]):
        self.P = np.asarray(P, dtype=np.float64)
        self.T = np.asarray(T, dtype=np.int64)
        self.rotations = rotations

    def shapes(self, scale: float, gap_px: int) -> list[Shape]:
        """Each orientation's raster at ``scale`` pixels per unit, dilated by ``gap_px`` pixels for the scan."""
        out, seen = [], set()
        for R in self.rotations:
            Q = self.P @ R.T
            lo = Q.min(axis=0)
            Qp = (Q - lo) * scale
            h, w = int(math.floor(Qp[:, 1].max())) + 1, int(math.floor(Qp[:, 0].max())) + 1
            ras = _raster(np.ascontiguousarray(Qp[self.T]), h, w)
            key = (h, w, ras.tobytes())
            if key not in seen:  # an orientation with the raster of an earlier one places the same (small pieces)
                seen.add(key)
                out.append(Shape(R, lo, ras, *_dilated_runs(ras, gap_px), gap_px))
        return out


class Grid:
    """An (H,W) pixel grid (a texture, a sheet) with the pieces placed on it; ``margin`` pixels kept free at the
    border."""

    def __init__(self, H: int, W: int, margin: int = 0):
        self.occ = np.zeros((H, W), dtype=np.uint8)
        self.nxt = np.tile(np.full(W + 1, W, dtype=np.int64), (H, 1))
        self.free = np.full(H, W, dtype=np.int64)
        self.since: dict = {}  # raster → the first (y, x) where it may still fit (:meth:`best`)
        self.margin = margin
        self.top = 0  # the highest row used + 1

    def best(self, shapes: list[Shape], top: bool = False) -> tuple[int, int, int] | None:
        """(orientation index, y, x) of the lowest, then leftmost placement over the orientations (``top``: the
        one whose top ends lowest), or None."""
        best = None
        H = self.occ.shape[0]
        for k, s in enumerate(shapes):
            h, w = s.raster.shape
            ylim = H if best is None else best[0][0] - (h if top else 0)  # a later one must be as low to win
            key = (s.gap, h, w, s.raster.tobytes())
            # the grid only fills up: a raster that fit nowhere before (y0, x0) still does not
            y0, x0 = self.since.get(key, (0, 0))
            y, x = _first_fit(self.nxt, self.free, s.runs, s.rows, h, w, self.margin,
                              2 * max(0, s.gap - self.margin), ylim, y0, x0)
            self.since[key] = (y, x) if y >= 0 else (max(y0, ylim + 1), 0)
            if y >= 0 and (best is None or (y + h * top, x) < best[0]):
                best = ((y + h * top, x), k, y, x)
        return None if best is None else best[1:]

    def place(self, shape: Shape, y: int, x: int) -> None:
        _stamp(self.occ, self.nxt, self.free, shape.raster, y, x)
        self.top = max(self.top, y + shape.raster.shape[0])


#: Sheets are rasterized with this many pixels along their longer side: the quantization costs about one pixel
#: along each outline (a fraction of a percent of a sheet of a few dozen pieces).
SHEET_PIXELS = 1024
#: Orderings tried within the time budget: by area, by longer side, by perimeter of the box (each with both
#: placement rules), then shuffles of the area order (seeded). The search stops at the first that needs no more
#: sheets than the pieces' area does; camelhead's 13 charts on one sheet of area (3D area) / 0.55 took 16.
NEST_TRIES = 48


@dataclass
class Placement:
    """Where a piece went: its sheet, and the rigid motion x -> x @ R.T + t (model units, sheet-local)."""

    sheet: int
    R: np.ndarray
    t: np.ndarray


class SheetNester:
    """Pieces nested on sheets of W x H model units, ``gap`` apart and from the sheet's edge, first fit: a piece
    goes on the first sheet where it fits (bottom-left), a new sheet opens when it fits on none.

    pieces : list of :class:`Piece`. W, H, gap : model units (gap > 0)."""

    def __init__(self, pieces: list[Piece], W: float, H: float, gap: float, pixels: int = SHEET_PIXELS):
        self.px = max(W, H) / pixels
        self.gh, self.gw = int(math.floor(H / self.px)), int(math.floor(W / self.px))
        self.gap_px = max(int(math.ceil(gap / self.px - 1e-9)), 1)
        self.shapes = [p.shapes(1.0 / self.px, self.gap_px) for p in pieces]
        self.areas = np.array([covered_area(p.P, p.T) for p in pieces])
        self.sheet_area = W * H

    def too_big(self) -> list[int]:
        """The pieces that fit on an empty sheet in none of their orientations."""
        inner_h, inner_w = self.gh - 2 * self.gap_px, self.gw - 2 * self.gap_px
        return [i for i, sh in enumerate(self.shapes)
                if not any(s.raster.shape[0] <= inner_h and s.raster.shape[1] <= inner_w for s in sh)]

    def run(self, order: np.ndarray, top: bool = False) -> tuple[list[Placement], list[Grid]] | None:
        """The pieces placed in ``order`` (``top``: :meth:`Grid.best`'s rule); None when one fits on no empty
        sheet."""
        grids: list[Grid] = []
        out: list = [None] * len(self.shapes)
        for i in order:
            shapes = self.shapes[i]
            for s, grid in enumerate([*grids, None]):
                if grid is None:
                    grid = Grid(self.gh, self.gw, self.gap_px)
                    grids.append(grid)
                where = grid.best(shapes, top)
                if where is not None:
                    k, y, x = where
                    grid.place(shapes[k], y, x)
                    sh = shapes[k]
                    out[i] = Placement(s, sh.R, np.array([x, y], dtype=np.float64) * self.px - sh.lo)
                    break
            else:
                return None
        return out, grids

    def orders(self, seed: int) -> list[np.ndarray]:
        """The orderings to try, in turn (``NEST_TRIES`` in all); :meth:`nested` runs every other one with the
        lowest-top rule (:meth:`Grid.best`)."""
        box = np.array([[s.raster.shape[0], s.raster.shape[1]] for s in (sh[0] for sh in self.shapes)], dtype=float)
        keys = [-self.areas, -box.max(axis=1), -box.sum(axis=1)]
        out = [o for k in keys for o in [np.lexsort((np.arange(len(k)), k))] * 2]  # each with both rules
        rng = np.random.default_rng(seed)
        while len(out) < NEST_TRIES:
            jitter = self.areas * rng.uniform(0.7, 1.3, len(self.areas))
            out.append(np.argsort(-jitter, kind="stable"))
        return out

    def score(self, grids: list[Grid]) -> tuple[int, int]:
        """Fewer sheets first, then the lower top on the last sheet."""
        return len(grids), grids[-1].top

    def nested(self, seconds: float, seed: int) -> tuple[list[Placement], list[Grid], dict]:
        """The best of the orderings (:meth:`orders`) tried within ``seconds`` (the first always): (placements,
        grids, search facts). The same pieces and seed give the same result whenever the search ends by its own
        rule (as few sheets as the area allows, or every ordering tried) before the time is up."""
        t0 = time.perf_counter()
        best, tries, timed_out = None, 0, False
        fewest = max(1, math.ceil(float(self.areas.sum()) / self.sheet_area - 1e-9))
        for n, order in enumerate(self.orders(seed)):
            if best is not None and time.perf_counter() - t0 > seconds:
                timed_out = True
                break
            got = self.run(order, top=bool(n % 2))
            tries += 1
            if got is not None and (best is None or self.score(got[1]) < self.score(best[1])):
                best = got
            if best is not None and len(best[1]) <= fewest:
                break  # no fewer sheets can hold the pieces' area
        if best is None:
            raise ValueError("a piece fits on no empty sheet")
        return best[0], best[1], {"orderings_tried": tries, "stopped_by_time": timed_out,
                                  "seconds": time.perf_counter() - t0, "pixel": self.px}
