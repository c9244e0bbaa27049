"""Reading meshes.

OBJ, OFF, STL and PLY load through heatparam's own tolerant readers (``formats.readers``: comments in any byte
encoding, every OBJ index form, PLY with its faces and triangle strips (our own reader), one-line errors naming
the file and line); glTF/GLB scenes through trimesh. The vertex order is kept exactly (no
merging, no reordering; STL excepted, whose identical corners are merged). Quads and polygons are fan-triangulated.
Plain triangle OBJs (``v x y z`` and three-corner ``f`` lines) take a vectorized fast path that reads exactly what
the general reader reads, in less time (BENCHMARKS.md §4). trimesh and meshio are imported only when a file needs
them, through ``interrupt.guarded_import`` (trimesh's import swallows ``KeyboardInterrupt``).
"""

from __future__ import annotations

import contextlib
import io
import os
import warnings
from pathlib import Path

import numpy as np

from heatparam import interrupt
from heatparam.errors import HeatparamError
from heatparam.formats import readers

MESH_SUFFIXES = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")

def _triangulate(cells: list[tuple[str, np.ndarray]]) -> np.ndarray:
    """Fan-triangulate polygon cells [(type, (c,k) indices)] into (m,3) int64 triangles, in order."""
    tris = []
    for _, idx in cells:
        idx = np.asarray(idx, dtype=np.int64)
        if idx.ndim != 2 or idx.shape[1] < 3:
            continue  # points and lines carry no surface
        for j in range(1, idx.shape[1] - 1):
            tris.append(np.stack([idx[:, 0], idx[:, j], idx[:, j + 1]], axis=1))
    if not tris:
        return np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(tris).astype(np.int64)

def load_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh: V (n,3) float64 in file order, F (m,3) int64.

    Raises HeatparamError (one line) for a missing, unreadable, unsupported or empty file.
    """
    p = Path(path)
    if p.is_dir():
        raise HeatparamError(f"cannot read {p}: a folder, not a mesh file (heatparam batch flattens a folder)")
    if not p.is_file():
        raise HeatparamError(f"cannot read {p}: no such file")
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise HeatparamError(f"cannot read {p}: unsupported format {suffix!r} (use one of {', '.join(MESH_SUFFIXES)})")
    # OBJ, OFF, STL and PLY: heatparam's own tolerant readers (``readers``; any byte encoding in comments, every
    # OBJ index form, PLY faces and triangle strips), plain triangle OBJs through a vectorized fast path. glTF goes
    # through trimesh (process=False, maintain_order=True: vertex order kept).
    if suffix == ".obj":
        loaders = [load_obj_fast, _load_obj]
    elif suffix == ".off":
        loaders = [readers.read_off]
    elif suffix == ".stl":
        loaders = [readers.read_stl]
    elif suffix == ".ply":
        loaders = [readers.read_ply]
    else:
        loaders = [_load_trimesh]
    first_error = None
    for load in loaders:
        try:
            V, F = load(p)
            break
        except NotSimpleObj:
            continue
        except HeatparamError as exc:
            first_error = first_error or str(exc)
        except MemoryError:
            first_error = first_error or f"cannot read {p}: it announces more data than fits in memory"
        except Exception:  # a library's parser failed: its text may name modules or codecs, so it is not shown
            fmt = suffix[1:].upper()
            first_error = first_error or f"cannot read {p}: not a valid {fmt} file (it could not be parsed)"
    else:
        raise HeatparamError(first_error)
    if suffix == ".stl":
        V, F = _merge_stl(V, F)
    if len(V) and not len(F):
        raise HeatparamError(f"{p}: no faces: a point cloud; mesh it first, e.g. by Poisson reconstruction")
    if len(V) == 0 or len(F) == 0:
        raise HeatparamError(f"cannot read {p}: the file holds no triangles")
    bad = (F < 0) | (F >= len(V))
    if bad.any():  # named here, with the file, before any check of the mesh that would count the wrong thing
        f, c = np.argwhere(bad)[0]
        index = F[f, c] + (suffix == ".obj")  # as the file writes it: OBJ counts from 1, the others from 0
        raise HeatparamError(f"cannot read {p}: face {f + 1} uses vertex index {index}, out of range (the file has "
                             f"{len(V)} vertices)")
    return V, F

class NotSimpleObj(Exception):
    """The OBJ is not a plain triangle mesh: let meshio read it."""

#: OBJ statements the fast path skips, as meshio does (normals and texture coordinates are not used here).
_OBJ_SKIP = ("vt", "vn", "s", "g", "o", "usemtl", "mtllib")

def load_obj_fast(p: Path) -> tuple[np.ndarray, np.ndarray]:
    """Plain triangle OBJ: every ``v`` line has 3 coordinates, every ``f`` line 3 positive vertex indices.

    Gives exactly meshio's result (V in file order, parsed by Python's correctly rounded ``float``; faces in
    file order, each corner's vertex index being the part before the first ``/``), without meshio's
    per-line Python loop. Anything else (polygons, negative indices, other statements, odd whitespace) raises
    :class:`NotSimpleObj` and the file goes to the general reader (``readers.read_obj``).
    """
    text = readers.decode(p.read_bytes())
    if "\t" in text or "\r" in text or "\\" in text:
        raise NotSimpleObj
    v_lines, f_lines, attr = [], [], {"vt": [], "vn": []}
    for line in text.split("\n"):
        head = line[:2]
        if head == "v ":
            v_lines.append(line)
        elif head == "f ":
            f_lines.append(line)
        elif line and line[0] != "#":
            key = line.split(" ", 1)[0]
            if key in attr:
                attr[key].append(line)
            elif key not in _OBJ_SKIP:
                raise NotSimpleObj
    if not v_lines or not f_lines:
        raise NotSimpleObj
    for lines in attr.values():  # meshio parses these and fails (→ another loader) unless one per vertex
        if lines:
            if len(lines) != len(v_lines):
                raise NotSimpleObj
            _float_table(lines)
    V = _float_table(v_lines)
    f_tok = " ".join(f_lines).split()
    if V.shape[1] != 3 or len(f_tok) != 4 * len(f_lines):
        raise NotSimpleObj  # 2 or 4+ coordinates, or a face with another number of corners
    f_tok = np.array(f_tok, dtype=object).reshape(-1, 4)
    if (f_tok[:, 0] != "f").any():
        raise NotSimpleObj
    try:
        corners = f_tok[:, 1:].ravel()
        if "/" in text:
            corners = [c.split("/", 1)[0] for c in corners]
        F = np.array(list(map(int, corners)), dtype=np.int64).reshape(-1, 3)
    except ValueError:
        raise NotSimpleObj from None
    if F.min() < 1:
        raise NotSimpleObj  # relative (negative) or zero indices: the general reader resolves or refuses them
    return V, F - 1

def _float_table(lines: list[str]) -> np.ndarray:
    """Lines ``key x y ...`` with the same number of entries → (len(lines), entries) float64, else NotSimpleObj."""
    tok = " ".join(lines).split()
    width = len(lines[0].split())
    if width < 2 or len(tok) != width * len(lines):
        raise NotSimpleObj
    tok = np.array(tok, dtype=object).reshape(-1, width)
    if (tok[:, 0] != tok[0, 0]).any():
        raise NotSimpleObj  # the key of each line must start a row: every line has the same width
    try:
        return np.array(list(map(float, tok[:, 1:].ravel())), dtype=np.float64).reshape(len(lines), width - 1)
    except ValueError:
        raise NotSimpleObj from None

def _load_obj(p: Path) -> tuple[np.ndarray, np.ndarray]:
    return readers.read_obj(p)

def load_meshio(p: Path) -> tuple[np.ndarray, np.ndarray]:
    meshio = interrupt.guarded_import("meshio")

    quiet = contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO())
    with warnings.catch_warnings(), quiet[0], quiet[1]:
        warnings.simplefilter("ignore")
        try:
            m = meshio.read(p)
        except SystemExit:  # meshio's OFF reader exits on some parse errors instead of raising
            raise HeatparamError(f"cannot read {p}: not a valid {p.suffix[1:].upper()} file") from None
    V = np.asarray(m.points, dtype=np.float64)
    if V.size == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    if V.ndim != 2 or V.shape[1] not in (2, 3):
        raise HeatparamError(f"cannot read {p}: vertices must have 2 or 3 coordinates")
    if V.shape[1] == 2:
        V = np.column_stack([V, np.zeros(len(V))])
    F = _triangulate([(c.type, c.data) for c in m.cells])
    return V, F

def _load_trimesh(p: Path) -> tuple[np.ndarray, np.ndarray]:
    trimesh = interrupt.guarded_import("trimesh")

    quiet = contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO())
    with warnings.catch_warnings(), quiet[0], quiet[1]:
        warnings.simplefilter("ignore")
        scene = trimesh.load(file_obj=str(p), process=False, maintain_order=True, force="scene")
    geoms = [g for g in scene.dump() if hasattr(g, "faces")]
    if not geoms:
        raise HeatparamError(f"cannot read {p}: the file holds no triangles")
    Vs, Fs, off = [], [], 0
    for g in geoms:
        Vs.append(np.asarray(g.vertices, dtype=np.float64))
        Fs.append(np.asarray(g.faces, dtype=np.int64) + off)
        off += len(g.vertices)
    return np.concatenate(Vs), np.concatenate(Fs)

def _merge_stl(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """STL stores every triangle with its own corners: merge identical positions (first appearance order)."""
    _, first, inverse = np.unique(V, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # unique rows in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return V[np.sort(first)], rank[inverse.ravel()][F]
