"""File formats, at the edge: nothing else in heatparam opens a file.

One module per family (as trimesh's ``exchange/``):

``exporters`` the table of output formats (suffixes, writer, optional dependency) that every command reads
``outputs``   the writing contract: every output path checked before the computation, all written or none
``files``     atomic writes (temporary beside the target, renamed when complete), JSON reports, .npy arrays
``meshes``    reading meshes (OBJ, OFF, PLY, STL, glTF/GLB)
``uvobj``     the map as an OBJ with ``vt`` (and reading one back)
``meshuv``    the map as a PLY or GLB; ``pattern``, ``dxf``, ``svg``: the flat pattern; ``step``: B-spline faces
``preview``   the preview PNG; ``summary``: a batch's summary.csv, summary.json and index.html

A new output format is a new module here with a ``write_<format>(path, ...)`` function over plain arrays that
writes through :func:`atomic_write`, and one line in ``exporters.EXPORTERS``.

The names below are imported when first used, so that reading the format table (``heatparam --help``) loads no
numerics.
"""

from __future__ import annotations

import importlib

#: name → the module that defines it
_HOMES = {"atomic_write": "files", "save_json": "files", "save_npy": "files", "MESH_SUFFIXES": "meshes",
          "load_mesh": "meshes", "load_uv_obj": "uvobj", "save_uv_obj": "uvobj"}

__all__ = ["MESH_SUFFIXES", "atomic_write", "load_mesh", "load_uv_obj", "save_json", "save_npy", "save_uv_obj"]


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    globals()[name] = value
    return value
