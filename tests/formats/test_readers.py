"""The tolerant readers (formats/readers.py), here PLY as users have it (issue 45): faces under either index name,
polygons, triangle strips with restarts in either byte order, float or double, extra properties, point clouds."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from heatparam import datasets, formats
from heatparam.errors import HeatparamError
from heatparam.formats.readers import strip_triangles

from hostile import leaked, ply_bytes

FORMATS = ["ascii", "binary_little_endian", "binary_big_endian"]


def _grid_strips(nx: int, ny: int) -> tuple[np.ndarray, list, np.ndarray]:
    """A flat nx × ny vertex grid as one triangle strip per row of quads (the Stanford / VCG way, with a -1 restart
    between rows in one list), and the same triangles as faces, counter-clockwise: V, [strip], F."""
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(nx * ny)])
    strip, F = [], []
    for j in range(ny - 1):
        for i in range(nx):
            strip += [(j + 1) * nx + i, j * nx + i]  # zig-zag: a, b, c, d ... along the row
        strip.append(-1)
        for i in range(nx - 1):
            a, b, c, d = j * nx + i, (j + 1) * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1
            F += [[b, a, d], [d, a, c]]
    return V, [strip[:-1]], np.array(F)


def test_strip_triangles_alternate_and_drop_swaps():
    # a, b, c, d, e: (a,b,c), (c,b,d), (c,d,e); then a restart; then a swap (a repeated index) that is dropped
    T = strip_triangles([[0, 1, 2, 3, 4, -1, 5, 6, 7, 7, 8]])
    assert T.tolist() == [[0, 1, 2], [2, 1, 3], [2, 3, 4], [5, 6, 7]]  # (6,7,7), (7,7,8) are swaps
    assert strip_triangles([[0, 1]]).shape == (0, 3)
    assert strip_triangles([[0, 1, 2], [3, 4, 5, 6]]).tolist() == [[0, 1, 2], [3, 4, 5], [5, 4, 6]]  # one per row


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("vtype", ["float", "double"])
def test_tristrips_ply_reads_as_consistently_oriented_triangles(tmp_path, fmt, vtype):
    """A binary PLY of 134k vertices whose faces are an ``element tristrips`` was refused as holding no triangles."""
    V, strips, F = _grid_strips(6, 4)
    p = tmp_path / "strips.ply"
    p.write_bytes(ply_bytes(V, strips=strips, fmt=fmt, vtype=vtype))
    V2, F2 = formats.load_mesh(p)
    assert np.array_equal(V2, V)
    assert sorted(map(tuple, np.sort(F2, axis=1).tolist())) == sorted(map(tuple, np.sort(F, axis=1).tolist()))
    e1, e2 = V2[F2[:, 1]] - V2[F2[:, 0]], V2[F2[:, 2]] - V2[F2[:, 0]]
    assert (np.cross(e1, e2)[:, 2] > 0).all()  # every triangle turns the same way: the strip's flips undone


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("index_name", ["vertex_indices", "vertex_index"])
def test_faces_under_either_name_with_extra_properties(tmp_path, fmt, index_name):
    s = datasets.cylinder_patch(h=0.3)
    p = tmp_path / "m.ply"
    p.write_bytes(ply_bytes(s.V, faces=s.F.tolist(), fmt=fmt, index_name=index_name))
    V2, F2 = formats.load_mesh(p)
    assert np.array_equal(V2, s.V.astype(np.float32)) and np.array_equal(F2, s.F)


@pytest.mark.parametrize("fmt", FORMATS)
def test_polygons_fan_triangulated_in_trimeshs_order(tmp_path, fmt):
    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [0, 1, 0], [1, 2, 0], [0, 2, 0]])
    polys = [[0, 1, 4, 5], [1, 2, 3], [1, 3, 4], [5, 4, 6, 7]]
    p, a = tmp_path / "q.ply", tmp_path / "ascii.ply"
    p.write_bytes(ply_bytes(V, faces=polys, fmt=fmt, extra=False))
    a.write_bytes(ply_bytes(V, faces=polys, extra=False))  # (trimesh reads mixed polygons from ASCII only)
    _, F = formats.load_mesh(p)
    ref = trimesh.load(a, process=False, maintain_order=True)
    assert np.array_equal(F, np.asarray(ref.faces))  # the maps of PLY meshes were made with trimesh's order


def test_faces_and_strips_together(tmp_path):
    V, strips, F = _grid_strips(3, 3)
    p = tmp_path / "both.ply"
    p.write_bytes(ply_bytes(V, faces=F[:2].tolist(), strips=strips, fmt="binary_little_endian"))
    _, F2 = formats.load_mesh(p)
    assert np.array_equal(F2[:2], F[:2]) and len(F2) == 2 + len(F)


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("faces", [None, []])
def test_point_cloud_refused_with_what_to_do(tmp_path, fmt, faces):
    p = tmp_path / "cloud.ply"
    p.write_bytes(ply_bytes(np.random.default_rng(0).random((50, 3)), faces=faces, fmt=fmt))
    with pytest.raises(HeatparamError) as exc:
        formats.load_mesh(p)
    assert str(exc.value) == f"{p}: no faces: a point cloud; mesh it first, e.g. by Poisson reconstruction"


@pytest.mark.parametrize("data,expect", [
    (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
     b"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n", "truncated or corrupt"),
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n", "no x, y, z"),
    (b"ply\nformat ascii 1.0\nelement point 1\nproperty float x\nend_header\n0\n", "no 'vertex' element"),
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quaternion x\nend_header\n0\n", "malformed PLY header"),
    (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n" + bytes(36) + b"\x02"
     + bytes(8), "at least 3 corners"),
    (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
     b"element face 1\nproperty list uchar int idx\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "no 'vertex_indices'"),
])
def test_bad_ply_files_one_line(tmp_path, data, expect):
    p = tmp_path / "bad.ply"
    p.write_bytes(data)
    with pytest.raises(HeatparamError) as exc:
        formats.load_mesh(p)
    msg = str(exc.value)
    assert expect in msg and str(p) in msg and "\n" not in msg, msg


_MESHLAB_HEADER = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                   b"element face 2\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\n"
                   b"property uchar red\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n")


def test_ascii_rows_longer_than_the_header_read_one_per_line(tmp_path):
    # MeshLab (VCG) writes face rows with more fields than the header declares: the extras are ignored
    p = tmp_path / "vcg.ply"
    p.write_bytes(_MESHLAB_HEADER + b"3 0 1 2 6 0.5 0.25 0.5 0.5 0.25 0.5 9 1 1 1 1\n"
                                    b"3 0 2 3 6 0.5 0.25 0.5 0.5 0.25 0.5 9 1 1 1 1\n")
    V, F = formats.load_mesh(p)
    assert V.shape == (4, 3) and F.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_capital_magic_word_and_crlf_lines(tmp_path):
    # Rhino's PLY: 'PLY' and CRLF line ends
    p = tmp_path / "rhino.ply"
    p.write_bytes(b"PLY\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n"
                  b"property float z\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n"
                  b"0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n")
    V, F = formats.load_mesh(p)
    assert V.shape == (3, 3) and F.tolist() == [[0, 1, 2]]


def test_corrupt_numbers_named_without_python_text(tmp_path):
    p = tmp_path / "junk.ply"
    p.write_bytes(_MESHLAB_HEADER + b"3 0 1 x 0 7\n3 0 2 3 0 7\n")
    with pytest.raises(HeatparamError) as exc:
        formats.load_mesh(p)
    msg = str(exc.value)
    assert "'face' element is truncated or corrupt" in msg and not leaked(msg) and "invalid literal" not in msg, msg


def test_obj_two_corner_faces_are_edges_and_skipped(tmp_path):
    # exporters write loose edges as 'f a b' (pybullet's samurai_monastry.obj): the faces around them are the mesh
    p = tmp_path / "edges.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1// 2//\nf 1 3 4\nl 1 3\n")
    V, F = formats.load_mesh(p)
    assert len(V) == 4 and F.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_obj_of_lines_only_is_a_wireframe_not_a_point_cloud(tmp_path):
    p = tmp_path / "wire.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2 3\nf 3 1\n")
    with pytest.raises(HeatparamError) as exc:
        formats.load_mesh(p)
    msg = str(exc.value)
    assert "no faces, only lines or curves (2): a wireframe" in msg and "point cloud" not in msg, msg


def test_off_counts_written_against_the_header(tmp_path):
    # trimesh's whitespace.off: 'OFF8 6 12', tabs, polygons with colours after the indices
    p = tmp_path / "glued.off"
    p.write_text("\t  OFF4 2 0 # a comment\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n 3  0 1 2  1.0 0.0 0.0\n3 0 2 3\n")
    V, F = formats.load_mesh(p)
    assert V.shape == (4, 3) and F.tolist() == [[0, 1, 2], [0, 2, 3]]
