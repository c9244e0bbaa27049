"""Common borders split into stretches (atlas/stretches.py): simple paths ending at cone points, longest first."""

from __future__ import annotations

import numpy as np

from heatparam import datasets
from heatparam.atlas.chart_topology import Topology
from heatparam.atlas.stretches import border_stretches, half_path


def _common_border(topo, left):
    h = np.flatnonzero((topo.opp >= 0) & left[np.arange(3 * len(topo.F)) // 3])
    return h[~left[topo.opp[h] // 3]]


def test_a_straight_border_of_a_flat_square_is_one_stretch():
    s = datasets.flat_square(h=0.1)
    topo = Topology.build(s.V, s.F)
    left = s.V[s.F].mean(axis=1)[:, 0] < 0.0
    h = _common_border(topo, left)
    (st,) = border_stretches(topo, h)
    assert np.array_equal(np.sort(st), np.sort(h))
    half = half_path(topo, st)
    ha, hb = topo.ends()
    assert len(half) == len(st) // 2 and (hb[half[:-1]] == ha[half[1:]]).all()  # a path, in order


def test_a_border_around_a_cube_corner_ends_there():
    """Two faces of a cube against the rest: the border passes cube corners (cone points), where stretches end."""
    V, F = datasets.closed_cube(n=2)
    topo = Topology.build(V, F)
    left = np.abs(V[F].mean(axis=1)[:, 2] - V[:, 2].max()) < 1e-9  # the top side
    h = _common_border(topo, left)
    parts = border_stretches(topo, h)
    assert len(parts) == 4  # the top square's four sides, between its four corners
    assert np.array_equal(np.sort(np.concatenate(parts)), np.sort(h))
    lengths = [topo.hlen[p].sum() for p in parts]
    assert lengths == sorted(lengths, reverse=True)
