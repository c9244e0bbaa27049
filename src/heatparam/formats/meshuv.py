"""Meshes with the map as texture coordinates: PLY and GLB.

Both hold one vertex per uv row (position ``V[uv_vertex[k]]``, texture coordinate ``uv[k]``) and the faces
``Fuv``, so a map with seams keeps one vertex per seam side; UVs are the true-scale map in model units, as in the
OBJ.

- PLY: binary little-endian, written here (trimesh's exporter stores positions as float32): ``double x y z s t``,
  the units and the UV convention in ``comment`` lines. trimesh reads ``s t`` back as ``visual.uv``.
- GLB: through trimesh, with a checkerboard base-colour texture so any glTF viewer shows the map. The texture
  coordinates stay in model units (glTF stores them as float32); the checker's size comes from the standard
  ``KHR_texture_transform`` extension (scale 1 / (2 cell)), and nearest-neighbour sampling with REPEAT wrap. The
  scene's ``extras`` state the units, the UV convention and the checker cell.
"""

from __future__ import annotations

import json
import os
import struct

import numpy as np


def _rows(V, uv, Fuv, uv_vertex):
    V = np.asarray(V, dtype=np.float64)
    uv = np.asarray(uv, dtype=np.float64)
    return V[np.asarray(uv_vertex, dtype=np.int64)], uv, np.asarray(Fuv, dtype=np.int64)


def write_ply(path: str | os.PathLike, V: np.ndarray, uv: np.ndarray, Fuv: np.ndarray, uv_vertex: np.ndarray,
              units: str = "mm", comment: str = "") -> dict:
    """Binary PLY: vertex ``double x y z s t`` (one per uv row), face ``list uchar int vertex_indices`` = Fuv.

    Parameters
    ----------
    V : (n,3) float64; uv : (k,2) float64; Fuv : (m,3) int64; uv_vertex : (k,) int64.
    units : model units, written in a comment (positions and UVs are both in these units).
    """
    P, T, Fk = _rows(V, uv, Fuv, uv_vertex)
    header = ["ply", "format binary_little_endian 1.0",
              f"comment units {units}: x y z and the texture coordinates s t (true-scale UV) are in {units}",
              *(f"comment {line}" for line in comment.splitlines() if line.strip()),
              f"element vertex {len(P)}", *(f"property double {a}" for a in "xyzst"),
              f"element face {len(Fk)}", "property list uchar int vertex_indices", "end_header"]
    vert = np.empty(len(P), dtype=[(a, "<f8") for a in "xyzst"])
    for i, a in enumerate("xyz"):
        vert[a] = P[:, i]
    vert["s"], vert["t"] = T[:, 0], T[:, 1]
    face = np.empty(len(Fk), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"], face["i"] = 3, Fk
    with open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        fh.write(vert.tobytes())
        fh.write(face.tobytes())
    return {"format": "ply", "units": units, "vertices": len(P), "faces": len(Fk)}


def checker_cell(uv: np.ndarray, cells: int = 16) -> float:
    """A round checker cell size (1, 2 or 5 times a power of ten) giving about ``cells`` cells across the map."""
    span = float(np.ptp(uv, axis=0).max()) if len(uv) else 1.0
    raw = span / cells if span > 0 else 1.0
    p = 10.0 ** np.floor(np.log10(raw))
    return float(min((m * p for m in (1, 2, 5, 10)), key=lambda c: abs(np.log(c / raw))))


def _checker_image(px: int = 64):
    from PIL import Image

    a = np.zeros((2 * px, 2 * px, 3), dtype=np.uint8)
    light, dark = (240, 150, 40), (40, 55, 140)
    a[:] = dark
    a[:px, :px] = light
    a[px:, px:] = light
    return Image.fromarray(a)


def write_glb(path: str | os.PathLike, V: np.ndarray, uv: np.ndarray, Fuv: np.ndarray, uv_vertex: np.ndarray,
              units: str = "mm", comment: str = "") -> dict:
    """GLB (binary glTF 2.0) through trimesh: positions, TEXCOORD_0 = uv, a checkerboard texture.

    Parameters
    ----------
    V : (n,3) float64; uv : (k,2) float64; Fuv : (m,3) int64; uv_vertex : (k,) int64.
    units : model units, stated in the scene's ``extras`` (glTF itself assumes metres).
    """
    import trimesh

    P, T, Fk = _rows(V, uv, Fuv, uv_vertex)
    cell = checker_cell(T)
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=_checker_image(), metallicFactor=0.0,
                                                   roughnessFactor=0.9, doubleSided=True)
    mesh = trimesh.Trimesh(P, Fk, visual=trimesh.visual.TextureVisuals(uv=T, material=material), process=False)
    data = mesh.export(file_type="glb")
    extras = {"generator": "heatparam", "units": units,
              "texcoord_0": f"true-scale UV in {units} (one uv per vertex; seam sides are separate vertices)",
              "checker_cell": cell, **({"comment": comment} if comment else {})}
    data = _patch_glb(data, extras, 1.0 / (2.0 * cell))
    with open(path, "wb") as fh:
        fh.write(data)
    return {"format": "glb", "units": units, "vertices": len(P), "faces": len(Fk), "checker_cell": cell}


def _patch_glb(data: bytes, extras: dict, scale: float) -> bytes:
    """Add scene extras, KHR_texture_transform (checker scale), a NEAREST/REPEAT sampler and bufferView targets
    to a GLB (the Khronos glTF validator then reports no error, warning or hint)."""
    magic, version, _ = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67:
        raise ValueError("not a GLB")
    jlen, jtype = struct.unpack_from("<II", data, 12)
    gltf = json.loads(data[20:20 + jlen].decode("utf-8"))
    rest = data[20 + jlen:]
    for scene in gltf.get("scenes", []):
        scene["extras"] = extras
    gltf.setdefault("asset", {})["extras"] = extras
    gltf["samplers"] = [{"magFilter": 9728, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    for tex in gltf.get("textures", []):
        tex["sampler"] = 0
    for mat in gltf.get("materials", []):
        info = mat.get("pbrMetallicRoughness", {}).get("baseColorTexture")
        if info is not None:
            info.setdefault("extensions", {})["KHR_texture_transform"] = {"scale": [scale, scale]}
    # bufferView targets (the Khronos validator's hint): vertex attributes 34962, indices 34963
    views = gltf.get("bufferViews", [])
    acc = gltf.get("accessors", [])
    for mesh in gltf.get("meshes", []):
        for prim in mesh.get("primitives", []):
            for a, target in [*((i, 34962) for i in prim.get("attributes", {}).values()),
                              *([(prim["indices"], 34963)] if "indices" in prim else [])]:
                bv = acc[a].get("bufferView")
                if bv is not None and views[bv].get("target", target) == target:
                    views[bv]["target"] = target
    used = gltf.setdefault("extensionsUsed", [])
    if "KHR_texture_transform" not in used:
        used.append("KHR_texture_transform")
    j = json.dumps(gltf, separators=(",", ":"), sort_keys=True).encode("utf-8")
    j += b" " * (-len(j) % 4)
    body = struct.pack("<II", len(j), jtype) + j + rest
    return struct.pack("<III", magic, version, 12 + len(body)) + body
