"""``mesh.validate_mesh``, case by case: every refusal with its one-line message, and the facts it reports."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam.errors import MeshError
from heatparam.mesh import NEARLY_CLOSED_RATIO, validate_mesh

from conftest import flat_disk

SQUARE_V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])


def _tetra():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    return V, F


def _refused(V, F, fragment: str, **kw):
    with pytest.raises(MeshError) as e:
        validate_mesh(np.asarray(V, dtype=float), np.asarray(F), **kw)
    msg = str(e.value)
    assert fragment in msg and "\n" not in msg, msg
    return msg


def test_a_square_passes_with_its_facts():
    info = validate_mesh(SQUARE_V, SQUARE_F)
    assert (info.n_vertices, info.n_faces, info.n_holes, info.zero_area_faces) == (4, 2, 0, 0)
    assert info.area == pytest.approx(1.0) and info.mean_edge == pytest.approx((4 + 2 * 2**0.5) / 6)
    assert info.diameter == pytest.approx(2**0.5) and sorted(info.boundary_loops[0].tolist()) == [0, 1, 2, 3]
    assert info.warnings == [] and info.referenced.all()


def test_shapes_and_empty_faces():
    _refused(np.zeros((2, 3)), SQUARE_F[:0], "expected at least 3 vertices")
    _refused(np.zeros((4, 2)), SQUARE_F, "expected at least 3 vertices")
    _refused(SQUARE_V, np.zeros((0, 3), int), "no triangles")


def test_non_finite_coordinates_name_the_first_vertex():
    V = SQUARE_V.copy()
    V[2, 1] = np.nan
    assert "vertex 2" in _refused(V, SQUARE_F, "NaN or infinite")


def test_indices_out_of_range_and_repeated_corners():
    _refused(SQUARE_V, np.array([[0, 1, 4], [0, 2, 3]]), "out of range")
    _refused(SQUARE_V, np.array([[0, 1, -1], [0, 2, 3]]), "out of range")
    _refused(SQUARE_V, np.array([[0, 1, 1], [0, 2, 3]]), "repeat a vertex index")


def test_non_manifold_edge():
    V = np.vstack([SQUARE_V, [[0.5, 0.5, 1.0]]])
    _refused(V, np.array([[0, 1, 2], [0, 2, 3], [0, 4, 2]]), "non-manifold edges")


def test_inconsistent_orientation():
    _refused(SQUARE_V, np.array([[0, 1, 2], [0, 3, 2]]), "inconsistently")


def test_bowtie_vertex():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]])
    _refused(V, np.array([[0, 1, 2], [0, 3, 4]]), "non-manifold vertices")


def test_several_components():
    V = np.vstack([SQUARE_V, SQUARE_V + [3, 0, 0]])
    _refused(V, np.vstack([SQUARE_F, SQUARE_F + 4]), "2 connected components")


def test_closed_refused_for_flattening_but_accepted_for_operators():
    V, F = _tetra()
    _refused(V, F, "closed mesh")
    info = validate_mesh(V, F, flatten=False)
    assert info.boundary_loops == [] and info.n_holes == 0


def test_nearly_closed_refused():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2)
    V, F = np.asarray(sphere.vertices), np.asarray(sphere.faces)[1:]  # one small hole
    closure_msg = _refused(V, F, "nearly closed")
    assert f"< {NEARLY_CLOSED_RATIO}" in closure_msg
    assert validate_mesh(V, F, flatten=False).n_holes == 0  # one loop: fine for distances


def test_handle_refused():
    # a flat annulus glued into a torus-like strip would be closed; a cylinder band with a slit has genus 0. A
    # torus with a hole punched: genus 1 with one border.
    n, k = 12, 8
    u, v = np.meshgrid(np.arange(n), np.arange(k), indexing="ij")
    a, b = 2 * np.pi * u / n, 2 * np.pi * v / k
    V = np.column_stack([((3 + np.cos(b)) * np.cos(a)).ravel(), ((3 + np.cos(b)) * np.sin(a)).ravel(),
                         np.sin(b).ravel()])
    idx = lambda i, j: (i % n) * k + (j % k)  # noqa: E731
    F = []
    for i in range(n):
        for j in range(k):
            F += [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)], [idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]]
    F = np.array(F[2:])  # punch a hole (drop one quad)
    _refused(V, F, "handle")


def test_unreferenced_vertices_and_zero_area_faces_are_warnings():
    V, F = flat_disk(6)
    V = np.vstack([V, [[5.0, 5.0, 0.0]]])  # a loose point
    info = validate_mesh(V, F)
    assert info.n_unreferenced == 1 and not info.referenced[-1]
    assert any("unreferenced" in w for w in info.warnings)
    # a sliver of zero area: a vertex on the segment between two others
    V2 = np.array([[0.0, 0, 0], [2, 0, 0], [1, 0, 0], [1, 1, 0]])
    info2 = validate_mesh(V2, np.array([[0, 2, 3], [2, 1, 3], [0, 1, 2]])[:2])
    assert info2.zero_area_faces == 0
    V3 = np.array([[0.0, 0, 0], [2, 0, 0], [1, 1e-9, 0], [1, 1, 0]])
    info3 = validate_mesh(V3, np.array([[0, 2, 3], [2, 1, 3], [0, 1, 2]]))
    assert info3.zero_area_faces == 0  # thin but not zero at 1e-14 of its longest edge²
    V4 = V3.copy()
    V4[2, 1] = 0.0
    info4 = validate_mesh(V4, np.array([[0, 2, 3], [2, 1, 3], [0, 1, 2]]))
    assert info4.zero_area_faces == 1 and any("zero-area" in w for w in info4.warnings)
