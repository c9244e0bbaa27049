"""Refinement (issue 5): flip-free, bijective, near-isometric maps through ``pipeline.parameterize`` defaults."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import pipeline, refine, shapes

from conftest import shared_mesh


def _param(V, F):
    """The pipeline with its default settings (fill auto, refine sd)."""
    return pipeline.parameterize(V, F)


def _load(name):
    from heatparam import io

    return io.load_mesh(shared_mesh(name))


# ---------------------------------------------------------------------------------------------------------- units
def test_max_step_is_first_root_of_det():
    rng = np.random.default_rng(0)
    J = np.eye(2)[None] + 0.1 * rng.standard_normal((50, 2, 2))
    D = rng.standard_normal((50, 2, 2))
    t = refine.max_step(J, D)
    assert np.isfinite(t) and t > 0
    dets = np.linalg.det(J + t * D)
    assert np.isclose(dets, 0.0, atol=1e-9).any()
    assert (np.linalg.det(J + 0.999 * t * D) > 0).all()


def test_polar_weights_match_svd():
    rng = np.random.default_rng(1)
    J = 2 * np.eye(2)[None] + rng.standard_normal((200, 2, 2))
    J = J[np.linalg.det(J) > 0.05]
    R, W2 = refine._polar_weights(J)
    U, s, Vt = np.linalg.svd(J)
    assert np.allclose(R, U @ Vt)
    w2 = (s + 1) * (s * s + 1) / s**3
    assert np.allclose(W2, np.einsum("mab,mb,mcb->mac", U, w2, U))


def test_tutte_on_disk_with_holes_is_flip_free():
    s = shapes.cylinder_with_holes()
    disk = refine.build_disk(s.V, s.F)
    assert len(disk.holes) >= 1
    uv = refine.tutte(s.V, disk)
    g, _ = refine.surface_gradients(s.V, s.F)
    assert (np.linalg.det(refine.jacobians(uv[: len(s.V)], s.F, g)) > 0).all()


def test_refine_none_returns_raw_mds():
    s = shapes.cylinder_patch()
    _, rep = pipeline.parameterize(s.V, s.F, fill="none", refine="none")
    assert rep["method"]["refine"] == {"method": "none"}
    assert rep["metrics"]["iso_mean"] > 1.01  # the raw heat-MDS map (measured ~1.05)


# ---------------------------------------------------------------------------------------------------------- acceptance
def _check_isometric(shape):
    uv, rep = _param(shape.V, shape.F)
    m = rep["metrics"]
    assert m["flips"] == 0
    assert m["boundary_crossings"] == 0
    assert m["iso_mean"] <= 1.001
    assert shapes.layout_error(uv, shape.uv_true) <= 1e-3


def test_cylinder_patch_isometric():
    _check_isometric(shapes.cylinder_patch())


def test_cylinder_with_holes_isometric():
    _check_isometric(shapes.cylinder_with_holes())


def test_cone_s_strip_isometric():
    _check_isometric(shapes.cone_s_strip())


def _check_bijective(V, F):
    _, rep = _param(V, F)
    assert rep["metrics"]["flips"] == 0
    assert rep["metrics"]["boundary_crossings"] == 0
    return rep


def test_curved_cap_with_holes_bijective():
    s = shapes.curved_cap_with_holes()
    _check_bijective(s.V, s.F)


@pytest.mark.parametrize("name", ["halftunnel.off", "woody.obj", "bump-domain.obj"])
def test_small_meshes_bijective(name):
    _check_bijective(*_load(name))


def test_camelhead_bijective():
    """Strongly curved disk: the MDS layout folds (~9.4k flipped faces); ~9 s on 2 cores."""
    _check_bijective(*_load("camelhead.off"))


def test_beetle_bijective():
    """20k vertices, 10 holes; ~15 s on 2 cores."""
    _check_bijective(*_load("beetle.off"))
