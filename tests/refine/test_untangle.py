"""Untangling (Garanzha et al. 2021): flip-free positions for the free vertices, the rest held exactly."""

from __future__ import annotations

import numpy as np

from heatparam import datasets
from heatparam.layout import tutte
from heatparam.refine import energy
from heatparam.refine.untangle import UNTANGLE_ROUNDS, _Region, _terms, untangle


def _flipped(x, F, g):
    return int((energy.det(energy.jacobians(x, F, g)) <= 0).sum())


def test_untangle_unflips_a_fold_beside_a_locked_boundary():
    """A vertex next to the border pushed out across it: its star folds over the locked boundary."""
    s = datasets.cylinder_patch(h=0.05)
    g, area = energy.surface_gradients(s.V, s.F)
    disk = tutte.build_disk(s.V, s.F)
    locked = np.zeros(len(s.V), dtype=bool)
    locked[disk.outer] = True
    x = s.uv_true.copy()
    # the interior vertex nearest the boundary, pushed through it by 3 edge lengths
    nb = np.isin(s.F, disk.outer).any(axis=1)
    cand = np.setdiff1d(s.F[nb].ravel(), disk.outer)
    v = int(cand[0])
    b = disk.outer[np.argmin(np.linalg.norm(s.uv_true[disk.outer] - s.uv_true[v], axis=1))]
    x[v] += 3.0 * (s.uv_true[b] - s.uv_true[v])
    assert _flipped(x, s.F, g) > 0
    free = np.zeros(len(x), dtype=bool)
    ring = np.isin(s.F, [v]).any(axis=1)
    free[s.F[ring].ravel()] = True
    for _ in range(3):
        free[s.F[free[s.F].any(axis=1)].ravel()] = True
    free &= ~locked
    y, rounds = untangle(x, s.F, g, area, free)
    assert y is not None and 2 <= rounds <= UNTANGLE_ROUNDS + 1  # ε rounds, then the barrier's minimization
    assert _flipped(y, s.F, g) == 0
    assert np.array_equal(y[~free], x[~free])  # nothing else moves
    # the repaired star is near the true layout's (a developable patch: the isometry is flip-free), not just unfolded
    assert energy.normalized_energy(y, s.F, g, area) < 1.5


def test_untangle_gives_up_when_the_flip_involves_only_held_vertices():
    s = datasets.cylinder_patch(h=0.1)
    g, area = energy.surface_gradients(s.V, s.F)
    x = s.uv_true.copy()
    f = s.F[0]
    x[f[0]], x[f[1]] = s.uv_true[f[1]], s.uv_true[f[0]]  # face 0 reversed by swapping two of its corners
    assert _flipped(x, s.F, g) > 0
    free = np.zeros(len(x), dtype=bool)
    free[np.setdiff1d(np.arange(len(x)), f)[:5]] = True  # free vertices far from face 0 cannot unflip it
    y, rounds = untangle(x, s.F, g, area, free)
    assert y is None and rounds == 0


def test_the_face_terms_derivatives_match_finite_differences():
    """ψ's gradient and Hessian in vec(J), folded faces included, against central differences."""
    rng = np.random.default_rng(3)
    J = rng.normal(size=(40, 2, 2))
    J[:20, 0] *= -1.0  # half of them flipped
    eps, h = 0.3, 1e-6
    _, grad, hess = _terms(J, eps, derivatives=True)
    for k in range(4):
        dJ = np.zeros(4)
        dJ[k] = h
        up = _terms(J + dJ.reshape(2, 2), eps, derivatives=True)
        down = _terms(J - dJ.reshape(2, 2), eps, derivatives=True)
        np.testing.assert_allclose((up[0] - down[0]) / (2 * h), grad[:, k], rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose((up[1] - down[1]) / (2 * h), hess[:, :, k], rtol=1e-5, atol=1e-5)


def test_each_minimization_reaches_the_minimum_lbfgs_finds():
    """The Newton minimization of E_ε over a region ends where scipy's L-BFGS (the paper's method) ends."""
    from scipy.optimize import minimize

    s = datasets.cylinder_patch(h=0.1)
    g, area = energy.surface_gradients(s.V, s.F)
    rng = np.random.default_rng(0)
    x = s.uv_true + rng.normal(scale=0.05, size=s.uv_true.shape)
    free = np.zeros(len(x), dtype=bool)
    free[np.unique(s.F[:12])] = True
    faces = np.flatnonzero(free[s.F].any(axis=1))
    region = _Region(x, s.F[faces], g[faces], area[faces], free)
    y0 = region.y.copy()

    def fun(z):
        y = y0.copy()
        y[region.fi] = z.reshape(-1, 2)
        return region.energy(y, 0.1)

    ref = minimize(fun, y0[region.fi].ravel(), method="L-BFGS-B", options={"maxiter": 2000, "ftol": 1e-14})
    region.minimize(0.1)
    assert region.energy(region.y, 0.1) <= ref.fun * (1 + 1e-6)
