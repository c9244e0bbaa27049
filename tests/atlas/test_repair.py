"""Lossless repair of scan-like input (bowties, non-manifold edges, slivers, islands, loose points) and the
atlas of such input, of several components, and of a nearly closed surface."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from heatparam import datasets
from heatparam.atlas.overlap import count_overlaps, uv_degenerate_faces
from heatparam.atlas.repair import half_edge_opposites, repair, union
from heatparam.errors import MeshError
from heatparam.mesh.topology import degenerate_faces
from heatparam.metrics import distortion
from heatparam.pipeline import atlas_stage, parameterize_disk

atlas = partial(atlas_stage.atlas, flatten_disk=parameterize_disk)


def scan_like(seed: int = 0) -> tuple[np.ndarray, np.ndarray, dict]:
    """A noisy height-field patch with a bowtie fan, a fin on an edge (3 faces), a row of slivers, two islands,
    a face of inconsistent orientation and loose points. Returns V, F and the counts built in."""
    rng = np.random.default_rng(seed)
    n = 14
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    x[:, 7] = x[:, 6] + 1e-3  # slivers: a column of points almost on the previous one
    x = x.copy()
    y = y.copy()
    y[7, :] = y[6, :] + 2e-3
    V = np.column_stack([x.ravel(), y.ravel(), 0.05 * np.sin(3 * x.ravel()) + rng.normal(0, 0.004, n * n)])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    F = np.concatenate([np.stack([a, a + n, a + n + 1], 1), np.stack([a, a + n + 1, a + 1], 1)])
    # a bowtie: a triangle fan touching the patch only at its corner vertex 0
    k = len(V)
    V = np.vstack([V, [[-0.2, -0.05, 0.0], [-0.05, -0.2, 0.0]]])
    F = np.vstack([F, [[0, k, k + 1]]])
    # a fin: a third face on an interior edge of the patch
    e0, e1 = F[40, 0], F[40, 1]
    V = np.vstack([V, [[V[e0, 0], V[e0, 1], 0.3]]])
    F = np.vstack([F, [[e0, e1, len(V) - 1]]])
    # islands: a quad and a single triangle, the quad's second face with reversed orientation
    b = len(V)
    V = np.vstack([V, [[2, 0, 0], [2.2, 0, 0], [2.2, 0.2, 0], [2, 0.2, 0], [3, 0, 0], [3.1, 0, 0], [3, 0.1, 0]]])
    F = np.vstack([F, [[b, b + 1, b + 2], [b, b + 3, b + 2], [b + 4, b + 5, b + 6]]])
    # loose points
    V = np.vstack([V, [[5, 5, 5], [6, 6, 6]]])
    return V.astype(np.float64), F.astype(np.int64), {"loose": 2}


def test_scan_like_is_refused_by_the_single_map_and_repaired_losslessly():
    V, F, built = scan_like()
    with pytest.raises(MeshError):  # a single flattening refuses it (heatparam.parameterize makes an atlas)
        parameterize_disk(V, F)
    rep = repair(V, F)
    assert len(rep.loose_points) == built["loose"]
    assert rep.split_vertices >= 1 and rep.cut_edges >= 2  # bowtie vertex; fin edge and reversed island edge
    faces = np.concatenate([c.faces for c in rep.components])
    assert np.array_equal(np.sort(faces), np.arange(len(F)))  # every face exactly once
    for c in rep.components:
        np.testing.assert_array_equal(c.vertex[c.F], F[c.faces])  # same corners, geometry unchanged
        np.testing.assert_array_equal(c.V, V[c.vertex])
        np.testing.assert_array_equal(c.zero_area, degenerate_faces(c.V, c.F))  # the repair's, face for face
    np.testing.assert_array_equal(rep.degenerate, degenerate_faces(V, F))
    np.testing.assert_array_equal(rep.opp, half_edge_opposites(F))


def test_scan_like_atlas():
    V, F, built = scan_like()
    res = atlas(V, F)
    assert res.Fuv.shape == F.shape and (res.Fuv >= 0).all()
    np.testing.assert_array_equal(res.uv_vertex[res.Fuv], F)
    d = distortion(V, F, res.uv, res.Fuv)
    assert d["flips"] == 0
    assert count_overlaps(res.uv, res.Fuv) == 0
    assert not uv_degenerate_faces(res.uv, res.Fuv).any()
    rep = res.report
    assert rep["repair"]["loose_points"] == built["loose"]
    assert len(rep["tiny_components"]) >= 3  # bowtie fan, fin, islands: reported, and charted
    assert sum(c["faces"] for c in rep["charts"]) == len(F)


def test_several_components_and_nearly_closed():
    V1, F1 = datasets.closed_cube(n=4)
    V2, F2 = datasets.capped_cylinder(n_theta=24, n_z=8, rings=3)
    V2 = V2 + [3.0, 0, 0]
    # nearly closed: the cylinder with two faces removed (a small hole)
    F2 = F2[2:]
    V = np.vstack([V1, V2])
    F = np.vstack([F1, F2 + len(V1)])
    with pytest.raises(MeshError):  # a single flattening refuses it (heatparam.parameterize makes an atlas)
        parameterize_disk(V, F)
    with pytest.raises(MeshError, match="nearly closed"):
        parameterize_disk(V2, F2)
    res = atlas(V, F)
    assert res.report["repair"]["components"] == 2
    d = distortion(V, F, res.uv, res.Fuv)
    assert d["flips"] == 0 and count_overlaps(res.uv, res.Fuv) == 0
    assert d["iso_mean"] <= 1.05
    assert set(np.unique(res.chart[: len(F1)])).isdisjoint(np.unique(res.chart[len(F1):]))


def test_scan_like_atlas_obj_round_trip(tmp_path):
    from heatparam.formats import load_uv_obj, save_uv_obj

    V, F, _ = scan_like()
    res = atlas(V, F)
    path = tmp_path / "a.obj"
    save_uv_obj(path, V, F, res.uv, Fuv=res.Fuv)
    V2, F2, UV2, FUV2 = load_uv_obj(path)
    np.testing.assert_array_equal(V2, V)  # loose points and split vertices kept: v unchanged
    np.testing.assert_array_equal(F2, F)
    np.testing.assert_array_equal(UV2[FUV2], res.uv[res.Fuv])


def test_union_of_components_keeps_every_face_and_its_owner():
    """``union``: the tiny components as one part, each face's corners unchanged and its component id kept."""
    V, F, _ = scan_like()
    rep = repair(V, F)
    ids = [1, 2, 3]
    part, owner = union([rep.components[i] for i in ids], ids)
    np.testing.assert_array_equal(part.vertex[part.F], F[part.faces])
    np.testing.assert_array_equal(part.zero_area, degenerate_faces(part.V, part.F))
    np.testing.assert_array_equal(owner, np.repeat(ids, [len(rep.components[i].F) for i in ids]))


def test_a_component_of_zero_area_faces_is_kept_a_mesh_of_them_refused():
    V, F = datasets.closed_cube(n=2)
    line = np.array([[3.0, 0, 0], [4, 0, 0], [5, 0, 0]])
    rep = repair(np.vstack([V, line]), np.vstack([F, [[len(V), len(V) + 2, len(V) + 1]]]))
    assert len(rep.components) == 2 and len(rep.components[1].F) == 1
    with pytest.raises(MeshError, match="all faces have zero area") as exc:
        repair(line, np.array([[0, 2, 1]]))
    assert "—" in str(exc.value)  # and what to do
