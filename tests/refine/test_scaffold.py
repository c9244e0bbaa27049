"""Scaffold steps (``refine.scaffold.feasible_step``, ``boundary_gaps``): chained scaffolds go past a single
scaffold's artificial limit, never past a real contact, and keep every point of the step bijective."""

from __future__ import annotations

import numpy as np

from heatparam import datasets, metrics
from heatparam.layout import tutte
from heatparam.mesh import boundary_loops
from heatparam.refine import scaffold
from heatparam.refine.energy import hat_gradients, jacobians, max_step


def _setup():
    s = datasets.cylinder_with_holes()
    disk = tutte.build_disk(s.V, s.F)
    loops = [disk.outer, *disk.holes]
    return s, s.uv_true, loops, scaffold.build_scaffold(s.uv_true, loops)


def _single_scaffold_limit(uv, d, sc):
    xs = np.vstack([uv, sc.box])
    gs = hat_gradients(xs[sc.F])
    return 0.9 * max_step(jacobians(xs, sc.F, gs), jacobians(np.vstack([d, np.zeros((4, 2))]), sc.F, gs))


def test_boundary_gaps_measure_distance_to_the_nearest_other_edge():
    """A unit square's corners are one edge apart; a hole of half-width r centred in it is 0.5 - r from it."""
    sq = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    hole = 0.5 + 0.1 * np.array([[-1.0, -1], [-1, 1], [1, 1], [1, -1]])  # clockwise
    uv = np.vstack([sq, hole])
    gaps = scaffold.boundary_gaps(uv, [np.arange(4), np.arange(4, 8)])
    assert np.allclose(gaps[:4], 0.4 * np.sqrt(2))  # a corner's nearest non-incident edge: the hole's corner
    assert np.allclose(gaps[4:], 0.2)  # a hole corner's: the hole's own far sides (nearer than the square's)


def test_chained_scaffolds_go_past_a_single_scaffolds_limit_and_stay_bijective():
    """A shear slides the holes along the border: one scaffold's thin triangles flip early (no crossing there);
    re-triangulating goes on, and no point of the step has crossing boundaries."""
    s, uv, loops, sc = _setup()
    d = np.column_stack([np.sin(3 * np.pi * uv[:, 1] / np.ptp(uv[:, 1])), np.zeros(len(uv))])
    t = scaffold.feasible_step(uv, d, loops, sc, 100.0)
    assert t > 5 * _single_scaffold_limit(uv, d, sc)
    for a in np.linspace(0, t, 25):
        assert metrics.boundary_crossings(uv + a * d, s.F) == 0


def test_a_step_towards_contact_stops_short_of_it():
    """A C-shaped part whose upper arm is sheared down onto the lower one (only scaffold lies between the arms;
    the surface's own flips come long after they meet): the chained scaffolds never let them cross, and the gap
    rule ends the step with every boundary vertex at least GAP_FRACTION of its first distance away."""
    outer = datasets.polygon(np.array([[0.0, 0], [3, 0], [3, 1], [1, 1], [1, 2], [3, 2], [3, 3], [0, 3]]), 0.1)
    uv, F = datasets.mesh_domain([outer], 0.1)
    loops = boundary_loops(F)
    sc = scaffold.build_scaffold(uv, loops)
    d = np.column_stack([np.zeros(len(uv)), -np.clip(uv[:, 0] - 1, 0, 1) * (uv[:, 1] > 1.5)])
    J, D = jacobians(uv, F, hat_gradients(uv[F])), jacobians(d, F, hat_gradients(uv[F]))
    surface = 0.9 * max_step(J, D)
    assert surface > 3  # the surface alone would let the arms pass through each other
    t = scaffold.feasible_step(uv, d, loops, sc, surface)
    assert t < 1.0  # the arms touch at t = 1 (their gap is 1)
    g0, g1 = scaffold.boundary_gaps(uv, loops), scaffold.boundary_gaps(uv + t * d, loops)
    # a vertex's gap is at most an edge or two (the next edges along its own side), so the arms may come that
    # close: much closer than one scaffold alone allows
    assert (g1 >= scaffold.GAP_FRACTION * g0).all() and g1.min() < 0.05
    assert t > 0.95 > _single_scaffold_limit(uv, d, sc)
    for a in np.linspace(0, t, 25):
        assert metrics.boundary_crossings(uv + a * d, F) == 0
    assert metrics.boundary_crossings(uv + 1.05 * d, F) > 0
