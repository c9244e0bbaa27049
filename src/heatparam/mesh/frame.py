"""The unit frame: coordinates brought near the unit box before any computation, and results mapped back.

Double precision covers 1e-308..1e308, but the stages square lengths and multiply areas (1e80 squared twice
overflows; 1e-80 squared twice underflows), and some iterative solvers have absolute floors. A mesh whose extent
lies outside [2^-20, 2^20] is therefore scaled by a power of two into [0.5, 1) — exactly: multiplying by 2^k
changes no mantissa bit — and one whose centre lies farther than 2^20 extents from the origin (survey or CAD
coordinates) is also moved there. Meshes of ordinary size and position keep their coordinates bit for bit, so
their maps are unchanged; at every scale the map is the same map × the scale up to round-off.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: extents within [2^-EXTENT_RANGE, 2^EXTENT_RANGE] model units are not rescaled
EXTENT_RANGE = 20
#: centres farther than 2^FAR_OFFSET extents from the origin are moved to it
FAR_OFFSET = 20


class UnitFrame(NamedTuple):
    """model = ldexp(unit, exponent) + offset: ``exponent`` an int (0 = not scaled), ``offset`` (3,) (zeros =
    not moved). ``unit`` = 2^exponent is the length of one internal unit in model units."""

    exponent: int
    offset: np.ndarray

    @property
    def unit(self) -> float:
        return math.ldexp(1.0, self.exponent)

    @property
    def moves(self) -> bool:
        """Whether the frame scales or moves anything (ordinary meshes: no)."""
        return bool(self.exponent or self.offset.any())

    def to_unit(self, V: np.ndarray) -> np.ndarray:
        """(n,3) model coordinates → internal ones (``V`` itself when the frame does not move it)."""
        return np.ldexp(V - self.offset, -self.exponent) if self.moves else V

    def lengths_to_model(self, x):
        """Lengths (or 2D layouts, which carry no offset) → model units: × 2^exponent, exactly."""
        return np.ldexp(x, self.exponent) if isinstance(x, np.ndarray) else math.ldexp(x, self.exponent)

    def areas_to_model(self, a: float) -> float:
        """An area in model units; inf where it exceeds double precision (a mesh larger than ~1e154 units)."""
        try:
            return math.ldexp(a, 2 * self.exponent)
        except OverflowError:
            return math.inf


def frame_of(V: np.ndarray, F: np.ndarray) -> UnitFrame:
    """:func:`unit_frame` of the vertices of (V (n,3) finite, F (m,3) in range) that faces use."""
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    return unit_frame(V[used])


def unit_frame(V: np.ndarray) -> UnitFrame:
    """The frame of the finite points ``V`` (n,3) (the referenced vertices): see the module docstring."""
    if len(V) == 0:
        return UnitFrame(0, np.zeros(3))
    lo, hi = V.min(axis=0), V.max(axis=0)
    half = float((0.5 * hi - 0.5 * lo).max())  # half the extent, without overflow at ±1e308
    offset = np.zeros(3)
    exponent = 0
    if half > 0:
        e = math.frexp(half)[1] + 1  # extent = 2·half in [2^(e-1), 2^e)
        if not -EXTENT_RANGE <= e <= EXTENT_RANGE:
            exponent = e
        centre = 0.5 * lo + 0.5 * hi
        if float(np.abs(centre).max()) > math.ldexp(half, FAR_OFFSET + 1):
            offset = centre
    return UnitFrame(exponent, offset)
