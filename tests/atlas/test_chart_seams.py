"""Seam lengths of an atlas (atlas/chart_seams.py)."""

from __future__ import annotations

import numpy as np

from heatparam import datasets
from heatparam.atlas.chart_seams import chart_seam_lengths, cut_half_edges, seam_length
from heatparam.atlas.repair import half_edge_opposites


def test_a_square_cut_in_two_has_its_cut_as_seam():
    s = datasets.flat_square(h=0.25)
    V, F = s.V, s.F
    left = V[F].mean(axis=1)[:, 0] < 0.0
    assert seam_length(V, F, F) == 0.0  # one chart: no seam
    Fuv = F.copy()
    Fuv[left] += len(V)  # the left faces on rows of their own
    opp = half_edge_opposites(F)
    cut = cut_half_edges(F, Fuv, opp)
    L = seam_length(V, F, Fuv)
    h = np.flatnonzero((opp >= 0) & left[np.arange(3 * len(F)) // 3])
    h = h[~left[opp[h] // 3]]  # the left side of the edges between the two halves
    ends = F.ravel()[h], F[:, [1, 2, 0]].ravel()[h]
    assert len(h) > 3 and np.isclose(L, np.linalg.norm(V[ends[1]] - V[ends[0]], axis=1).sum())
    per = chart_seam_lengths(V, F, cut, left.astype(np.int64), 2)
    np.testing.assert_allclose(per, [L, L])  # each side's border along the cut
