"""File formats, at the edge: nothing else in heatparam opens a file.

One module per family (as trimesh's ``exchange/``):

``files``    atomic writes (temporary beside the target, renamed when complete), JSON reports, .npy arrays
``meshes``   reading meshes (OBJ, OFF, PLY, STL, glTF/GLB)
``uvobj``    the map as an OBJ with ``vt`` (and reading one back)

A new output format is a new module here with a ``write_<format>(path, ...)`` function over plain arrays that
writes through :func:`atomic_write` (see docs/architecture.md).
"""

from heatparam.formats.files import atomic_write, save_json, save_npy
from heatparam.formats.meshes import MESH_SUFFIXES, load_mesh
from heatparam.formats.uvobj import load_uv_obj, save_uv_obj

__all__ = ["MESH_SUFFIXES", "atomic_write", "load_mesh", "load_uv_obj", "save_json", "save_npy", "save_uv_obj"]
