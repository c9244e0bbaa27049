"""refine.charts: several charts polished in one Newton system keep every chart bijective, never let two charts
overlap, and lower the distortion of each."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets
from heatparam.atlas.overlap import count_overlaps
from heatparam.layout import tutte
from heatparam.layout.conformal import conformal_layout
from heatparam.metrics import true_scale_iso
from heatparam.refine.charts import arrange, refine_charts

from conftest import excess_cone


def _mean_iso(V, F, uv):
    fi, area, det = true_scale_iso(V, F, uv)
    assert (det > 0).all()
    return float((fi * area).sum() / area.sum())


def test_three_charts_polished_together():
    """A developable chart, a chart lifted onto a sphere (LSCM is not isometric there) and a small flat one, all
    laid at the origin (overlapping) before the call."""
    cyl = datasets.cylinder_patch(h=0.12)
    disk = datasets.flat_disk(h=0.12)
    small = datasets.scale_shape(datasets.flat_disk(h=0.15), 0.3)
    parts = [(cyl.V, cyl.F), (datasets.lift_sphere(disk.uv_true, 1.5), disk.F), (small.V, small.F)]
    offs = np.cumsum([0] + [len(p[0]) for p in parts])
    V = np.vstack([p[0] for p in parts])
    F = np.vstack([p[1] + o for p, o in zip(parts, offs[:-1], strict=True)])
    vgroup = np.repeat(np.arange(len(parts)), np.diff(offs))
    starts = [conformal_layout(Vi, Fi) for Vi, Fi in parts]
    x, rep = refine_charts(V, F, np.vstack(starts), vgroup, len(parts))
    assert rep["flips"] == 0 and rep["boundary_crossings"] == 0 and rep["converged"]
    assert count_overlaps(x, F) == 0
    before = [_mean_iso(Vi, Fi, starts[i]) for i, (Vi, Fi) in enumerate(parts)]
    after = [_mean_iso(Vi, Fi, x[offs[i]:offs[i + 1]]) for i, (Vi, Fi) in enumerate(parts)]
    assert after[1] < before[1] - 1e-3  # the curved chart gains
    assert after[0] < 1.0 + 1e-3 and after[2] < 1.0 + 1e-3  # the flat ones stay (near) isometric


def test_arrange_separates_the_charts_boxes():
    uv = np.array([[0, 0], [1, 0], [0, 1], [0, 0], [2, 0], [0, 2]], dtype=float)
    vgroup = np.array([0, 0, 0, 1, 1, 1])
    x = arrange(uv, vgroup, 2)
    lo0, hi0 = x[:3].min(0), x[:3].max(0)
    lo1, hi1 = x[3:].min(0), x[3:].max(0)
    assert (hi0 < lo1).any() or (hi1 < lo0).any()
    np.testing.assert_allclose(x[:3] - x[0], uv[:3] - uv[0])  # translations only


def test_excess_rule_stops_early_at_nearly_the_same_energy():
    """The joint polish's stop on the excess (two iterations in a row that gain < EXCESS_TOL of the energy's
    excess over an isometry, whatever the step and scaffold, or the next gain, the last one times its ratio to the
    one before, predicted below that): on a torus's charts it takes fewer iterations than the polish run to its
    ordinary convergence, to an energy within 1e-3 of the start's excess of that one's."""
    from heatparam.atlas.chart_topology import Topology
    from heatparam.atlas.flatten import flatten_charts
    from heatparam.atlas.segment import segment

    V, F = datasets.torus()
    topo = Topology.build(V, F)
    seg = segment(topo, 1.05)
    groups = [np.flatnonzero(seg.chart == c) for c in range(seg.chart.max() + 1)]
    fl = flatten_charts(topo, groups, seg.glued)
    assert fl.ok(np.inf).all()
    for scaffold in (True, False):  # with the scaffold the rule's own stop; without, an uncut small step's
        _, fast = refine_charts(fl.Vl, fl.Fl, fl.uv, fl.vgroup, len(groups), scaffold=scaffold)
        _, full = refine_charts(fl.Vl, fl.Fl, fl.uv, fl.vgroup, len(groups), excess_tol=0.0, scaffold=scaffold)
        if scaffold:
            assert fast["stop"].startswith(("converged (next gain predicted", "converged (gains below"))
            assert full["stop"] == "converged"
        assert fast["converged"] and full["converged"]
        assert fast["iterations"] < full["iterations"]
        assert fast["flips"] == 0 and fast["boundary_crossings"] == 0
        assert fast["energy_end"] - full["energy_end"] <= 1e-3 * (full["energy_start"] - 1.0)


def test_polish_without_scaffold_stops_where_the_boundary_would_cross(monkeypatch):
    """The joint polish has no scaffold: each chart's step is halved until its boundary does not cross itself.
    On a cone whose isometric layout overlaps itself, from a Tutte start, the polish lowers the energy and stays
    bijective; the same polish with the crossing check switched off runs into the overlap (so the check is what
    keeps it out)."""
    from heatparam import metrics

    V, F = excess_cone()
    uv = tutte.tutte(V, tutte.build_disk(V, F))  # a bijective start
    assert metrics.boundary_crossings(uv, F) == 0
    groups = np.zeros(len(V), dtype=np.int64)
    x, rep = refine_charts(V, F, uv, groups, 1)
    assert rep["energy_end"] < rep["energy_start"] - 1.0
    assert rep["flips"] == 0 and rep["boundary_crossings"] == 0 and count_overlaps(x, F) == 0
    monkeypatch.setattr(metrics, "crossing_pairs", lambda P, E: np.zeros((0, 2), dtype=np.int64))
    y, off = refine_charts(V, F, uv, groups, 1)
    monkeypatch.undo()
    assert off["flips"] == 0 and metrics.boundary_crossings(y, F) > 0 and count_overlaps(y, F) > 0


def test_a_chart_whose_boundary_keeps_crossing_does_not_hold_the_others_back(monkeypatch):
    """Polished together with the excess cone, already polished until its boundary meets itself (so its steps
    cross at once; a single halving allowed here), a chart lifted onto a sphere reaches the distortion it reaches
    when polished alone: the crossing chart stays where it is, the others go on."""
    from heatparam import metrics
    from heatparam.refine import newton

    Vc, Fc = excess_cone()
    uc = tutte.tutte(Vc, tutte.build_disk(Vc, Fc))
    uc, _ = refine_charts(Vc, Fc, uc, np.zeros(len(Vc), dtype=np.int64), 1)  # polished until its boundary meets
    disk = datasets.flat_disk(h=0.12)
    Vs, Fs = datasets.lift_sphere(disk.uv_true, 1.5), disk.F
    us = conformal_layout(Vs, Fs)
    monkeypatch.setattr(newton, "CROSSING_HALVINGS", 1)
    alone, _ = refine_charts(Vs, Fs, us, np.zeros(len(Vs), dtype=np.int64), 1)
    V = np.vstack([Vc, Vs])
    F = np.vstack([Fc, Fs + len(Vc)])
    groups = np.repeat([0, 1], [len(Vc), len(Vs)])
    x, rep = refine_charts(V, F, np.vstack([uc, us]), groups, 2)
    assert rep["flips"] == 0 and rep["boundary_crossings"] == 0 and count_overlaps(x, F) == 0
    assert metrics.boundary_crossings(x[:len(Vc)], Fc) == 0
    assert _mean_iso(Vs, Fs, x[len(Vc):]) == pytest.approx(_mean_iso(Vs, Fs, alone), abs=1e-4)
    assert _mean_iso(Vs, Fs, x[len(Vc):]) < _mean_iso(Vs, Fs, us) - 1e-3
