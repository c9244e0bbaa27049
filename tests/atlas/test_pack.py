"""Texture packing (atlas.pack, texture mode): charts nested in [0,1]² at one texel density, moved and turned only,
no overlaps, the gutter of --padding pixels at --resolution kept (rasterized with each chart grown by half of it)."""

import numpy as np
import pytest
import shapely

from heatparam import datasets
from heatparam.atlas.overlap import count_overlaps
from heatparam.atlas.pack import pack_charts
from heatparam.errors import HeatparamError


def _charts():
    """Six flat pieces of different shapes and sizes: disks, squares, a part with holes (its true layouts)."""
    shapes = [datasets.flat_disk(1.0, h=0.15), datasets.flat_square(1.5, h=0.15),
              datasets.noisy_scan_part(scale=1.0, noise=0.0, h=0.12), datasets.flat_disk(0.5, h=0.1),
              datasets.scale_shape(datasets.flat_square(1.5, h=0.15), 0.6), datasets.flat_disk(0.3, h=0.08)]
    return [s.uv_true - s.uv_true.mean(axis=0) for s in shapes], [s.F for s in shapes]


def _claims(placed, Fs, padding, resolution):
    """(R,R) how many charts, each grown by padding/2 pixels, hold each pixel's centre."""
    c = (np.arange(resolution) + 0.5) / resolution
    X, Y = np.meshgrid(c, c)
    count = np.zeros(X.shape, dtype=int)
    for P, F in zip(placed, Fs, strict=True):
        region = shapely.union_all([shapely.Polygon(t) for t in P[F]]).buffer(padding / 2 / resolution)
        count += shapely.contains_xy(region, X, Y)
    return count


@pytest.mark.parametrize("padding, resolution", [(4, 256), (2.5, 200)])
def test_texture_packing_keeps_the_gutter_and_the_shapes(padding, resolution):
    uvs, Fs = _charts()
    placed, info = pack_charts(uvs, Fs, "texture", padding, resolution)
    allP = np.concatenate(placed)
    assert allP.min() >= 0 and allP.max() <= 1
    assert _claims(placed, Fs, padding, resolution).max() <= 1  # no pixel claimed by two charts
    offs = np.cumsum([0] + [len(P) for P in placed])
    assert count_overlaps(allP, np.concatenate([F + o for F, o in zip(Fs, offs, strict=False)])) == 0
    s = info["scale"]
    for P, Q in zip(uvs, placed, strict=True):  # a rigid motion at the common scale: distances kept
        d0 = np.linalg.norm(P[:, None] - P[None], axis=2)
        d1 = np.linalg.norm(Q[:, None] - Q[None], axis=2)
        assert np.allclose(d1, s * d0, atol=1e-12)
    area = sum(shapely.area(shapely.polygons(P[F])).sum() for P, F in zip(placed, Fs, strict=True))
    assert info["utilization"] == pytest.approx(area)
    assert info["texels_per_unit"] == pytest.approx(s * resolution)


def test_texels_per_unit_is_honoured_and_refused_when_too_large():
    uvs, Fs = _charts()
    _, best = pack_charts(uvs, Fs, "texture", 4, 256)
    half = best["texels_per_unit"] / 2
    placed, info = pack_charts(uvs, Fs, "texture", 4, 256, texels_per_unit=half)
    assert info["texels_per_unit"] == half and info["scale"] == pytest.approx(half / 256)
    assert np.concatenate(placed).max() <= 1
    with pytest.raises(HeatparamError, match="texels_per_unit=.* do not fit in one 256 x 256 texture"):
        pack_charts(uvs, Fs, "texture", 4, 256, texels_per_unit=best["texels_per_unit"] * 1.5)


def test_too_many_charts_for_the_texture_are_refused_in_one_line():
    uvs, Fs = _charts()
    with pytest.raises(HeatparamError, match="do not fit in one 16 x 16 texture at any texel density"):
        pack_charts(uvs * 4, Fs * 4, "texture", 4, 16)
