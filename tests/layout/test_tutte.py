"""Tutte's embedding, the refinement's last-resort start (``layout.tutte``)."""

import numpy as np
import pytest

from heatparam import datasets, metrics
from heatparam.layout import tutte
from heatparam.refine import energy


def _judged(shape, weights):
    disk = tutte.build_disk(shape.V, shape.F)
    uv = tutte.tutte(shape.V, disk, weights=weights)[: len(shape.V)]
    g, area = energy.surface_gradients(shape.V, shape.F)
    flipped = int((np.linalg.det(energy.jacobians(uv, shape.F, g)) <= 0).sum())
    return uv, flipped, energy.normalized_energy(uv, shape.F, g, area)


@pytest.mark.parametrize("weights", tutte.TUTTE_WEIGHTS)
def test_tutte_on_disk_with_holes_is_bijective(weights):
    s = datasets.cylinder_with_holes()
    assert len(tutte.build_disk(s.V, s.F).holes) >= 1
    uv, flipped, _ = _judged(s, weights)
    assert flipped == 0
    assert metrics.boundary_crossings(uv, s.F) == 0 and metrics.inverted_loops(uv, s.F) == 0


@pytest.mark.parametrize("make", [datasets.cylinder_with_holes, datasets.curved_cap_with_holes,
                                  datasets.cone_s_strip])
def test_mean_value_weights_start_closer_to_an_isometry(make):
    s = make()
    _, flipped, e_mv = _judged(s, "mean_value")
    _, _, e_uniform = _judged(s, "uniform")
    assert flipped == 0 and e_mv < e_uniform


def test_mean_value_weights_fall_back_to_uniform_on_degenerate_triangles():
    s = datasets.cylinder_with_holes()
    V = s.V.copy()
    interior = np.setdiff1d(np.arange(len(V)), np.concatenate(tutte.build_disk(V, s.F).loops))
    a = interior[0]
    b = s.F[(s.F == a).any(axis=1)][0]
    V[b[b != a][0]] = V[a]  # a zero-length edge: mean value weights are not finite there
    disk = tutte.build_disk(V, s.F)
    with np.errstate(all="ignore"):
        assert not np.isfinite(tutte.mean_value_laplacian(np.vstack([V, np.zeros((len(disk.holes), 3))]),
                                                          disk.F).data).all()
    uv = tutte.tutte(V, disk)
    assert np.array_equal(uv, tutte.tutte(V, disk, weights="uniform"))


def test_unknown_weights_are_refused():
    s = datasets.flat_square()
    with pytest.raises(ValueError, match="weights"):
        tutte.tutte(s.V, tutte.build_disk(s.V, s.F), weights="cotan")


def test_a_failing_mean_value_solve_falls_back_to_uniform(monkeypatch):
    s = datasets.cylinder_with_holes()
    disk = tutte.build_disk(s.V, s.F)

    def fail(*args, **kwargs):
        raise ArithmeticError("singular")  # neither PARDISO's nor SuperLU's own error: any failure

    monkeypatch.setattr(tutte, "solve_unsymmetric", fail)
    assert np.array_equal(tutte.tutte(s.V, disk), tutte.tutte(s.V, disk, weights="uniform"))
