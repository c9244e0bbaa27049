"""Tests for heatparam.datasets: valid manifold meshes with exact flat layouts, and the layout-error measure."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse as sp
from matplotlib.path import Path
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull

from heatparam import datasets as S
from heatparam import metrics

DEFAULT_H = {
    "cylinder_patch": 0.04,
    "cylinder_with_holes": 0.045,
    "cone_s_strip": 0.03,
    "curved_cap_with_holes": 0.035,
    "flat_disk": 0.04,
    "flat_square": 0.035,
}
N_LOOPS = {
    "cylinder_patch": 1,
    "cylinder_with_holes": 3,
    "cone_s_strip": 1,
    "curved_cap_with_holes": 4,
    "flat_disk": 1,
    "flat_square": 1,
}
# exact areas of the smooth default domains (the meshes use inscribed chord polygons for curved borders)
AREA = {
    "cylinder_patch": 2.0 * 1.5,
    "cylinder_with_holes": 2.4 * 1.8 - 0.5 * 0.6 / 2 - np.pi * (0.3**2 + 0.35**2),
    "cone_s_strip": 2 * 1.5 * np.pi * 0.5 * 0.3,
    "curved_cap_with_holes": np.pi * 0.8 - 2 * np.pi * 0.2 * 0.096 - (0.7 * 0.1 + np.pi * 0.05**2),
    "flat_disk": np.pi,
    "flat_square": 1.5**2,
}
DEVELOPABLE = [n for n in S.SHAPES if n != "curved_cap_with_holes"]


@pytest.fixture(scope="module")
def datasets() -> dict[str, S.Shape]:
    return {name: gen() for name, gen in S.SHAPES.items()}


def flat(shape: S.Shape) -> np.ndarray:
    """The planar domain: uv_true, or for the cap the pre-lift (x, y) (lift_sphere keeps x and y)."""
    return shape.uv_true if shape.uv_true is not None else shape.V[:, :2]


def signed_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def edges(F: np.ndarray) -> np.ndarray:
    E = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    return np.unique(E, axis=0)


def angles_deg(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    P = uv[F]
    out = []
    for i in range(3):
        a, b = P[:, (i + 1) % 3] - P[:, i], P[:, (i + 2) % 3] - P[:, i]
        c = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        out.append(np.degrees(np.arccos(np.clip(c, -1, 1))))
    return np.stack(out, axis=1)


def test_registry_names(datasets):
    assert set(S.SHAPES) == set(N_LOOPS)
    for name, sh in datasets.items():
        assert sh.name == name


@pytest.mark.parametrize("name", list(S.SHAPES))
def test_arrays_and_size(datasets, name):
    sh = datasets[name]
    assert sh.V.dtype == np.float64 and sh.V.ndim == 2 and sh.V.shape[1] == 3
    assert sh.F.dtype == np.int64 and sh.F.ndim == 2 and sh.F.shape[1] == 3
    if name == "curved_cap_with_holes":
        assert sh.uv_true is None and not sh.developable
    else:
        assert sh.uv_true.dtype == np.float64 and sh.uv_true.shape == (sh.n_vertices, 2)
    assert 1500 <= sh.n_vertices <= 4000
    assert np.isfinite(sh.V).all()
    d3, d2 = metrics.diameter(sh.V), metrics.diameter(flat(sh))
    assert 1.0 <= d3 <= 3.0 and 1.0 <= d2 <= 3.2


@pytest.mark.parametrize("name", list(S.SHAPES))
def test_manifold_single_component(datasets, name):
    sh = datasets[name]
    V, F = sh.V, sh.F
    assert igl.is_edge_manifold(F)[0]
    assert np.all(igl.is_vertex_manifold(F))
    assert np.array_equal(np.unique(F), np.arange(len(V))), "unreferenced vertices"
    E = edges(F)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    assert connected_components(A, directed=False)[0] == 1
    loops = igl.boundary_loop_all(F)
    assert len(loops) == N_LOOPS[name]
    # each boundary vertex lies on exactly one loop, once (no pinched vertex with two fans)
    bverts = np.concatenate([np.asarray(lp) for lp in loops])
    assert len(np.unique(bverts)) == len(bverts)
    # consistent orientation: every directed half-edge appears once
    H = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    assert len(np.unique(H, axis=0)) == len(H)


@pytest.mark.parametrize("name", list(S.SHAPES))
def test_flat_layout_quality(datasets, name):
    sh = datasets[name]
    uv, h = flat(sh), DEFAULT_H[name]
    sa = signed_areas(uv, sh.F)
    assert sa.min() > 0.05 * h * h, "every triangle counter-clockwise, no slivers"
    assert angles_deg(uv, sh.F).min() > 20.0
    # the mesh covers the domain: no filled hole, no missing corner
    assert sa.sum() == pytest.approx(AREA[name], rel=2e-3)
    # border edges are the boundary samples (spacing <= h): recovered by Delaunay, nothing cut across
    for lp in igl.boundary_loop_all(sh.F):
        lp = np.asarray(lp)
        assert np.linalg.norm(uv[lp] - uv[np.roll(lp, -1)], axis=1).max() <= h * (1 + 1e-9)
    assert np.linalg.norm(uv[edges(sh.F)[:, 0]] - uv[edges(sh.F)[:, 1]], axis=1).max() < 2.0 * h


@pytest.mark.parametrize("name", list(S.SHAPES))
def test_3d_normals_outward(datasets, name):
    sh = datasets[name]
    P = sh.V[sh.F]
    N = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    c = P.mean(axis=1)
    if name.startswith("cylinder"):
        out = c * np.array([1.0, 0.0, 1.0])  # radial, cylinder axis = y
    elif name == "cone_s_strip":
        out = c * np.array([1.0, 1.0, 0.0])  # away from the cone axis z
    else:
        out = np.tile([0.0, 0.0, 1.0], (len(c), 1))
    assert np.all(np.sum(N * out, axis=1) > 0)


def pair_distance_3d(name: str, uv: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Exact 3D chord length between the bent images of uv[i] and uv[j], from closed formulas."""
    if name.startswith("cylinder"):
        R = 1.0
        dx, dy = uv[j, 0] - uv[i, 0], uv[j, 1] - uv[i, 1]
        return np.sqrt((2 * R * np.sin(dx / (2 * R))) ** 2 + dy**2)
    if name == "cone_s_strip":
        s = np.pi / (2 * np.pi)
        r1, r2 = np.hypot(*uv[i].T), np.hypot(*uv[j].T)
        dth = np.arctan2(uv[j, 1], uv[j, 0]) - np.arctan2(uv[i, 1], uv[i, 0])
        cos_g = s * s * np.cos(dth / s) + 1 - s * s  # angle between the two generators in 3D
        return np.sqrt(np.maximum(r1**2 + r2**2 - 2 * r1 * r2 * cos_g, 0.0))
    return np.linalg.norm(uv[j] - uv[i], axis=1)  # flat


@pytest.mark.parametrize("name", DEVELOPABLE)
def test_bending_is_exact_isometry_up_to_chords(datasets, name):
    sh = datasets[name]
    uv = sh.uv_true
    E = edges(sh.F)
    rng = np.random.default_rng(0)
    pairs = np.vstack([E, rng.integers(0, len(uv), size=(5000, 2))])
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    i, j = pairs.T
    d3 = np.linalg.norm(sh.V[j] - sh.V[i], axis=1)
    pred = pair_distance_3d(name, uv, i, j)
    np.testing.assert_allclose(d3, pred, rtol=1e-12, atol=1e-13)
    # mesh edges are chords: never longer than in the layout, and shorter by < 0.1 % at default h
    l2 = np.linalg.norm(uv[E[:, 1]] - uv[E[:, 0]], axis=1)
    short = 1 - d3[: len(E)] / l2
    assert short.min() > -1e-12
    assert short.max() < 1e-3
    if not name.startswith("flat"):
        assert short.max() > 1e-6  # really bent


def numerical_metric(f, uv: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """First fundamental form J^T J of the map f at points uv, by central differences. (n,2,2)."""
    J = np.stack(
        [(f(uv + eps * e) - f(uv - eps * e)) / (2 * eps) for e in (np.array([1.0, 0]), np.array([0, 1.0]))],
        axis=2,
    )
    return np.einsum("nki,nkj->nij", J, J)


def test_bending_maps_have_identity_metric(datasets):
    eye = np.broadcast_to(np.eye(2), (200, 2, 2))
    uv = datasets["cylinder_with_holes"].uv_true[::10][:200]
    np.testing.assert_allclose(numerical_metric(lambda p: S.bend_cylinder(p, 0.7), uv), eye, atol=1e-8)
    uv = datasets["cone_s_strip"].uv_true[::9][:200]
    for alpha in (0.5, np.pi, 5.0):
        np.testing.assert_allclose(numerical_metric(lambda p, a=alpha: S.wrap_cone(p, a), uv), eye, atol=1e-8)
    # the sphere lift is not an isometry: the same test must fail for it
    uv = datasets["flat_disk"].uv_true[::10][:200] * 0.9
    assert np.abs(numerical_metric(lambda p: S.lift_sphere(p, 2.0), uv) - eye).max() > 0.05


def test_cone_s_strip_geometry(datasets):
    sh = datasets["cone_s_strip"]
    uv = sh.uv_true
    assert uv[:, 0].min() > 0.5  # apex (origin) well outside the domain
    assert np.ptp(np.arctan2(uv[:, 1], uv[:, 0])) < np.pi  # within the developed sector
    # strongly non-convex: the domain fills little more than half of its convex hull
    assert signed_areas(uv, sh.F).sum() < 0.6 * ConvexHull(uv).volume
    # the straight segment from an arm tip to the middle of the S leaves the domain (geodesics bend)
    lp = np.asarray(igl.boundary_loop_all(sh.F)[0])
    path = Path(uv[lp])
    # centre-curve points: near the upper arm's tip (angle 0.2 on the upper arc) and the middle of the S
    tip = np.array([1.6, 0.5]) + 0.5 * np.array([np.cos(0.2), np.sin(0.2)])
    middle = np.array([1.6, 0.0])
    seg = tip + np.linspace(0, 1, 50)[:, None] * (middle - tip)
    assert path.contains_points(tip[None])[0] and path.contains_points(middle[None])[0]
    assert not path.contains_points(seg).all()


def test_flat_shapes_are_planar(datasets):
    for name in ("flat_disk", "flat_square"):
        sh = datasets[name]
        assert np.array_equal(sh.V[:, :2], sh.uv_true) and np.all(sh.V[:, 2] == 0)


def test_cap_is_curved(datasets):
    sh = datasets["curved_cap_with_holes"]
    r2 = np.sum(sh.V[:, :2] ** 2, axis=1)
    np.testing.assert_allclose(np.sum((sh.V - [0, 0, -4.0]) ** 2, axis=1), 16.0, rtol=1e-12)
    assert np.ptp(sh.V[:, 2]) > 0.05 and r2.max() < 1.0 + 1e-12


def test_deterministic():
    for gen in S.SHAPES.values():
        a, b = gen(h=0.08), gen(h=0.08)
        assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F)


@pytest.mark.parametrize("name", list(S.SHAPES))
@pytest.mark.parametrize("h", [0.021, 0.06, 0.11])
def test_other_resolutions_valid(name, h):
    sh = S.SHAPES[name](h=h)
    assert igl.is_edge_manifold(sh.F)[0] and np.all(igl.is_vertex_manifold(sh.F))
    assert len(igl.boundary_loop_all(sh.F)) == N_LOOPS[name]
    assert signed_areas(flat(sh), sh.F).min() > 0
    assert angles_deg(flat(sh), sh.F).min() > 15.0


def test_mesh_domain_boundary_segments_are_edges():
    h = 0.1
    outer = S.polygon(np.array([[0, 0], [2, 0], [2, 1], [0, 1]]), h)
    hole = S.circle((1.0, 0.5), 0.25, h, clockwise=True)
    uv, F = S.mesh_domain([outer, hole], h)
    index = {tuple(p): k for k, p in enumerate(uv.tolist())}
    E = {tuple(e) for e in edges(F).tolist()}
    for lp in (outer, hole):
        ids = np.array([index[tuple(p)] for p in lp.tolist()])
        for a, b in zip(ids, np.roll(ids, -1), strict=True):
            assert (min(a, b), max(a, b)) in E


def test_mesh_domain_recovers_thin_notch():
    # a 3.6-degree V notch: Delaunay alone misses border segments, splitting them must recover them
    h = 0.05
    corners = np.array([[0, 0], [1, 0], [1.0, 0.8], [1.05, 0], [2, 0], [2, 1], [0, 1]], dtype=float)
    outer = S.polygon(corners, h)
    with pytest.raises(RuntimeError, match="boundary segments"):
        S.mesh_domain([outer], h, max_refine=0)
    uv, F = S.mesh_domain([outer], h)
    assert igl.is_edge_manifold(F)[0] and np.all(igl.is_vertex_manifold(F))
    assert signed_areas(uv, F).min() > 0
    assert signed_areas(uv, F).sum() == pytest.approx(2.0 - 0.5 * 0.05 * 0.8, rel=1e-12)
    lp = np.asarray(igl.boundary_loop(F))
    assert len(lp) > len(outer)  # split segments
    perimeter = np.sum(np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1))
    assert np.linalg.norm(uv[lp] - uv[np.roll(lp, -1)], axis=1).sum() == pytest.approx(perimeter, rel=1e-12)


def test_scale_shape(datasets):
    sh = datasets["cylinder_patch"]
    big = S.scale_shape(sh, 2.5)
    np.testing.assert_array_equal(big.V, 2.5 * sh.V)
    np.testing.assert_array_equal(big.uv_true, 2.5 * sh.uv_true)
    assert np.array_equal(big.F, sh.F) and big.name == sh.name
    assert metrics.layout_error(big.uv_true, sh.uv_true) > 0.1
    cap = S.scale_shape(datasets["curved_cap_with_holes"], 0.5)
    assert cap.uv_true is None and np.array_equal(cap.V, 0.5 * datasets["curved_cap_with_holes"].V)
