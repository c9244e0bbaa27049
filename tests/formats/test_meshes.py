import numpy as np
import pytest
import trimesh

from heatparam import datasets, formats
from heatparam.errors import HeatparamError
from heatparam.formats import meshes

from conftest import shared_mesh


@pytest.fixture(scope="module")
def mesh():
    sh = datasets.cylinder_patch(h=0.1)
    return sh.V, sh.F


@pytest.mark.parametrize("suffix", [".ply", ".glb", ".stl", ".off"])
def test_formats_keep_vertex_order(tmp_path, mesh, suffix):
    V, F = mesh
    p = tmp_path / f"m{suffix}"
    trimesh.Trimesh(V, F, process=False).export(p)
    V2, F2 = formats.load_mesh(p)
    tol = 1e-6 if suffix in (".ply", ".glb", ".stl") else 1e-9  # float32 / trimesh's OFF text precision
    assert V2.shape == V.shape
    if suffix == ".stl":  # STL has no shared vertices: corners are merged, numbered in order of appearance
        assert np.abs(V2[F2] - V[F]).max() < tol
    else:
        assert np.abs(V2 - V).max() < tol and np.array_equal(F2, F)


def test_obj_round_trip_exact(tmp_path, mesh):
    V, F = mesh
    uv = V[:, :2] * 1.5
    p = tmp_path / "m.obj"
    formats.save_uv_obj(p, V, F, uv)
    V2, F2 = formats.load_mesh(p)
    assert np.array_equal(V2, V) and np.array_equal(F2, F)  # bit-exact (repr round trip)
    V3, F3, UV, FUV = formats.load_uv_obj(p)
    assert np.array_equal(UV, uv) and np.array_equal(FUV, F)


def test_obj_with_seams_round_trip(tmp_path, mesh):
    """A map with seams: vt rows per seam side, f v/vt with different indices; v and F unchanged."""
    V, F = mesh
    Fuv = np.arange(F.size).reshape(F.shape)[::-1].copy()  # one vt per corner, in another order
    uv = np.random.default_rng(0).random((F.size, 2))
    p = tmp_path / "s.obj"
    formats.save_uv_obj(p, V, F, uv, Fuv=Fuv)
    V2, F2, UV, FUV = formats.load_uv_obj(p)
    assert np.array_equal(V2, V) and np.array_equal(F2, F)
    assert np.array_equal(UV, uv) and np.array_equal(FUV, Fuv)


def test_quads_and_polygons_triangulated(tmp_path):
    p = tmp_path / "q.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3\n")
    V, F = formats.load_mesh(p)
    assert len(V) == 6 and F.shape == (4, 3)
    off = tmp_path / "q.off"
    off.write_text("OFF\n5 1 0\n0 0 0\n1 0 0\n1.5 1 0\n0.5 1.5 0\n-0.5 1 0\n5 0 1 2 3 4\n")
    V, F = formats.load_mesh(off)
    assert len(V) == 5 and F.shape == (3, 3)


def test_public_quad_off_loads():
    V, F = formats.load_mesh(shared_mesh("halftunnel.off"))  # its faces are quads
    assert V.shape == (831, 3) and F.shape == (1568, 3)


def test_atomic_write_keeps_old_file_on_failure(tmp_path):
    p = tmp_path / "out.json"
    p.write_text("old")
    with pytest.raises(RuntimeError), formats.atomic_write(p) as fh:
        fh.write("half")
        raise RuntimeError("boom")
    assert p.read_text() == "old" and len(list(tmp_path.iterdir())) == 1


def test_missing_folder_is_one_line_error(tmp_path):
    with pytest.raises(HeatparamError, match="does not exist"):
        formats.save_json(tmp_path / "nope" / "r.json", {})


def test_uv_obj_without_vt_rejected(tmp_path):
    p = tmp_path / "novt.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(HeatparamError, match="texture"):
        formats.load_uv_obj(p)


@pytest.mark.parametrize("body", [
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nf 1 2 3\nf 2 4 3\n",
    "# c\nmtllib x.mtl\no part\nv 0 0 0\nv 1.5e-3 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nvn 0 0 1\n"
    "vn 0 0 1\ng a\ns off\nusemtl m\nf 1/1/1 2/2/2 3/3/3\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1//1 2//1 3//1\nf 2 4 3\n",
])
def test_plain_obj_fast_path_equals_meshio(tmp_path, body):
    p = tmp_path / "m.obj"
    p.write_text(body)
    V1, F1 = meshes.load_obj_fast(p)
    V2, F2 = meshes.load_meshio(p)
    assert V1.dtype == V2.dtype and F1.dtype == F2.dtype
    assert np.array_equal(V1, V2) and np.array_equal(F1, F2)


@pytest.mark.parametrize("body", [
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",  # quad
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",  # relative indices
    "v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n",  # homogeneous coordinate
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nf 1 2 3\n",  # another statement
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n  f 1 2 3\n",  # odd whitespace
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",  # fewer vt than v: meshio fails, trimesh reads it
])
def test_other_objs_left_to_meshio(tmp_path, body):
    p = tmp_path / "m.obj"
    p.write_text(body)
    with pytest.raises(meshes.NotSimpleObj):
        meshes.load_obj_fast(p)


def test_large_obj_fast_path_exact(tmp_path):
    rng = np.random.default_rng(1)
    V = rng.standard_normal((500, 3)) * 10.0 ** rng.integers(-8, 8, (500, 1))
    F = rng.integers(0, 500, (900, 3))
    p = tmp_path / "m.obj"
    formats.save_uv_obj(p, V, F, rng.random((500, 2)))
    V2, F2 = formats.load_mesh(p)
    assert np.array_equal(V2, V) and np.array_equal(F2, F)
    assert np.array_equal(V2, meshes.load_meshio(p)[0]) and np.array_equal(F2, meshes.load_meshio(p)[1])


@pytest.mark.parametrize("name, text, index", [
    ("short.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n", 3),
    ("short.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", 3),
])
def test_a_face_beyond_the_vertices_is_named_with_the_file(tmp_path, name, text, index):
    (tmp_path / name).write_text(text)
    with pytest.raises(HeatparamError, match=rf"cannot read .*{name}: face 1 uses vertex index {index}, out of range"):
        formats.load_mesh(tmp_path / name)
