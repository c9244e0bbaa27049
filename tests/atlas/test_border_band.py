"""The overlap count from the border band (atlas/border_band.py): always ``count_overlaps``'s number, from the band
alone on overlap-free atlases, on layouts built to overlap without a single flipped face."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets
from heatparam.atlas.border_band import border_band, exact_overlap_count
from heatparam.atlas.overlap import count_overlaps


def _disk():
    s = datasets.flat_disk(radius=1.0, h=0.08)
    return s.V[:, :2].copy(), s.F


def _two(uv, F, shift, mirror=False):
    """Two copies of one chart, the second shifted (and mirrored: its faces turn the other way)."""
    other = uv * [-1.0, 1.0] if mirror else uv
    return np.vstack([uv, other + shift]), np.vstack([F, F + len(uv)])


def _wound_strip(turns: float):
    """A strip of a grid laid out along an arc of ``turns`` full turns: every face counter-clockwise, its border
    crossing itself past one turn."""
    nx, ny = 120, 6
    x, y = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny), indexing="ij")
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    F = np.concatenate([np.stack([a, a + ny, a + ny + 1], 1), np.stack([a, a + ny + 1, a + 1], 1)])
    theta, r = 2 * np.pi * turns * x.ravel(), 1.0 + 0.3 * y.ravel()
    uv = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    area = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return uv, F if (area > 0).all() else F[:, ::-1]


def test_an_overlap_free_chart_is_counted_from_its_band():
    uv, F = _disk()
    band = border_band(uv, F)
    assert band is not None and 0 < len(band) < len(F) // 2
    assert exact_overlap_count(uv, F) == count_overlaps(uv, F) == 0
    mirrored = _two(uv, F, [2.5, 0.0], mirror=True)  # a chart turned over beside another: still proven
    assert border_band(*mirrored) is not None and exact_overlap_count(*mirrored) == 0


@pytest.mark.parametrize("case", ["shifted copy", "chart inside a chart", "wound strip", "mirrored copy"])
def test_overlaps_without_a_flip_are_counted_exactly(case):
    """Overlaps that no flipped face betrays: the band finds them and the whole atlas is counted."""
    uv, F = _disk()
    if case == "shifted copy":
        uv, F = _two(uv, F, [1.2, 0.3])
    elif case == "chart inside a chart":
        uv, F = np.vstack([uv, 0.2 * uv + [0.1, -0.2]]), np.vstack([F, F + len(uv)])
    elif case == "wound strip":
        uv, F = _wound_strip(1.3)
    else:
        uv, F = _two(uv, F, [0.7, 0.0], mirror=True)
    expected = count_overlaps(uv, F)
    assert expected > 0 and exact_overlap_count(uv, F) == expected


def test_flipped_and_collapsed_faces_fall_back_to_the_full_count():
    uv, F = _disk()
    rng = np.random.default_rng(0)
    noisy = uv + rng.normal(0, 0.05, uv.shape)  # flips inside: no proof, the full count
    assert border_band(noisy, F) is None
    assert exact_overlap_count(noisy, F) == count_overlaps(noisy, F) > 0
    flat = uv.copy()
    f = F[len(F) // 2]
    flat[f[2]] = 0.5 * (flat[f[0]] + flat[f[1]])  # a zero-area UV face
    assert border_band(flat, F) is None and exact_overlap_count(flat, F) == count_overlaps(flat, F)


def test_a_strip_short_of_a_turn_is_proven_free():
    uv, F = _wound_strip(0.9)
    assert border_band(uv, F) is not None
    assert exact_overlap_count(uv, F) == count_overlaps(uv, F) == 0
