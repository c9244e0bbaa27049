import numpy as np
import pytest
import scipy.sparse.linalg as spla

from heatparam.mesh import face_areas
from heatparam.operators import build_operators, intrinsic_areas, mollify


@pytest.mark.parametrize("mass", ["lumped", "consistent"])
def test_laplacian_and_mass(disk, mass):
    V, F = disk
    op = build_operators(V, F, mass=mass)
    L = op.L
    assert abs(L - L.T).max() < 1e-12
    assert np.abs(np.asarray(L.sum(axis=1))).max() < 1e-10
    lam_min = spla.eigsh(L.tocsc(), k=1, sigma=-1e-3, which="LM", return_eigenvectors=False)[0]
    assert lam_min > -1e-9  # positive semidefinite
    assert op.B.sum() == pytest.approx(face_areas(V, F).sum(), rel=1e-12)


def test_linear_precision_on_flat_mesh(disk):
    V, F = disk
    op = build_operators(V, F)
    boundary = np.zeros(len(V), bool)
    import igl

    boundary[igl.boundary_loop(F)] = True
    for x in (V[:, 0], 2 * V[:, 0] - 3 * V[:, 1] + 1):
        r = op.L @ x
        assert np.abs(r[~boundary]).max() < 1e-12
        assert np.abs(r[boundary]).max() > 1e-6  # the boundary term is not zero: the test can fail


def test_gradient_divergence_consistent_with_laplacian(disk):
    V, F = disk
    op = build_operators(V, F)
    assert abs((-op.D @ op.G) - op.L).max() < 1e-10
    # gradient of a linear function is constant with the right magnitude
    g = (op.G @ (3 * V[:, 0] + 4 * V[:, 1])).reshape(2, -1)
    assert np.allclose(np.hypot(g[0], g[1]), 5.0)


def test_mollification_handles_zero_area_faces():
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0], [1, -1, 0]], float)
    F = np.array([[0, 1, 3], [1, 2, 3], [0, 2, 1], [0, 4, 2]])  # face 2 is flat (collinear)
    lengths = np.linalg.norm(V[F[:, [1, 2, 0]]] - V[F[:, [2, 0, 1]]], axis=2)
    assert intrinsic_areas(lengths)[2] == 0.0
    ml, eps = mollify(lengths, 1e-4)
    assert eps > 0 and intrinsic_areas(ml).min() > 0
    op = build_operators(V, F)
    assert op.mollify_eps > 0
    assert np.isfinite(op.L.data).all() and np.isfinite(op.G.data).all()


def test_mollification_noop_on_good_mesh(disk):
    op = build_operators(*disk)
    assert op.mollify_eps == 0.0


def test_lengths_of_a_flipped_triangulation_stay_valid_when_exact_ones_would_break_a_needle():
    """The exact lengths of the input's edges and the intrinsic Delaunay triangulation's own (snapped) lengths differ
    by round-off; on a needle whose margin is smaller, mixing them makes a triangle of zero area (NaN cotangents:
    the heat factorization of a noisy 182k scan failed). Such a triangle's edges keep the triangulation's lengths."""
    from heatparam.operators import _consistent_lengths, _restore_lengths, intrinsic_areas

    F = np.array([[0, 1, 2], [0, 2, 3]])
    # lengths of the edge opposite each corner; edge 0-2 is shared: face 0's second, face 1's third
    l1 = np.array([[1.0, 1.999999, 1.0], [1.2, 1.2, 1.999999]])  # the triangulation's own: valid, face 0 a needle
    l0 = np.array([[1.0, 2.000001, 1.0], [1.2, 1.2, 2.000001]])  # "exact": the needle's long edge a hair too long
    assert (intrinsic_areas(_restore_lengths(F, l0, F, l1)) == 0).any()  # the failure this guards against
    fixed = _consistent_lengths(F, l0, F, l1)
    assert (intrinsic_areas(fixed) > 0).all()
    np.testing.assert_array_equal(fixed, l1)  # edge 0-2 from the triangulation, in both faces ...
    assert np.array_equal(_consistent_lengths(F, l1, F, l1 * (1 + 1e-9)), l1)  # ... exact lengths wherever valid
