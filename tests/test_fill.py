"""Tests for heatparam.fill: the fill surface M* (paper §2.5, Eq. 15-16) through the pipeline, and its parts.

Acceptance (issue 3): with the fill, the S-strip on a cone and the cylinder with holes map with 0 flips, 0
boundary crossings, mean iso <= 1.10 and layout error <= 3% of the diameter; the curved cap with holes with 0
flips and 0 crossings; halftunnel.off and beetle.off run end to end with fill="auto" and honest reports.
"""

from __future__ import annotations

import igl
import numpy as np
import pytest

from heatparam import datasets, fill, metrics, pipeline
from heatparam.errors import HeatparamError
from heatparam.mesh import validate_mesh

from conftest import shared_mesh

METHODS = ("poisson", "biharmonic")


def _parameterize(sh: datasets.Shape, method: str):
    """The pipeline's raw map with the fill ``method`` ("none", "poisson", "biharmonic")."""
    return pipeline.parameterize(sh.V, sh.F, fill=method, refine="none")


@pytest.fixture(scope="module")
def s_strip():
    return datasets.cone_s_strip()


@pytest.fixture(scope="module")
def cyl_holes():
    return datasets.cylinder_with_holes()


# ----------------------------------------------------------------------------------------------------------
# acceptance through the pipeline
# ----------------------------------------------------------------------------------------------------------
def test_s_strip_folds_without_fill(s_strip):
    uv, rep = _parameterize(s_strip, "none")
    m = rep["metrics"]
    assert m["flips"] > 0 or m["iso_mean"] > 1.5
    assert rep["method"]["fill"]["used"] is False


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("name", ["s_strip", "cyl_holes"])
def test_developable_with_fill_is_near_isometric(name, method, request):
    sh = request.getfixturevalue(name)
    uv, rep = _parameterize(sh, method)
    m, fr = rep["metrics"], rep["method"]["fill"]
    assert fr["used"] and fr["method"] == method
    assert m["flips"] == 0
    assert m["boundary_crossings"] == 0
    assert m["iso_mean"] <= 1.10
    assert metrics.layout_error(uv, sh.uv_true) <= 0.03
    assert fr["boundary_loops"] == 1


@pytest.mark.parametrize("method", METHODS)
def test_curved_cap_with_fill_is_bijective(method):
    uv, rep = _parameterize(datasets.curved_cap_with_holes(), method)
    assert rep["metrics"]["flips"] == 0
    assert rep["metrics"]["boundary_crossings"] == 0


def _load_shared(name: str) -> datasets.Shape:
    from heatparam.formats import load_mesh

    V, F = load_mesh(shared_mesh(name))
    return datasets.Shape(V, F, None, name)


@pytest.mark.parametrize("name", ["halftunnel.off", "beetle.off"])
def test_shared_meshes_run_with_auto_fill_and_honest_report(name):
    sh = _load_shared(name)
    uv, rep = pipeline.parameterize(sh.V, sh.F, fill="auto", refine="none")
    assert uv.shape == (len(sh.V), 2) and np.isfinite(uv).all()
    fr = rep["method"]["fill"]
    assert fr["used"] and fr["reason"].startswith("auto:") and "hole" in fr["reason"]
    assert fr["boundary_loops"] == 1 and fr["distance_max_rel"] < 0.02
    m = rep["metrics"]
    folded = m["flips"] > 0 or m["boundary_crossings"] > 0
    assert folded == any("not bijective" in w for w in rep["warnings"])


# ----------------------------------------------------------------------------------------------------------
# needs_fill
# ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("make", [datasets.flat_disk, datasets.cylinder_patch])
def test_convex_patch_needs_no_fill(make):
    sh = make()
    need, why = fill.needs_fill(sh.V, sh.F, validate_mesh(sh.V, sh.F))
    assert not need and why.startswith("auto: convex disk without holes")


def test_holes_need_fill(cyl_holes):
    need, why = fill.needs_fill(cyl_holes.V, cyl_holes.F, validate_mesh(cyl_holes.V, cyl_holes.F))
    assert need and why == "auto: 2 holes"


def test_s_strip_needs_fill(s_strip):
    need, why = fill.needs_fill(s_strip.V, s_strip.F, validate_mesh(s_strip.V, s_strip.F))
    assert need and why.startswith("auto: concave border (hull/area")


# ----------------------------------------------------------------------------------------------------------
# trimming and the M -> M* correspondence
# ----------------------------------------------------------------------------------------------------------
def _hull_area(sh: datasets.Shape) -> float:
    info = validate_mesh(sh.V, sh.F)
    uv = fill.provisional_layout(sh.V, sh.F, info)
    return fill.concavity(uv, sh.F) * info.area


@pytest.mark.parametrize("method", METHODS)
def test_fill_is_one_disk_containing_m_and_bounded(method):
    sh = datasets.cylinder_with_holes(h=0.08)
    info = validate_mesh(sh.V, sh.F)
    M = fill.fill_surface(sh.V, sh.F, info, method=method)
    assert M.V.shape[1] == 3 and M.F.dtype == np.int64 and M.face.shape == (len(sh.V),)
    assert len(igl.boundary_loop_all(M.F)) == 1
    validate_mesh(M.V, M.F)  # a single manifold, consistently oriented disk
    located = np.einsum("pc,pcd->pd", M.bary, M.V[M.F[M.face]])
    dist = np.linalg.norm(located - sh.V, axis=1)
    assert dist.max() <= 0.01 * info.diameter
    assert M.report["distance_max"] == pytest.approx(dist.max(), abs=1e-9 * info.diameter)
    # Spans the gaps, but not far beyond the hull of M's layout.
    area = float(np.sum(0.5 * np.linalg.norm(np.cross(M.V[M.F[:, 1]] - M.V[M.F[:, 0]],
                                                       M.V[M.F[:, 2]] - M.V[M.F[:, 0]]), axis=1)))
    assert info.area * 1.05 < area <= 1.1 * _hull_area(sh)
    assert M.report["extent_rel"] <= 1.05


def test_trim_closed_reconstruction_keeps_the_near_side():
    """A closed 'reconstruction' (the whole sphere under a cap) is cut to the cap's hull, near side only."""
    import trimesh

    sh = datasets.curved_cap_with_holes(h=0.07)
    info = validate_mesh(sh.V, sh.F)
    ball = trimesh.creation.icosphere(subdivisions=5, radius=4.0)
    Vp = np.asarray(ball.vertices) + np.array([0.0, 0.0, -4.0])
    Fp = np.asarray(ball.faces, dtype=np.int64)
    uv = fill.provisional_layout(sh.V, sh.F, info)
    Vs, Fs, _ = fill.trim_to_hull(Vp, Fp, sh.V, sh.F, uv, near=0.25 * info.diameter)
    assert len(igl.boundary_loop_all(Fs)) == 1
    assert Vs[:, 2].min() > -0.5  # nothing from the far side of the sphere (z down to -8)
    _, _, d = fill.locate_points(sh.V, Vs, Fs)
    assert d.max() < 0.01 * info.diameter


def test_biharmonic_fill_contains_m_exactly(s_strip):
    info = validate_mesh(s_strip.V, s_strip.F)
    M = fill.biharmonic_fill(s_strip.V, s_strip.F, info)
    n, m = len(s_strip.V), len(s_strip.F)
    np.testing.assert_array_equal(M.V[:n], s_strip.V)
    np.testing.assert_array_equal(M.F[:m], s_strip.F)
    np.testing.assert_allclose(np.einsum("pc,pcd->pd", M.bary, M.V[M.F[M.face]]), s_strip.V, atol=1e-12)
    assert M.report["gap_vertices"] > 0.3 * n  # the bays between the arms are filled


def test_auto_depth_is_scale_free(s_strip):
    info = validate_mesh(s_strip.V, s_strip.F)
    big = datasets.scale_shape(s_strip, 100.0)
    assert fill.auto_depth(info) == fill.auto_depth(validate_mesh(big.V, big.F))


def test_auto_depth_makes_a_cell_of_about_half_a_mean_edge(s_strip):
    """The coarsest depth whose octree cell (PoissonRecon's cube, ~1.1 × the diameter, over 2^depth) is at most
    CELL_PER_EDGE × the mean edge; clamped to MIN_DEPTH..MAX_DEPTH on very coarse and very fine meshes."""
    from types import SimpleNamespace

    info = validate_mesh(s_strip.V, s_strip.F)
    depth = fill.auto_depth(info)
    assert depth == 8  # diameter 2.41, mean edge 0.031: a cell of 0.34 mean edges
    cell = 1.1 * info.diameter / 2**depth
    assert 0.5 * fill.CELL_PER_EDGE * info.mean_edge < cell <= fill.CELL_PER_EDGE * info.mean_edge
    assert fill.auto_depth(SimpleNamespace(diameter=1.0, mean_edge=0.5)) == fill.MIN_DEPTH  # unclamped: 3
    assert fill.auto_depth(SimpleNamespace(diameter=1.0, mean_edge=1e-4)) == fill.MAX_DEPTH  # unclamped: 15


# ----------------------------------------------------------------------------------------------------------
# errors
# ----------------------------------------------------------------------------------------------------------
def test_unknown_method_is_a_one_line_error(cyl_holes):
    with pytest.raises(HeatparamError, match="fill method must be one of"):
        fill.fill_surface(cyl_holes.V, cyl_holes.F, validate_mesh(cyl_holes.V, cyl_holes.F), method="mls")


def test_empty_reconstruction_raises(monkeypatch):
    import gpytoolbox

    sh = datasets.cylinder_with_holes(h=0.08)
    monkeypatch.setattr(gpytoolbox, "point_cloud_to_mesh",
                        lambda P, N, **kw: (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)))
    with pytest.raises(HeatparamError, match="Poisson reconstruction .* produced no surface"):
        fill.poisson_fill(sh.V, sh.F, validate_mesh(sh.V, sh.F))


def test_auto_falls_back_when_the_fill_fails(cyl_holes, monkeypatch):
    def broken(*args, **kwargs):
        raise HeatparamError("the Poisson reconstruction (depth 8) produced no surface")

    monkeypatch.setattr(fill, "fill_surface", broken)
    uv, rep = pipeline.parameterize(cyl_holes.V, cyl_holes.F, fill="auto", refine="none")
    assert rep["method"]["fill"]["used"] is False and "produced no surface" in rep["method"]["fill"]["failed"]
    assert any("fill surface failed" in w for w in rep["warnings"])
    with pytest.raises(HeatparamError, match="produced no surface"):
        pipeline.parameterize(cyl_holes.V, cyl_holes.F, fill="poisson", refine="none")


def test_poisson_fill_refuses_planar_mesh():
    sh = datasets.flat_square()
    with pytest.raises(HeatparamError, match="planar"):
        pipeline.parameterize(sh.V, sh.F, fill="poisson")
    uv, rep = pipeline.parameterize(sh.V, sh.F, fill="biharmonic", refine="none")  # the alternative works
    assert rep["metrics"]["flips"] == 0
