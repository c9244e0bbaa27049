import numpy as np
import pytest

from heatparam import memory
from heatparam.errors import ResourceError
from heatparam.mds import classical_mds, landmark_mds, orient_layout


def _procrustes_err(X, Y):
    Xc, Yc = X - X.mean(0), Y - Y.mean(0)
    U, _, Wt = np.linalg.svd(Xc.T @ Yc)
    return np.abs(Xc @ U @ Wt - Yc).max()


def _points(n=300, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (n, 2)) * [2.0, 1.0]


def test_classical_mds_recovers_euclidean_points():
    P = _points()
    D = np.linalg.norm(P[:, None] - P[None], axis=2)
    X = classical_mds(D)
    assert _procrustes_err(X, P) < 1e-8  # rigid motion only: no scaling
    assert np.allclose(X.mean(0), 0)


def test_classical_mds_deterministic():
    P = _points()
    D = np.linalg.norm(P[:, None] - P[None], axis=2)
    assert np.array_equal(classical_mds(D, seed=1), classical_mds(D, seed=1))


def test_landmark_mds_matches():
    P = _points(500)
    lm = np.arange(0, 500, 10)
    DL = np.linalg.norm(P[:, None] - P[lm][None], axis=2)
    X, XL = landmark_mds(DL, lm)
    assert _procrustes_err(X, P) < 1e-8
    assert np.allclose(XL, X[lm])
    X2, _ = landmark_mds(DL, Dkk=DL[lm])
    assert np.allclose(X, X2)


def test_memory_guard(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 1000)
    D = np.zeros((50, 50))
    with pytest.raises(ResourceError, match="GiB"):
        classical_mds(D)


def test_orient_layout_mirrors_clockwise():
    uv = np.array([[0, 0], [1, 0], [0, 1.0]])
    F = np.array([[0, 2, 1]])
    out = orient_layout(uv, F)
    a, b = out[1] - out[0], out[2] - out[0]
    assert a[0] * b[1] - a[1] * b[0] < 0  # face (0,2,1) is now counter-clockwise
    e1, e2 = out[F[0, 1]] - out[F[0, 0]], out[F[0, 2]] - out[F[0, 0]]
    assert e1[0] * e2[1] - e1[1] * e2[0] > 0
