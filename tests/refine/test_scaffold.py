"""Scaffold steps (``refine.scaffold.feasible_step``, ``boundary_gaps``): chained scaffolds go past a single
scaffold's artificial limit, never past a real contact, and keep every point of the step bijective."""

from __future__ import annotations

import numpy as np
import pytest

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


def test_a_scaffold_holds_while_its_triangles_keep_their_area(monkeypatch):
    """The polish keeps the last iteration's scaffold (and so the Hessian's pattern) while every triangle keeps
    ``SCAFFOLD_KEEP`` of its area: it holds for its own layout and a slight squeeze of a hole, not once the hole
    is squeezed to a twentieth of its height (the triangles inside it too), nor when reuse is off."""
    s, uv, loops, sc = _setup()
    assert sc.area is not None and (sc.area > 0).all()
    assert scaffold.scaffold_holds(uv, sc)
    hole = loops[1]
    d = np.zeros_like(uv)
    d[hole, 1] = uv[hole, 1].mean() - uv[hole, 1]  # t = 1 flattens the first hole onto its middle line
    assert scaffold.scaffold_holds(uv + 0.01 * d, sc)
    assert not scaffold.scaffold_holds(uv + 0.95 * d, sc)
    monkeypatch.setattr(scaffold, "SCAFFOLD_KEEP", 0.0)
    assert not scaffold.scaffold_holds(uv, sc)


def test_polish_keeps_its_scaffold_and_so_the_factors_analysis(monkeypatch):
    """camelhead (one smooth border) near its minimum, as a fine level after its coarse one (``keep_scaffold``, as
    ``multilevel`` asks of such a level): the polish keeps the scaffold on most iterations (re-triangulated on
    every one when reuse is off) and so the Hessian's pattern: PARDISO refactorizes in place (no new analysis);
    the same minimum either way."""
    from heatparam import solvers
    from heatparam.formats import load_mesh
    from heatparam.layout.conformal import conformal_layout
    from heatparam.refine import newton
    from heatparam.refine.energy import surface_gradients

    from conftest import shared_mesh

    V, F = load_mesh(shared_mesh("camelhead.off"))
    g, area = surface_gradients(V, F)
    x0, _ = newton.polish(conformal_layout(V, F), F, g, area, boundary_loops(F), tol=1e-3, backend="pardiso")
    built, fresh_factors = [], []
    real_build, real_init = newton.build_scaffold, solvers.Factor.__init__
    monkeypatch.setattr(newton, "build_scaffold", lambda *a: built.append(1) or real_build(*a))
    monkeypatch.setattr(solvers.Factor, "__init__",
                        lambda self, *a, **k: fresh_factors.append(1) or real_init(self, *a, **k))
    runs, default = {}, scaffold.SCAFFOLD_KEEP
    for keep in (default, 0.0):
        monkeypatch.setattr(scaffold, "SCAFFOLD_KEEP", keep)
        built.clear()
        fresh_factors.clear()
        run = newton.Polish(x0, F, g, area, boundary_loops(F),
                            newton.PolishSettings(tol=1e-7, backend="pardiso", keep_scaffold=True))
        run.run()
        runs[keep] = (len(built), len(fresh_factors), run.report())
    (b_kept, f_kept, rep_kept), (b_fresh, f_fresh, rep_fresh) = runs[default], runs[0.0]
    assert rep_kept["converged"] and rep_fresh["converged"] and rep_kept["iterations"] >= 3
    assert b_fresh == rep_fresh["iterations"] and b_kept < rep_kept["iterations"] / 2, (b_kept, rep_kept)
    assert f_kept == 1 and f_kept <= f_fresh  # one analysis: every later factorization refactorized in place
    assert rep_kept["energy_end"] == pytest.approx(rep_fresh["energy_end"], rel=1e-6)
