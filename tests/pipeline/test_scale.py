"""Any finite scale gives the same map × the scale (issue 16): meshes far outside the unit box are computed in a
power-of-two unit frame (``mesh.frame``) and mapped back; the report is in model units."""

from __future__ import annotations

import numpy as np
import pytest

import heatparam
from heatparam import datasets
from heatparam.mesh.frame import unit_frame

SCALES = (1e-80, 1e-6, 1.0, 1e6, 1e80)


@pytest.fixture(scope="module")
def part():
    s = datasets.cylinder_with_holes(h=0.09)
    return s, heatparam.parameterize(s.V, s.F)


@pytest.mark.parametrize("scale", SCALES)
def test_same_map_times_scale(part, scale):
    s, base = part
    r = heatparam.parameterize(s.V * scale, s.F)
    extent = float(np.ptp(base.uv, axis=0).max())
    # measured 6e-13 .. 3e-12 of the extent (round-off of V * scale carried through the polish)
    assert np.abs(r.uv / scale - base.uv).max() <= 1e-9 * extent
    m, mb = r.report["metrics"], base.report["metrics"]
    assert m["flips"] == 0 and m["iso_mean"] == pytest.approx(mb["iso_mean"], rel=1e-9)
    assert r.report["mesh"]["area"] == pytest.approx(base.report["mesh"]["area"] * scale**2, rel=1e-12)
    assert r.report["mesh"]["bbox_diagonal"] == pytest.approx(base.report["mesh"]["bbox_diagonal"] * scale, rel=1e-12)


def test_far_from_the_origin_and_huge():
    s = datasets.cylinder_patch(h=0.1)
    base = heatparam.parameterize(s.V, s.F)
    for V in (s.V + 1e9, s.V * 1e155):
        r = heatparam.parameterize(V, s.F)
        assert r.report["metrics"]["flips"] == 0
        assert r.report["metrics"]["iso_mean"] == pytest.approx(base.report["metrics"]["iso_mean"], rel=1e-6)


def test_unit_frame_is_exact_and_leaves_ordinary_meshes_alone():
    V = np.random.default_rng(0).random((50, 3))
    f = unit_frame(V)
    assert f.exponent == 0 and not f.offset.any()
    f = unit_frame(V * 2.0**100)
    assert np.array_equal(f.to_unit(V * 2.0**100), V * 2.0 ** (100 - f.exponent))  # a power of two: exact
    assert 0.5 <= np.ptp(f.to_unit(V * 2.0**100), axis=0).max() < 1


def test_geodesic_distances_scale():
    s = datasets.flat_square(h=0.1)
    D0, _ = heatparam.geodesic_distances(s.V, s.F, [0, 5])
    for scale in (1e-80, 1e80):
        D, _ = heatparam.geodesic_distances(s.V * scale, s.F, [0, 5])
        np.testing.assert_allclose(D / scale, D0, rtol=1e-9, atol=1e-12)
