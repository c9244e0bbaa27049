"""The map as an OBJ: ``v`` the input vertices in input order, ``vt`` the UVs, faces ``f v/vt`` (and reading any
tool's OBJ with ``vt`` back for ``heatparam evaluate``)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.formats import readers
from heatparam.formats.files import atomic_write


def save_uv_obj(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, uv: np.ndarray, header: str = "",
                Fuv: np.ndarray | None = None) -> None:
    """Write an OBJ: ``v`` = V in input order, ``vt`` = uv, faces ``f v/vt``: vt index = v index (one vt per
    vertex) or, with ``Fuv`` (m,3), the rows of uv at each face's corners (a map with seams)."""
    Fuv = F if Fuv is None else Fuv
    with atomic_write(path) as fh:
        if header:
            fh.write("".join(f"# {line}\n" for line in header.splitlines()))
        # repr() of a float is the shortest text that reads back to the same float: exact round trip
        fh.write(("v %r %r %r\n" * len(V)) % tuple(np.asarray(V, dtype=np.float64).ravel().tolist()))
        fh.write(("vt %r %r\n" * len(uv)) % tuple(np.asarray(uv, dtype=np.float64).ravel().tolist()))
        f1 = np.stack([np.asarray(F, dtype=np.int64), np.asarray(Fuv, dtype=np.int64)], axis=2) + 1
        fh.write(("f %d/%d %d/%d %d/%d\n" * len(F)) % tuple(f1.ravel().tolist()))

def load_uv_obj(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read an OBJ with texture coordinates: V (n,3), F (m,3), UV (t,2), FUV (m,3) (per-corner UV indices).

    Polygons are fan-triangulated; faces without ``vt`` raise a one-line HeatparamError.
    """
    p = Path(path)
    if not p.is_file():
        raise HeatparamError(f"cannot read {p}: no such file")
    V, UV, F, FT = [], [], [], []
    lineno = 0
    try:
        for lineno, tok in readers.obj_lines(readers.decode(p.read_bytes())):  # noqa: B007 - read in except
            if tok[0] == "v":
                V.append([float(x) for x in tok[1:4]])
            elif tok[0] == "vt":
                UV.append([float(x) for x in tok[1:3]])
            elif tok[0] == "f":
                corners = [c.split("/") for c in tok[1:]]
                if any(len(c) < 2 or not c[1] for c in corners):
                    raise HeatparamError(f"{p}: a face has no texture coordinates (need 'f v/vt ...')")
                vi = [_obj_index(c[0], len(V)) for c in corners]
                ti = [_obj_index(c[1], len(UV)) for c in corners]
                for j in range(1, len(vi) - 1):
                    F.append([vi[0], vi[j], vi[j + 1]])
                    FT.append([ti[0], ti[j], ti[j + 1]])
    except (ValueError, IndexError) as exc:
        if isinstance(exc, HeatparamError):
            raise
        raise HeatparamError(f"cannot read {p} (line {lineno}): malformed OBJ line (a number or index expected)"
                             ) from None
    if not UV:
        raise HeatparamError(f"{p} has no texture coordinates (vt lines) to evaluate")
    if not F:
        raise HeatparamError(f"cannot read {p}: the file holds no faces")
    return (np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64),
            np.asarray(UV, dtype=np.float64), np.asarray(FT, dtype=np.int64))


def _obj_index(tok: str, count: int) -> int:
    i = int(tok)
    return i - 1 if i > 0 else count + i
