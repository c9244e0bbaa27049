"""The projected Newton polish (``refine.newton``): its line search on steep starts."""

from __future__ import annotations

import numpy as np

from heatparam.mesh import boundary_loops
from heatparam.refine import energy, newton


def _flat_grid(k: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A flat k×k grid of unit squares, each cut along a diagonal: V (n,3) at z = 0, F (m,3) counter-clockwise."""
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    V = np.column_stack([i.ravel(), j.ravel(), np.zeros(i.size)]).astype(np.float64)
    a = (i[:-1, :-1] * (k + 1) + j[:-1, :-1]).ravel()
    b, c, d = a + (k + 1), a + (k + 1) + 1, a + 1
    return V, np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(np.int64)


def test_polish_of_a_start_with_a_nearly_degenerate_triangle_doubles_its_step_on():
    # the isometric layout with one interior vertex pushed to 1e-9 of the way short of its opposite edge in one
    # triangle (bijective, det J 1e-9 there): Newton's step grows that det by only a third, so with the line search
    # doubling only once it took tens of iterations; doubling on while the energy falls, a few
    V, F = _flat_grid()
    g, area = energy.surface_gradients(V, F)
    uv = V[:, :2].copy()
    p = 6 * 13 + 6  # an interior vertex
    f = int(np.flatnonzero((F == p).any(axis=1))[0])
    a, b = (v for v in F[f] if v != p)
    uv[p] += (1 - 1e-9) * (0.5 * (uv[a] + uv[b]) - uv[p])
    J = energy.jacobians(uv, F, g)
    assert (energy.det(J) > 0).all() and energy.det(J).min() < 1e-8
    loops = boundary_loops(F)
    x, rep = newton.polish(uv, F, g, area, loops)
    assert rep["converged"] and rep["energy_start"] > 1e8
    assert rep["energy_end"] < 1 + 1e-6  # the isometry, to the tolerance
    assert rep["iterations"] <= 8
    assert (energy.det(energy.jacobians(x, F, g)) > 0).all()
