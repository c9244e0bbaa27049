import numpy as np
import pytest

from heatparam import memory
from heatparam.errors import ResourceError
from heatparam.layout.conformal import orient_layout
from heatparam.layout.mds import classical_mds, landmark_mds, smacof


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


# ---- SMACOF (stress majorization of Eq. 1) ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def cyl_geodesics():
    """A coarse cylinder patch (developable), its all-pairs heat distances and its classical MDS layout."""
    from heatparam import datasets, heat
    from heatparam.operators import build_operators

    sh = datasets.cylinder_patch(h=0.08)
    op = build_operators(sh.V, sh.F)
    D = heat.all_pairs(heat.HeatGeodesics(op, heat.time_step(op)))
    return sh, D, classical_mds(D)


def _rel_stress(X, D):
    """Relative RMS stress of X over all pairs (independent of smacof's own bookkeeping)."""
    E = np.linalg.norm(X[:, None] - X[None], axis=2)
    return np.sqrt(((E - D) ** 2).sum() / (D**2).sum())


def test_smacof_monotone_from_mds_on_developable_surface(cyl_geodesics):
    from heatparam import metrics

    sh, D, X0 = cyl_geodesics
    X, info = smacof(X0, D, iters=300, tol=1e-9)
    h = np.array(info["history"])
    assert len(h) == info["iterations"] + 1 and info["iterations"] >= 5
    assert np.all(np.diff(h) <= 1e-12 * h[0])  # majorization: σ never increases (up to rounding)
    assert info["stress_start"] == pytest.approx(_rel_stress(X0, D), rel=1e-9)
    assert info["stress_end"] == pytest.approx(_rel_stress(X, D), rel=1e-9)
    assert info["stress_end"] < 0.8 * info["stress_start"]  # MDS minimizes strain, not stress: room to gain
    # Lower stress against heat distances also means a layout closer to the true flat one here.
    assert metrics.layout_error(X, sh.uv_true) < metrics.layout_error(X0, sh.uv_true)
    assert np.allclose(X.mean(axis=0), 0, atol=1e-12)  # the constraint of Eq. 1
    X2, _ = smacof(X0, D, iters=300, tol=1e-9)
    assert np.array_equal(X, X2)  # deterministic


@pytest.mark.parametrize("pattern", ["all-pairs", "landmarks", "weighted"])
def test_smacof_recovers_planar_configuration(pattern):
    """Exact Euclidean distances: the stress minimum is the configuration itself, up to a rigid motion."""
    P = _points(200)
    rng = np.random.default_rng(1)
    X0 = P @ np.array([[0.6, 0.8], [-0.8, 0.6]]) + 0.15 * rng.standard_normal(P.shape) + 3.0  # moved, noisy
    D = np.linalg.norm(P[:, None] - P[None], axis=2)
    if pattern == "all-pairs":
        X, info = smacof(X0, D, iters=3000, tol=1e-15)
    elif pattern == "weighted":
        W = rng.uniform(0.2, 2.0, D.shape)
        X, info = smacof(X0, D, iters=3000, tol=1e-15, weights=W + W.T)
    else:
        lm = rng.choice(200, 20, replace=False)
        X, info = smacof(X0, D[:, lm], lm, iters=3000, tol=1e-15)
    assert info["stress_start"] > 0.05 and info["stress_end"] < 1e-10
    assert _procrustes_err(X, P) < 1e-8  # rotation/reflection + translation only: a wrong scale fails this


def test_smacof_landmarks_with_every_point_equals_all_pairs():
    """k = n landmarks (in any order): the bipartite pattern holds every unordered pair twice, which doubles V and
    B(Z) alike, so each Guttman transform is the all-pairs one; only rounding may differ."""
    P = _points(150)
    rng = np.random.default_rng(2)
    D = np.linalg.norm(P[:, None] - P[None], axis=2) * rng.uniform(0.9, 1.1, (150, 150))
    D = 0.5 * (D + D.T)  # noisy: not Euclidean, so the minimum is not trivial
    np.fill_diagonal(D, 0)
    X0 = P + 0.1 * rng.standard_normal(P.shape)
    lm = rng.permutation(150)
    Xa, ia = smacof(X0, D, iters=10, tol=0)
    Xb, ib = smacof(X0, D[:, lm], lm, iters=10, tol=0)
    assert ia["iterations"] == ib["iterations"] == 10
    assert np.abs(Xa - Xb).max() < 1e-10 * np.abs(Xa).max()
    assert np.allclose(ia["history"], ib["history"], rtol=1e-10)


def test_smacof_landmarks_agrees_with_all_pairs_on_surface(cyl_geodesics):
    """k = 30 of 581 vertices. The landmark stress weighs only the n×k pairs, so its minimum is not the all-pairs
    one, but both fit the same nearly-Euclidean heat distances of a developable patch: each lies within ~1% of
    the diameter of the true flat layout (heat-distance error), hence within 2% of each other. A wrong Schur
    solve or a missing half of B(Z) gives a layout off by tens of percent or a rising stress."""
    from heatparam import metrics

    sh, D, X0 = cyl_geodesics
    lm = np.linspace(0, len(D) - 1, 30).astype(np.int64)
    XL0, _ = landmark_mds(D[:, lm], lm)
    Xl, il = smacof(XL0, D[:, lm], lm, iters=300, tol=1e-9)
    Xa, _ = smacof(X0, D, iters=300, tol=1e-9)
    assert Xl.shape == (len(D), 2) and il["pattern"] == "landmarks" and il["pairs"] == len(D) * 30 - 30
    assert np.all(np.diff(il["history"]) <= 1e-12 * il["history"][0])
    assert il["stress_end"] < 0.8 * il["stress_start"]
    diam = metrics.diameter(sh.uv_true)
    assert _procrustes_err(Xl, Xa) < 0.02 * diam
    assert _rel_stress(Xl, D) < _rel_stress(XL0, D)  # also lower on all pairs than its landmark-MDS start


def test_smacof_landmarks_never_allocates_n_by_n():
    import tracemalloc

    n, k = 3000, 30
    P = _points(n)
    lm = np.arange(0, n, n // k)
    DL = np.linalg.norm(P[:, None] - P[lm][None], axis=2)
    X0 = P + 0.05 * np.random.default_rng(3).standard_normal(P.shape)
    tracemalloc.start()
    X, info = smacof(X0, DL, lm, iters=20, tol=0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert X.shape == (n, 2) and info["iterations"] == 20
    assert peak < 0.1 * 8 * n * n  # an n×n float64 array would be 72 MB; n×k scratch is ~0.7 MB each


def test_smacof_rejects_bad_shapes():
    X0 = _points(10)
    with pytest.raises(ValueError):
        smacof(X0, np.zeros((10, 9)))
    with pytest.raises(ValueError):
        smacof(X0, np.zeros((10, 3)), np.array([0, 1, 1]))


def test_stress_option_reaches_report_and_cli(tmp_path):
    import json

    from heatparam import datasets
    from heatparam.cli import main
    from heatparam.errors import HeatparamError
    from heatparam.pipeline import parameterize

    sh = datasets.cylinder_with_holes(h=0.1)  # holes and a notch: the fill path has something to fill
    uv0, r0 = parameterize(sh.V, sh.F, fill="none", refine="none")
    uv1, r1 = parameterize(sh.V, sh.F, fill="none", refine="none", stress="smacof")
    assert r0["method"]["stress"] == {"method": "none"} and r0["parameters"]["stress"] == "none"
    s = r1["method"]["stress"]
    assert s["method"] == "smacof" and s["pattern"] == "all-pairs" and s["iterations"] >= 1
    assert s["stress_end"] < s["stress_start"]
    assert "history" not in s
    assert not np.allclose(uv0, uv1)  # the option changes the map
    # Fill path: the points and M*'s vertices against the landmarks on M*.
    _, r2 = parameterize(sh.V, sh.F, fill="biharmonic", refine="none", stress="smacof")
    s2 = r2["method"]["stress"]
    assert s2["pattern"] == "landmarks" and s2["stress_end"] < s2["stress_start"]
    with pytest.raises(HeatparamError, match="stress"):
        parameterize(sh.V, sh.F, stress="majorize")
    # CLI: the flag reaches the report.
    obj = tmp_path / "in.obj"
    with open(obj, "w") as fh:
        fh.writelines(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in sh.V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in sh.F)
    rep = tmp_path / "r.json"
    code = main(["unwrap", str(obj), "-o", str(tmp_path / "out.obj"), "--report", str(rep), "--quiet",
                 "--fill", "none", "--refine", "none", "--stress", "smacof"])
    assert code == 0
    r = json.loads(rep.read_text())
    assert r["parameters"]["stress"] == "smacof" and r["method"]["stress"]["method"] == "smacof"


def test_tutte_of_a_strip_with_every_vertex_on_the_border():
    """A strip of triangles has no interior vertex: nothing to solve, the circle is the embedding (a chart of the
    dragon scan's atlas failed in the factorization of an empty system)."""
    from heatparam.layout.tutte import build_disk, tutte
    from heatparam.mesh.planar import signed_areas

    x = np.arange(6, dtype=float)
    V = np.vstack([np.column_stack([x, np.zeros(6), np.zeros(6)]), np.column_stack([x, np.ones(6), x ** 2 / 10])])
    F = np.array([f for i in range(5) for f in ([i, i + 1, i + 7], [i, i + 7, i + 6])], dtype=np.int64)
    uv = tutte(V, build_disk(V, F))
    assert (signed_areas(uv[: len(V)], F) > 0).all()
