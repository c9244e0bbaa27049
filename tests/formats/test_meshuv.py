"""PLY and GLB with the map as texture coordinates, re-read with trimesh: the same UVs, positions and faces."""

import json
import struct

import numpy as np
import pytest
import trimesh

from heatparam.cli import main

from formats_cases import cylinder_map, halftunnel_map, write_off


@pytest.mark.parametrize("case", ["cylinder", "halftunnel"])
def test_ply_and_glb_round_trip(tmp_path, case):
    """One vertex per uv row (seam sides apart on halftunnel), faces = Fuv. PLY is exact (float64); GLB stores
    float32 (glTF), so UVs agree to float32 rounding of their magnitude."""
    m = cylinder_map() if case == "cylinder" else halftunnel_map()
    src = write_off(tmp_path / "in.off", m.V, m.F)
    ply, glb = tmp_path / "m.ply", tmp_path / "m.glb"
    assert main(["unwrap", str(src), "-o", str(ply), "-o", str(glb), "--units", "cm", "--quiet"]) == 0
    for path, tol in ((ply, 0.0), (glb, 4 * np.finfo(np.float32).eps)):
        r = trimesh.load(path, process=False, force="mesh")
        scale = np.abs(m.uv).max()
        assert r.visual.uv.shape == m.uv.shape
        assert np.abs(r.visual.uv - m.uv).max() <= tol * scale
        assert np.abs(r.vertices - m.V[m.uv_vertex]).max() <= tol * np.abs(m.V).max()
        assert np.array_equal(r.faces, m.Fuv)
    if case == "halftunnel":
        assert len(m.uv) > len(m.V)  # the seams really split vertices
    header = ply.read_bytes().split(b"end_header")[0].decode()
    assert "comment units cm" in header and "property double s" in header


def test_glb_units_and_checker(tmp_path):
    """The GLB states its units in the scene extras, has a checker texture and scales it with
    KHR_texture_transform (a viewer shows about 16 cells across the part)."""
    m = cylinder_map()
    src = write_off(tmp_path / "in.off", m.V, m.F)
    glb = tmp_path / "m.glb"
    assert main(["unwrap", str(src), "-o", str(glb), "--units", "in", "--quiet"]) == 0
    data = glb.read_bytes()
    magic, _, length = struct.unpack_from("<III", data)
    assert magic == 0x46546C67 and length == len(data)
    jlen, jtype = struct.unpack_from("<II", data, 12)
    assert jtype == 0x4E4F534A and jlen % 4 == 0
    gltf = json.loads(data[20:20 + jlen])
    assert gltf["scenes"][0]["extras"]["units"] == "in"
    assert "KHR_texture_transform" in gltf["extensionsUsed"]
    info = gltf["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
    s = info["extensions"]["KHR_texture_transform"]["scale"][0]
    cells = np.ptp(m.uv, axis=0).max() * 2 * s
    assert 6 < cells < 40
    scene = trimesh.load(glb, process=False)
    assert scene.metadata["units"] == "in"
    img = next(iter(scene.geometry.values())).visual.material.baseColorTexture
    assert len(set(np.asarray(img.convert("RGB")).reshape(-1, 3).view("u1,u1,u1").ravel().tolist())) == 2
