"""Packing charts without overlap; packing moves and turns charts only (one common scale in texture mode).

``scale``: true scale (model units), each chart turned to its minimum-area bounding rectangle, shelf packing of the
boxes with a gap of ``gap`` model units between them.
``texture``: the charts nested by their rasters in a ``resolution``² texture (``mesh.nest``: rotations by quarter
turns of their own and of their minimum-area rectangle's frame, and 22.5° steps for the large charts; bottom-left
fill, largest first, by either of two placement rules), every chart at one texel density: the largest that fits
(bisection), or ``texels_per_unit`` when given. Two charts are at least
``padding`` pixels apart (their conservative rasters, one dilated by the padding, never meet) and every chart at
least half of it from the border; UVs in [0,1]².
"""

from __future__ import annotations

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.mesh.nest import Grid, Piece, min_area_rotation, orientations
from heatparam.mesh.planar import covered_area, shelf_pack

__all__ = ["min_area_rotation", "pack_charts"]

#: Charts holding at least this fraction of the UV area also try turns between the quarter turns (22.5° steps):
#: the large pieces decide the packing (beetle's 5 charts 0.323 -> 0.436, cow 0.585 -> 0.600: bench/bench_pack.py);
#: the many small ones keep 8 orientations (time grows with charts x orientations).
FINE_TURNS_FRACTION = 0.02
#: The bisection on the texel density stops when the bracket is this narrow (relative): utilization within ~1%.
DENSITY_TOLERANCE = 0.005


def pack_charts(uvs: list[np.ndarray], Fs: list[np.ndarray], mode: str = "scale", padding: float = 4.0,
                resolution: int = 1024, gap: float | None = None, texels_per_unit: float | None = None
                ) -> tuple[list[np.ndarray], dict]:
    """Place charts without overlap.

    Parameters
    ----------
    uvs : list of (n_i,2) float64 chart layouts (each bijective on its own). Fs : list of (m_i,3) int64 their
        triangles (for the packing efficiency).
    mode : ``scale`` or ``texture`` (module docstring).
    padding, resolution : the texture gutter in pixels and the texture size (``texture``).
    gap : ``scale`` mode gap in model units (default: 2% of the square root of the mean chart box area).
    texels_per_unit : ``texture``: the texel density (pixels per model unit) instead of the largest that fits.

    Returns
    -------
    (placed layouts, info dict with ``scale`` (UV units per model unit; 1 in scale mode), ``width``, ``height``,
    ``efficiency`` = summed chart UV area / area of the atlas rectangle ([0,1]² in texture mode: the utilization),
    and in texture mode ``texels_per_unit``, ``padding``, ``resolution``).
    """
    if mode == "texture":
        return _TexturePack(uvs, Fs, float(padding), int(resolution)).packed(texels_per_unit)
    if mode != "scale":
        raise ValueError(f"pack must be 'scale' or 'texture', got {mode!r}")
    rot, sizes, areas = _upright(uvs, Fs)
    return _pack_scale(rot, sizes, areas, gap)


def _upright(uvs: list[np.ndarray], Fs: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Each chart turned to its minimum-area bounding rectangle, moved to the origin: (the layouts, (k,2) their
    boxes' sizes, (k,) their UV areas)."""
    rot = []
    sizes = np.zeros((len(uvs), 2))
    areas = np.zeros(len(uvs))
    for i, P in enumerate(uvs):
        R = min_area_rotation(P)
        Q = P @ R.T
        Q = Q - Q.min(axis=0)
        rot.append(Q)
        sizes[i] = Q.max(axis=0)
        areas[i] = covered_area(Q, Fs[i])
    return rot, sizes, areas


def _pack_scale(rot: list[np.ndarray], sizes: np.ndarray, areas: np.ndarray, gap: float | None
                ) -> tuple[list[np.ndarray], dict]:
    """True scale: the shelf width (of a few tried) that gives the smallest rectangle."""
    g = gap if gap is not None else 0.02 * float(np.sqrt(np.mean(sizes[:, 0] * sizes[:, 1])) + 1e-300)
    total = float((sizes + g).prod(axis=1).sum())
    best = None
    for f in (0.8, 0.9, 1.0, 1.1, 1.25, 1.4, 1.6, 2.0):  # shelf widths: keep the smallest rectangle
        width = max(float(np.sqrt(total) * f), float(sizes[:, 0].max()))
        cand = shelf_pack(sizes, width, g)
        if best is None or cand[1] * cand[2] < best[1] * best[2]:
            best = cand
    pos, w, h = best
    out = [Q + pos[i] for i, Q in enumerate(rot)]
    return out, {"mode": "scale", "scale": 1.0, "width": w, "height": h, "gap": g,
                 "efficiency": float(areas.sum() / max(w * h, 1e-300))}


class _TexturePack:
    """The charts nested in one ``resolution``² texture at one texel density (module docstring)."""

    def __init__(self, uvs: list[np.ndarray], Fs: list[np.ndarray], padding: float, resolution: int):
        self.areas = np.array([covered_area(P, F) for P, F in zip(uvs, Fs, strict=True)])
        big = self.areas >= FINE_TURNS_FRACTION * self.areas.sum()
        self.pieces = [Piece(P, F, orientations(P, "fine" if b else "free"))
                       for P, F, b in zip(uvs, Fs, big, strict=True)]
        self.order = np.argsort(-self.areas, kind="stable")  # largest first
        self.R = resolution
        self.gap_px = int(np.ceil(padding - 1e-9))
        self.margin = int(np.ceil(padding / 2 - 1e-9))
        self.padding = padding

    def fit(self, density: float) -> list | None:
        """Each chart's (shape, y, x) at ``density`` pixels per unit, or None when they do not all fit by either
        placement rule (lowest position, or lowest top: ``mesh.nest.Grid.best``)."""
        shapes = [self.pieces[i].shapes(density, self.gap_px) for i in range(len(self.pieces))]
        for top in (False, True):
            grid = Grid(self.R, self.R, self.margin)
            placed: list = [None] * len(self.pieces)
            for i in self.order:
                where = grid.best(shapes[i], top)
                if where is None:
                    break
                k, y, x = where
                grid.place(shapes[i][k], y, x)
                placed[i] = (shapes[i][k], y, x)
            else:
                return placed
        return None

    def packed(self, texels_per_unit: float | None) -> tuple[list[np.ndarray], dict]:
        """The placed layouts (UVs in [0,1]²) and the packing's report entry."""
        if texels_per_unit is not None:
            density, placed = float(texels_per_unit), self.fit(float(texels_per_unit))
            if placed is None:
                raise HeatparamError(f"the charts at texels_per_unit={texels_per_unit:g} do not fit in one "
                                     f"{self.R} x {self.R} texture — lower texels_per_unit or raise resolution")
        else:
            density, placed = self._largest()
        out = []
        for i, (shape, y, x) in enumerate(placed):
            Q = (self.pieces[i].P @ shape.R.T - shape.lo) * density + np.array([x, y], dtype=np.float64)
            out.append(Q / self.R)
        scale = density / self.R
        used = float(self.areas.sum() * scale * scale)
        return out, {"mode": "texture", "scale": scale, "width": 1.0, "height": 1.0,
                     "gutter": self.padding / self.R, "padding": self.padding, "resolution": self.R,
                     "texels_per_unit": density, "efficiency": used, "utilization": used}

    def _largest(self) -> tuple[float, list]:
        """The largest density at which the charts fit (bisection between a fit and a failure)."""
        inner = self.R - 2 * self.margin
        hi = inner / np.sqrt(max(float(self.areas.sum()), 1e-300))  # every texel used: an upper bound
        lo, placed = 0.7 * hi, None
        while placed is None:
            placed = self.fit(lo)
            if placed is None:
                hi, lo = lo, lo * 0.8
                if lo * np.sqrt(self.areas.max(initial=0.0)) < 0.5:  # every chart under a texel: no density fits
                    raise HeatparamError(f"the {len(self.pieces)} charts with a padding of {self.padding:g} pixels "
                                         f"do not fit in one {self.R} x {self.R} texture at any texel density — "
                                         "raise resolution or lower padding")
        while hi - lo > DENSITY_TOLERANCE * lo:
            mid = 0.5 * (lo + hi)
            trial = self.fit(mid)
            if trial is None:
                hi = mid
            else:
                lo, placed = mid, trial
        return lo, placed
