"""The exact overlap count of an atlas from the faces near its UV borders, when that is provably enough.

``atlas.overlap.count_overlaps`` tests every pair of faces whose UV boxes meet: on a 300k-face chart that is
seconds for a count that is almost always 0. A sum of chains gives the same answer from far fewer faces. Orient
every UV triangle counter-clockwise (a mirrored chart turned over as a whole); where the two faces of every welded
edge turn the same way, the interior edges cancel and, for a point p on no edge, the number of triangles covering p
is the winding number around p of the border chain (the half-edges without an opposite). Where two triangles
overlap, that number is at least 2 on an open set; at a generic point q of that set's boundary, which lies on a
border edge, two triangles cover the side where it is 2, and both have q in their closure: both UV boxes meet that
border face's box. So the faces whose boxes meet a border face's box (the band) hold an overlapping pair whenever
the atlas has one, and no overlap in the band means none at all. When the band has one, or the precondition
(every face turning the way of its welded neighbours, by an orientation sign certain in floating point, none of
zero area) fails, the whole atlas is counted: the number is always ``count_overlaps``'s.
"""

from __future__ import annotations

import numpy as np

from heatparam.atlas.overlap import count_overlaps, float_orientation
from heatparam.atlas.repair import half_edge_opposites

__all__ = ["border_band", "exact_overlap_count"]

#: grid cells a border face's box may cover before the band gives up (the full count then): a bound on work only
_MAX_CELLS_PER_BORDER_FACE = 64
#: a face whose box covers more cells joins the band without a look (a larger band is still exact)
_MAX_CELLS_PER_FACE = 16


def exact_overlap_count(uv: np.ndarray, Fuv: np.ndarray) -> int:
    """Number of triangle pairs of the atlas whose UV interiors intersect: ``count_overlaps(uv, Fuv)``, counted over
    the border band alone when it has none (module docstring).

    Parameters
    ----------
    uv : (k,2) float64 UV positions. Fuv : (m,3) int64 rows of ``uv`` per face corner.
    """
    uv = np.asarray(uv, dtype=np.float64)
    Fuv = np.asarray(Fuv, dtype=np.int64)
    band = border_band(uv, Fuv)
    if band is None or not len(band):
        return count_overlaps(uv, Fuv)
    in_band = count_overlaps(uv, Fuv[band])
    return 0 if in_band == 0 else in_band if len(band) == len(Fuv) else count_overlaps(uv, Fuv)


def border_band(uv: np.ndarray, Fuv: np.ndarray) -> np.ndarray | None:
    """(b,) int64 sorted faces whose UV box shares a grid cell with the box of a face that has a border half-edge (a
    superset of the faces whose boxes meet one); None when the band proves nothing: a face of zero or uncertain UV
    orientation, or two faces of a welded edge turning opposite ways."""
    P = uv[Fuv]
    sign = _sure_signs(P)
    opp = half_edge_opposites(Fuv)
    inner = np.flatnonzero(opp >= 0)
    if not len(Fuv) or (sign == 0).any() or (sign[inner // 3] != sign[opp[inner] // 3]).any():
        return None
    border = np.unique(np.flatnonzero(opp < 0) // 3)
    lo, hi = P.min(axis=1), P.max(axis=1)
    return _near(lo, hi, border)


def _sure_signs(P: np.ndarray) -> np.ndarray:
    """(m,) the orientation sign (-1, 1) of each UV triangle (m,3,2), 0 where it is zero or not certain."""
    det, bound = float_orientation(P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1], P[:, 2, 0], P[:, 2, 1])
    return np.where(np.abs(det) > bound, np.sign(det), 0.0)


def _near(lo: np.ndarray, hi: np.ndarray, border: np.ndarray) -> np.ndarray | None:
    """Faces (boxes lo, hi (m,2)) sharing a grid cell with a ``border`` face's box; None when the border boxes would
    cover too many cells (the band is then not worth it)."""
    if not len(border):
        return np.zeros(0, dtype=np.int64)
    cell = float(np.median((hi[border] - lo[border]).max(axis=1)))
    origin = lo.min(axis=0)
    if not cell > 0 or not np.isfinite(cell):
        return None
    c0 = np.floor((lo - origin) / cell)
    c1 = np.floor((hi - origin) / cell)
    if c1.max() >= 2.0 ** 30:
        return None
    c0, c1 = c0.astype(np.int64), c1.astype(np.int64)
    ny = int(c1[:, 1].max()) + 1
    span = c1 - c0 + 1
    count = span[:, 0] * span[:, 1]
    if count[border].sum() > _MAX_CELLS_PER_BORDER_FACE * len(border):
        return None
    marked = np.unique(_cells(c0[border], span[border], count[border], ny)[1])
    small = np.flatnonzero(count <= _MAX_CELLS_PER_FACE)
    face, key = _cells(c0[small], span[small], count[small], ny)
    hit = small[np.unique(face[np.isin(key, marked)])]
    return np.union1d(hit, np.flatnonzero(count > _MAX_CELLS_PER_FACE))


def _cells(c0: np.ndarray, span: np.ndarray, count: np.ndarray, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """Every grid cell of each box (lower cell c0 (b,2), spans (b,2), cells per box (b,)): (box of each cell, the
    cell's key), concatenated."""
    box = np.repeat(np.arange(len(c0)), count)
    offs = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    sx = span[box, 0]
    return box, (c0[box, 0] + offs % sx) * ny + c0[box, 1] + offs // sx
