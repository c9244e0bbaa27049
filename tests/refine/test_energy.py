"""The symmetric Dirichlet energy's building blocks (``refine.energy``): the per-face Jacobians."""

from __future__ import annotations

import numpy as np

from heatparam.refine import energy

from conftest import imports_numba


def test_jacobians_are_the_same_bits_with_or_without_the_compiled_loop():
    """``energy.jacobians`` runs a compiled loop from ``COMPILED_MIN_FACES`` faces and numpy below it: each face's
    Jacobian is the same bits either way (a coarse level holds some of its mesh's faces, a flat one's det J at
    round-off), equal to the batched products to rounding, for int32 and int64 faces."""
    rng = np.random.default_rng(5)
    m = energy.COMPILED_MIN_FACES
    uv, g = rng.standard_normal((m // 2, 2)) * 300, rng.standard_normal((m, 3, 2))
    F = rng.integers(0, m // 2, (m, 3))
    J = energy.jacobians(uv, F, g)
    np.testing.assert_allclose(J, np.matmul(uv[F].transpose(0, 2, 1), g), rtol=0, atol=1e-10)
    assert np.array_equal(energy.jacobians(uv, F.astype(np.int32), g), J)
    assert np.array_equal(energy.jacobians(uv, F[:-1], g[:-1]), J[:-1])  # below it: numpy, face by face the same
    assert np.array_equal(energy.jacobians(uv, F[:3], g[:3]), J[:3])


def test_a_small_disk_is_flattened_without_numba():
    """Below ``COMPILED_MIN_FACES`` a disk's pipeline never imports numba (0.1-0.5 s a process)."""
    assert not imports_numba("import heatparam\nfrom heatparam import datasets\ns = datasets.cylinder_patch(h=0.1)\n"
                             "heatparam.parameterize(s.V, s.F)")


def test_newton_entries_from_the_compiled_loop_match_numpys():
    """``energy.sd_newton_entries`` from ``COMPILED_MIN_FACES`` faces: the compiled loop gives the gradient and the
    21 Hessian entries of the numpy passes below it (flipped faces included, whose flip eigenvalue is clamped)."""
    rng = np.random.default_rng(6)
    m = energy.COMPILED_MIN_FACES
    J = np.eye(2)[None] + 0.4 * rng.standard_normal((m, 2, 2))
    g, w = rng.standard_normal((m, 3, 2)), rng.uniform(0.5, 1.5, m)
    assert (energy.det(J) < 0).any()
    grad, out = energy.sd_newton_entries(J, g, w)
    grad0, out0 = energy.sd_newton_entries(J[:-1], g[:-1], w[:-1])  # below it: numpy's passes
    np.testing.assert_allclose(grad[:-1], grad0, rtol=1e-13, atol=1e-13 * np.abs(grad0).max())
    np.testing.assert_allclose(out[:, :-1], out0, rtol=1e-13, atol=1e-13 * np.abs(out0).max())
