"""refine.smoother: Gauss-Seidel sweeps on the symmetric Dirichlet energy, the multilevel polish's smoother."""

from __future__ import annotations

import numpy as np

from heatparam.mesh import boundary_loops
from heatparam.metrics import boundary_crossings
from heatparam.refine import energy
from heatparam.refine.smoother import Smoother

from conftest import flat_disk


def _jittered_disk(amount: float, seed: int = 1):
    """The flat disk, its isometric layout with every interior vertex moved at random by up to ``amount`` × the
    ring spacing, halved until no face is flipped, the surface's hat gradients and areas, and its boundary."""
    V, F = flat_disk(n_ring=16)
    fixed = np.concatenate(boundary_loops(F))
    inner = np.setdiff1d(np.arange(len(V)), fixed)
    move = np.random.default_rng(seed).uniform(-amount, amount, (len(inner), 2)) / 16
    g, area = energy.surface_gradients(V, F)
    while True:
        uv = V[:, :2].copy()
        uv[inner] += move
        if (energy.det(energy.jacobians(uv, F, g)) > 0).all():
            return V, F, uv, g, area, fixed
        move /= 2


def test_sweeps_remove_local_error_and_keep_the_boundary():
    V, F, uv, g, area, fixed = _jittered_disk(0.3)
    sm = Smoother(F, g, area, len(V), fixed)
    x, rep = sm.smooth(uv)
    e0, e1 = energy.normalized_energy(uv, F, g, area), energy.normalized_energy(x, F, g, area)
    assert rep["energy_before"] == e0 and rep["energy_after"] == e1
    assert e1 - 1.0 < 0.1 * (e0 - 1.0)  # the jitter is the local error a smoother is for
    assert np.array_equal(x[fixed], uv[fixed])
    assert (energy.det(energy.jacobians(x, F, g)) > 0).all() and boundary_crossings(x, F) == 0
    assert np.array_equal(uv, _jittered_disk(0.3)[2])  # the input is not touched


def test_each_sweep_lowers_the_energy_by_what_it_reports():
    V, F, uv, g, area, fixed = _jittered_disk(0.4, seed=2)
    sm = Smoother(F, g, area, len(V), fixed)
    x = uv.copy()
    e = energy.normalized_energy(x, F, g, area)
    for _ in range(4):
        gain = sm.sweep(x)
        e1 = energy.normalized_energy(x, F, g, area)
        assert gain > 0 and np.isclose(4 * (e - e1), gain, rtol=1e-8)
        e = e1


def test_an_isometry_stays_put_and_smoothing_is_deterministic():
    V, F, uv, g, area, fixed = _jittered_disk(0.0)
    x, rep = Smoother(F, g, area, len(V), fixed).smooth(uv)
    assert np.allclose(x, uv, atol=1e-12) and rep["sweeps"] <= 2
    V, F, uv, g, area, fixed = _jittered_disk(0.3)
    a, _ = Smoother(F, g, area, len(V), fixed).smooth(uv)
    b, _ = Smoother(F, g, area, len(V), fixed).smooth(uv)
    assert np.array_equal(a, b)


def test_one_vertex_moves_to_its_minimum():
    """A lone movable vertex, displaced in an isometric layout: its faces' energy is least back where it was, and
    a few local Newton steps (one per sweep) take it there."""
    V, F, uv, g, area, _ = _jittered_disk(0.0)
    v = 200
    x = uv.copy()
    x[v] += [0.02, -0.015]
    assert (energy.det(energy.jacobians(x, F, g)) > 0).all()
    sm = Smoother(F, g, area, len(V), np.delete(np.arange(len(V)), v))
    for _ in range(6):
        sm.sweep(x)
    assert np.linalg.norm(x[v] - uv[v]) < 1e-9 and np.array_equal(np.delete(x, v, 0), np.delete(uv, v, 0))
