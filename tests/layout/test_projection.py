"""The mean-plane projection, a start for height-field-like parts (``layout.projection``) and its judging as a
start (``refine.start``)."""

import numpy as np

from heatparam import datasets, metrics
from heatparam.atlas.repair import repair
from heatparam.layout.projection import projection_layout
from heatparam.layout.tutte import build_disk
from heatparam.mesh.planar import signed_areas
from heatparam.mesh.topology import face_areas
from heatparam.refine import energy, start
from heatparam.refine.scaffold import build_scaffold


def _rotation(seed: int) -> np.ndarray:
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_a_tilted_plane_projects_to_an_isometry():
    s = datasets.flat_disk()
    V = s.V @ _rotation(1).T + [3.0, -2.0, 5.0]
    uv = projection_layout(V, s.F)
    g, area = energy.surface_gradients(V, s.F)
    assert (signed_areas(uv, s.F) > 0).all()
    assert energy.normalized_energy(uv, s.F, g, area) - 1.0 < 1e-12


def test_a_cap_with_holes_projects_bijectively_at_its_area():
    s = datasets.curved_cap_with_holes()
    V = s.V @ _rotation(2).T
    uv = projection_layout(V, s.F)
    assert (signed_areas(uv, s.F) > 0).all()
    assert metrics.boundary_crossings(uv, s.F) == 0 and metrics.inverted_loops(uv, s.F) == 0
    assert np.isclose(signed_areas(uv, s.F).sum(), face_areas(V, s.F).sum())


def test_no_mean_plane_gives_none():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [0, 1, 0], [1, 0, 0]])
    assert projection_layout(V, np.array([[0, 1, 2], [3, 4, 5]])) is None


def test_start_rejects_a_projection_that_folds():
    s = datasets.cylinder_patch(angle=4.5)  # rolled past a half turn: not a height field over any plane
    g, area = energy.surface_gradients(s.V, s.F)
    x, rep = start.choose_start(s.V, s.F, None, build_disk(s.V, s.F), g, area, None, None, "auto")
    assert rep["projection"]["flips"] > 0 and rep["layout"] != "projection"
    assert start.bijectivity(x, s.F, g) == (0, 0)


def _pinched_grid() -> tuple[np.ndarray, np.ndarray]:
    """A 3×3 grid of squares on a tilted plane without its corner square (0, 0) and its centre (1, 1): the vertex
    they share is a bowtie, which the atlas's repair splits into two copies at one point."""
    n = 4
    P = np.array([[i, j, 0.0] for j in range(n) for i in range(n)])
    F = []
    for j in range(n - 1):
        for i in range(n - 1):
            if (i, j) in ((0, 0), (1, 1)):
                continue
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            F += [[a, b, c], [a, c, d]]
    return P @ _rotation(3).T, np.array(F)


def test_split_vertex_copies_are_pushed_apart_so_the_scaffold_can_be_built():
    comp = repair(*_pinched_grid()).components[0]
    V, F = comp.V, comp.F
    disk = build_disk(V, F)
    g, area = energy.surface_gradients(V, F)
    raw = projection_layout(V, F)
    bnd = np.concatenate(disk.loops)
    assert len(np.unique(raw[bnd], axis=0)) < len(bnd)  # the two copies project onto one point
    x, rep = start.choose_start(V, F, None, disk, g, area, None, None, "auto")
    assert rep["layout"] == "projection" and rep["projection"]["separated"] == 2
    assert len(np.unique(x[bnd], axis=0)) == len(bnd) and start.bijectivity(x, F, g) == (0, 0)
    build_scaffold(x, disk.loops)  # raises when boundary points touch
