"""Tolerant readers for OBJ, OFF, ASCII/binary STL and PLY, with one-line errors.

Comments and names may be in any byte encoding (Latin-1 from European or Windows exporters, UTF-8, junk): the
bytes are decoded as UTF-8 where valid and as Latin-1 otherwise, which never fails; numbers and keywords are
ASCII in every encoding. Every error is a :class:`~heatparam.errors.HeatparamError` of one line that names the
file, the line and the problem.

OBJ: ``v`` (2 or more coordinates; the first three are used, a missing z is 0), ``f`` with ``v``, ``v/vt``,
``v//vn`` or ``v/vt/vn`` corners, positive and negative (relative) indices, polygons fan-triangulated, ``\\`` line
continuations, ``#`` comments; every other statement (``vt``, ``vn``, ``o``, ``g``, ``s``, ``usemtl``,
``mtllib``, ``l``, ``p``, free-form geometry) is skipped.
OFF: the ``[ST][C][N]OFF`` headers (per-vertex extras and per-face colours ignored), counts on the header line or
the next, polygons fan-triangulated; binary, 4D and n-dimensional OFF are refused.
STL: binary (recognized by its size: 84 + 50 bytes per triangle) or ASCII (``vertex x y z`` triples).
PLY: parsed here (ASCII, binary of either endianness, every element), faces and triangle strips included.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from heatparam.errors import HeatparamError


def decode(data: bytes) -> str:
    """Bytes → text: UTF-8 (a byte-order mark dropped) where valid, else Latin-1 (every byte is a character)."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _shown(tok: str, limit: int = 24) -> str:
    """A token as it may appear in a one-line message: printable ASCII, quoted, truncated."""
    s = "".join(c if 32 <= ord(c) < 127 else "?" for c in tok)
    return repr(s[:limit] + ("…" if len(s) > limit else ""))


def _fail(p: Path, what: str, lineno: int | None = None) -> HeatparamError:
    where = f" (line {lineno})" if lineno is not None else ""
    return HeatparamError(f"cannot read {p}{where}: {what}")


def _fan(corners: list[int]) -> list[list[int]]:
    return [[corners[0], corners[j], corners[j + 1]] for j in range(1, len(corners) - 1)]


def _read_bytes(p: Path) -> bytes:
    try:
        return p.read_bytes()
    except OSError as exc:
        raise _fail(p, exc.strerror or "the file cannot be opened") from None


# ----------------------------------------------------------------------------------------------------------
# OBJ
# ----------------------------------------------------------------------------------------------------------
def obj_lines(text: str):
    """(line number, tokens) of the statements of an OBJ text: comments dropped, continuations joined."""
    pending, start = "", 0
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0]
        if not pending:
            start = lineno
        stripped = line.rstrip()
        if stripped.endswith("\\"):
            pending += stripped[:-1] + " "
            continue
        line, pending = pending + line, ""
        tokens = line.split()
        if tokens:
            yield start, tokens
    if pending.split():
        yield start, pending.split()


def read_obj(p: Path, text: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Any OBJ → V (n,3) float64 in file order, F (m,3) int64 (0-based; out-of-range ones are left for the
    validation to report)."""
    if text is None:
        text = decode(_read_bytes(p))
    V: list[list[float]] = []
    groups: list[list[list[int]]] = []  # runs of faces with the same corner count (and ``g``), as meshio read them
    lines = 0  # edges and curves: ``l``, ``curv`` and ``f`` of two corners (how some exporters write loose edges)
    for lineno, tok in obj_lines(text):
        key = tok[0]
        if key == "v":
            if len(tok) < 3:
                raise _fail(p, "a 'v' line needs at least 2 coordinates", lineno)
            try:
                xyz = [float(t) for t in tok[1:4]]
            except ValueError:
                bad = next(t for t in tok[1:4] if not _is_float(t))
                raise _fail(p, f"vertex coordinate {_shown(bad)} is not a number", lineno) from None
            if len(xyz) == 2:
                xyz.append(0.0)
            V.append(xyz)
        elif key in ("l", "curv", "curv2"):
            lines += 1
        elif key == "f" or key == "fo":
            if len(tok) == 3:
                lines += 1
                continue
            if len(tok) < 3:
                raise _fail(p, f"a face needs at least 3 corners, this one has {len(tok) - 1}", lineno)
            corners = []
            for c in tok[1:]:
                head = c.split("/", 1)[0]
                try:
                    i = int(head)
                except ValueError:
                    raise _fail(p, f"face corner {_shown(c)} is not a vertex index", lineno) from None
                if i == 0:
                    raise _fail(p, "face index 0 (OBJ indices start at 1; negative ones count back)", lineno)
                if i < 0:
                    if -i > len(V):
                        raise _fail(p, f"relative face index {i} points before the first vertex "
                                       f"({len(V)} defined so far)", lineno)
                    i = len(V) + i
                else:
                    i -= 1
                corners.append(i)
            if not groups or (groups[-1] and len(groups[-1][-1]) != len(corners)):
                groups.append([])
            groups[-1].append(corners)
        elif key == "g":
            groups.append([])
    Va = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    Fa = _fan_groups([g for g in groups if g])
    if lines and not len(Fa):
        raise _fail(p, f"no faces, only lines or curves ({lines}): a wireframe; heatparam flattens surfaces: "
                       f"export the surface's faces")
    if len(Fa) and Fa.max() > np.iinfo(np.int64).max // 2:
        raise _fail(p, "a face index is out of range")
    return Va, Fa


def _fan_groups(groups: list[list[list[int]]]) -> np.ndarray:
    """Fan-triangulate groups of same-size polygons, each group as [all first triangles, all second ...] (the order
    heatparam's maps were made with when meshio read OBJs). (m,3) int64."""
    tris = []
    for g in groups:
        a = np.asarray(g, dtype=np.int64)
        tris += [a[:, [0, j, j + 1]] for j in range(1, a.shape[1] - 1)]
    return np.concatenate(tris) if tris else np.zeros((0, 3), dtype=np.int64)


def _off_triangles(polys: list[list[int]]) -> np.ndarray:
    """Triangles of OFF polygons in the order trimesh gives (heatparam's maps were made with it): the triangles,
    then the quads' (0,1,2) and their (2,3,0) halves, then the larger polygons' fans. (m,3) int64."""
    sizes = np.array([len(q) for q in polys], dtype=np.int64)
    if len(sizes) and (sizes == 3).all():
        return np.asarray(polys, dtype=np.int64).reshape(-1, 3)
    tri = np.asarray([q for q in polys if len(q) == 3], dtype=np.int64).reshape(-1, 3)
    quad = np.asarray([q for q in polys if len(q) == 4], dtype=np.int64).reshape(-1, 4)
    fans = [t for q in polys if len(q) > 4 for t in _fan(q)]
    return np.vstack([tri, quad[:, [0, 1, 2]], quad[:, [2, 3, 0]], np.asarray(fans, dtype=np.int64).reshape(-1, 3)])


def _is_float(t: str) -> bool:
    try:
        float(t)
    except ValueError:
        return False
    return True


# ----------------------------------------------------------------------------------------------------------
# OFF
# ----------------------------------------------------------------------------------------------------------
_OFF_HEADER = re.compile(r"^(ST)?(C)?(N)?(4)?(n)?OFF$")
_OFF_GLUED = re.compile(r"^((?:ST)?C?N?4?n?OFF)(\d+)$")  # 'OFF8 6 12': the vertex count written against the header


def _data_lines(text: str):
    for lineno, raw in enumerate(text.splitlines(), 1):
        tokens = raw.split("#", 1)[0].split()
        if tokens:
            yield lineno, tokens


def _ints(p: Path, tokens: list[str], lineno: int, what: str) -> list[int]:
    try:
        return [int(t) for t in tokens]
    except ValueError:
        bad = next(t for t in tokens if not t.lstrip("+-").isdigit())
        raise _fail(p, f"{what} {_shown(bad)} is not a whole number", lineno) from None


def read_off(p: Path) -> tuple[np.ndarray, np.ndarray]:
    """ASCII OFF → V (n,3) float64 in file order, F (m,3) int64 (polygons fan-triangulated)."""
    data = _read_bytes(p)
    first = data.lstrip()[:64].split(b"\n", 1)[0].upper()
    if b"BINARY" in first:
        raise _fail(p, "binary OFF is not supported — export it as ASCII OFF, OBJ or PLY")
    text = decode(data)
    fast = _off_fast(text)
    if fast is not None:
        return fast
    lines = _data_lines(text)
    nv, nf = _off_counts(p, lines)
    V = _off_vertices(p, lines, nv)
    return V, _off_triangles(_off_faces(p, lines, nf))


def _off_counts(p: Path, lines) -> tuple[int, int]:
    """The vertex and face counts after the (optional) ``OFF`` header, read from the data ``lines``."""
    try:
        lineno, tok = next(lines)
    except StopIteration:
        raise _fail(p, "the file is empty") from None
    glued = _OFF_GLUED.match(tok[0])
    if glued:
        tok = [glued.group(1), glued.group(2), *tok[1:]]
    if _OFF_HEADER.match(tok[0]):
        m = _OFF_HEADER.match(tok[0])
        if m.group(4) or m.group(5):
            raise _fail(p, f"{_shown(tok[0])} (4D or n-dimensional) OFF is not supported: vertices must be 3D", lineno)
        tok = tok[1:]
        if not tok:
            try:
                lineno, tok = next(lines)
            except StopIteration:
                raise _fail(p, "the file ends after the header") from None
    elif not tok[0].lstrip("+-").isdigit():
        raise _fail(p, f"expected the 'OFF' header, got {_shown(tok[0])} — is it an OFF file?", lineno)
    counts = _ints(p, tok[:3], lineno, "count")
    if len(counts) < 2 or min(counts) < 0:
        raise _fail(p, "expected the vertex and face counts after the header", lineno)
    return counts[0], counts[1]


def _off_vertices(p: Path, lines, nv: int) -> np.ndarray:
    """The next ``nv`` vertex lines as V (nv,3) float64."""
    rows: list[list[float]] = []
    for k, (lineno, tok) in enumerate(lines):
        if len(tok) < 3:
            raise _fail(p, "a vertex line needs 3 coordinates", lineno)
        try:
            rows.append([float(t) for t in tok[:3]])
        except ValueError:
            bad = next(t for t in tok[:3] if not _is_float(t))
            raise _fail(p, f"vertex coordinate {_shown(bad)} is not a number", lineno) from None
        if k + 1 == nv:
            break
    if len(rows) < nv:
        raise _fail(p, f"the file ends after {len(rows)} of the {nv} vertices its header announces")
    return np.asarray(rows, dtype=np.float64).reshape(-1, 3)


def _off_faces(p: Path, lines, nf: int) -> list[list[int]]:
    """The next ``nf`` face lines as lists of vertex indices (polygons)."""
    polys: list[list[int]] = []
    done = 0
    for lineno, tok in lines if nf else ():
        idx = _ints(p, tok[:1], lineno, "corner count")
        k = idx[0]
        if k < 3:
            raise _fail(p, f"a face needs at least 3 corners, this one has {k}", lineno)
        if len(tok) < k + 1:
            raise _fail(p, f"a face announces {k} corners but lists {len(tok) - 1}", lineno)
        polys.append(_ints(p, tok[1:k + 1], lineno, "vertex index"))
        done += 1
        if done == nf:
            break
    if done < nf:
        raise _fail(p, f"the file ends after {done} of the {nf} faces its header announces")
    return polys


def _off_fast(text: str) -> tuple[np.ndarray, np.ndarray] | None:
    """A plain OFF (``OFF`` header, no comments, 3 coordinates per vertex, all faces with the same corner count)
    read vectorized: the same result as the line-by-line reader, or None for anything else."""
    if "#" in text:
        return None
    tok = text.split()
    if len(tok) < 4 or tok[0] != "OFF":
        return None
    try:
        nv, nf, _ = (int(t) for t in tok[1:4])
        body = tok[4:]
        if nv < 0 or nf <= 0 or len(body) < 3 * nv + 1:
            return None
        k = int(body[3 * nv])
        if k < 3 or len(body) != 3 * nv + (k + 1) * nf:
            return None
        V = np.array(body[:3 * nv], dtype=np.float64).reshape(nv, 3)
        P = np.array(body[3 * nv:], dtype=np.int64).reshape(nf, k + 1)
    except (ValueError, OverflowError):
        return None
    if (P[:, 0] != k).any():
        return None
    P = P[:, 1:]
    if k == 3:
        return V, P
    if k == 4:
        return V, np.vstack([P[:, [0, 1, 2]], P[:, [2, 3, 0]]])
    return V, np.stack([P[:, [0, j, j + 1]] for j in range(1, k - 1)], axis=1).reshape(-1, 3)


# ----------------------------------------------------------------------------------------------------------
# STL
# ----------------------------------------------------------------------------------------------------------
_STL_BINARY = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
_STL_VERTEX = re.compile(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)", re.IGNORECASE)


def read_stl(p: Path) -> tuple[np.ndarray, np.ndarray]:
    """STL → one vertex per triangle corner V (3m,3), F (m,3) (``io`` merges identical corners)."""
    data = _read_bytes(p)
    count = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0]) if len(data) >= 84 else -1
    if count >= 0 and len(data) == 84 + 50 * count:
        tri = np.frombuffer(data, dtype=_STL_BINARY, count=count, offset=84)
        V = tri["v"].reshape(-1, 3).astype(np.float64)
        return V, np.arange(len(V), dtype=np.int64).reshape(-1, 3)
    if count >= 0 and b"\0" in data[84:]:  # binary, whatever its header says: the size does not match
        raise _fail(p, f"truncated or corrupt binary STL: {len(data)} bytes, but its header announces {count} "
                       f"triangles ({84 + 50 * count} bytes)")
    if not data.lstrip()[:5].lower() == b"solid":
        raise _fail(p, f"not an STL file: neither ASCII ('solid …') nor binary (a binary STL of "
                       f"{len(data)} bytes would need 84 + 50 bytes per triangle)")
    found = _STL_VERTEX.findall(data)
    if len(found) % 3:
        raise _fail(p, f"ASCII STL with {len(found)} 'vertex' lines, not a multiple of 3")
    try:
        V = np.array([[float(x) for x in row] for row in found], dtype=np.float64).reshape(-1, 3)
    except ValueError:
        raise _fail(p, "an ASCII STL 'vertex' line holds something that is not a number") from None
    return V, np.arange(len(V), dtype=np.int64).reshape(-1, 3)


# ----------------------------------------------------------------------------------------------------------
# PLY
# ----------------------------------------------------------------------------------------------------------
#: the names exporters give the list of a face's (or a strip's) vertex indices
_PLY_INDEX_NAMES = ("vertex_indices", "vertex_index")
#: PLY scalar type names → numpy type codes (both spellings of the standard)
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def read_ply(p: Path) -> tuple[np.ndarray, np.ndarray]:
    """PLY as users have it → V (n,3) float64 in file order, F (m,3) int64.

    ASCII or binary of either endianness, any numeric property types (:class:`_Ply` parses every element); the
    ``vertex`` element's x, y, z; the ``face`` element's polygons (``vertex_indices`` or ``vertex_index``),
    fan-triangulated in trimesh's order (heatparam's maps were made with it: :func:`_off_triangles`), then the
    triangles of a ``tristrips`` element (:func:`strip_triangles`, the Stanford / VCG convention); other elements
    and properties are ignored. A file of vertices only gives F of 0 rows (``load_mesh`` names it a point cloud)."""
    ply = _parse_ply(p)
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise _fail(p, "the PLY file has no 'vertex' element")
    vert = ply["vertex"].data
    if not {"x", "y", "z"} <= set(vert):
        raise _fail(p, "the PLY 'vertex' element has no x, y, z properties")
    V = np.column_stack([vert["x"], vert["y"], vert["z"]]).astype(np.float64)
    tris = [np.zeros((0, 3), dtype=np.int64)]
    if "face" in names and ply["face"].count:
        tris.append(_ply_polygons(p, _ply_index_lists(p, ply["face"])))
    if "tristrips" in names and ply["tristrips"].count:
        tris.append(strip_triangles(list(_ply_index_lists(p, ply["tristrips"]))))
    return V, np.concatenate(tris)


def strip_triangles(strips: list) -> np.ndarray:
    """Triangle strips (index sequences, -1 restarting a strip) → (m,3) int64 triangles, consistently oriented.

    In a strip a, b, c, d, e, ... the triangles are (a, b, c), (c, b, d), (c, d, e), ...: every other one is
    flipped, counting from the strip's start. Triangles that repeat an index (the swaps that join strips) are no
    faces and are dropped."""
    parts = [np.append(np.asarray(s, dtype=np.int64).ravel(), -1) for s in strips]
    seq = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
    if len(seq) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    pos = np.arange(len(seq))
    start = np.maximum.accumulate(np.where(seq == -1, pos + 1, 0))  # where each position's strip starts
    a, b, c = seq[:-2], seq[1:-1], seq[2:]
    odd = (pos[:-2] - start[:-2]) % 2 == 1
    T = np.column_stack([np.where(odd, b, a), np.where(odd, a, b), c])
    T = T[(a != -1) & (b != -1) & (c != -1)]
    return T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 2] != T[:, 0])]


def _ply_index_lists(p: Path, element) -> np.ndarray:
    """The element's vertex index lists: (k,3) when read as triangles, else (k,) arrays."""
    for name in _PLY_INDEX_NAMES:
        if name in element.data:
            return element.data[name]
    raise _fail(p, f"the PLY {_shown(element.name)} element has no 'vertex_indices' list")


def _ply_polygons(p: Path, lists: np.ndarray) -> np.ndarray:
    """A ``face`` element's index lists → triangles (m,3) int64."""
    if lists.dtype != object and lists.ndim == 2 and lists.shape[1] == 3:
        return np.asarray(lists, dtype=np.int64)
    if all(len(q) == 3 for q in lists):
        return np.vstack(lists).astype(np.int64)
    polys = [np.asarray(q, dtype=np.int64).tolist() for q in lists]
    short = next((k for k, q in enumerate(polys) if len(q) < 3), None)
    if short is not None:
        raise _fail(p, f"a face needs at least 3 corners, face {short} has {len(polys[short])}")
    return _off_triangles(polys)


def _parse_ply(p: Path) -> _Ply:
    """The file's elements (:class:`_Ply`), its errors as one line."""
    data = _read_bytes(p)
    end = data.find(b"end_header")
    if data[:3].lower() != b"ply" or end < 0:  # Rhino writes the magic word in capitals
        raise _fail(p, "not a PLY file (no 'ply' … 'end_header' header)")
    nl = data.find(b"\n", end)
    body = nl + 1 if nl >= 0 else len(data)
    ply = _Ply(p, data[:end].decode("ascii", errors="replace").splitlines())
    try:
        ply.read(data, body)
    except (ValueError, IndexError, OverflowError) as exc:
        detail = f" ({exc})" if isinstance(exc, _Corrupt) else ""  # numpy's and int()'s texts are no message
        raise _fail(p, f"its {_shown(ply.reading)} element is truncated or corrupt{detail}") from None
    return ply


class _Corrupt(ValueError):
    """A PLY body that does not match its header, in words fit for the user."""


class _PlyList:
    """Reading a PLY element that holds list properties (faces, strips)."""

    @staticmethod
    def column(values: list, t: str, count: str | None) -> np.ndarray:
        """A property's rows as read one by one: (n,) for a scalar, (n, k) when every list has k entries, else an
        object array of (k_i,) arrays."""
        if count is None:
            return np.asarray(values, dtype=np.float64).astype(t)
        if values and all(len(v) == len(values[0]) for v in values):
            return np.vstack(values).astype(np.int64)
        out = np.empty(len(values), dtype=object)
        out[:] = values
        return out

    @staticmethod
    def first_lengths(el: _PlyElement, body: bytes, at: int, order: str) -> list[int]:
        """The list lengths of the element's first row (0 for scalars)."""
        lengths = []
        for _, t, c in el.props:
            if c is None or el.count == 0:
                lengths.append(0)
                at += np.dtype(t).itemsize
                continue
            n = int(np.frombuffer(body, dtype=order + c, count=1, offset=at)[0])
            lengths.append(n)
            at += np.dtype(c).itemsize + n * np.dtype(t).itemsize
        return lengths

    @staticmethod
    def row_dtype(el: _PlyElement, lengths: list[int], order: str) -> np.dtype:
        """A row as a structured type, each list with the given length (its count field before it)."""
        fields = []
        for (name, t, c), n in zip(el.props, lengths, strict=True):
            if c is None:
                fields.append((name, order + t))
            else:
                fields += [(f"{name}#count", order + c), (name, order + t, (n,))]
        return np.dtype(fields)

    @staticmethod
    def uniform(el: _PlyElement, rows: np.ndarray, lengths: list[int]) -> bool:
        """Whether every row's lists have the first row's lengths (the structured read is then the file)."""
        return all(c is None or (rows[f"{name}#count"] == n).all()
                   for (name, _, c), n in zip(el.props, lengths, strict=True))

    @staticmethod
    def rows(el: _PlyElement, body: bytes, at: int, order: str) -> int:
        """Read ``el`` row by row (lists of varying length); the position after it."""
        cols: dict = {name: [] for name, _, _ in el.props}
        for _ in range(el.count):
            for name, t, c in el.props:
                if c is None:
                    cols[name].append(np.frombuffer(body, dtype=order + t, count=1, offset=at)[0])
                    at += np.dtype(t).itemsize
                    continue
                n = int(np.frombuffer(body, dtype=order + c, count=1, offset=at)[0])
                at += np.dtype(c).itemsize
                cols[name].append(np.frombuffer(body, dtype=order + t, count=n, offset=at).astype(np.int64))
                at += n * np.dtype(t).itemsize
        el.data = {name: _PlyList.column(cols[name], t, c) for name, t, c in el.props}
        return at


class _PlyElement:
    """One PLY element: its name, row count, properties (name, type code, list count type or None) and, once read,
    ``data``: property name → (count,) array, or for a list (count, k) when every row has k entries, else an object
    array of (k_i,) arrays."""

    def __init__(self, name: str, count: int):
        self.name, self.count, self.props, self.data = name, count, [], {}


class _Ply:
    """A PLY file as its header declares it (format, elements, properties), read by :meth:`read`.

    A tolerant reader of our own: the PLY readers of trimesh and meshio read no ``tristrips`` element, and the one
    that does (plyfile) is GPL-licensed."""

    def __init__(self, p: Path, header: list[str]):
        self.p, self.elements, self.fmt, self.reading = p, [], None, "header"
        for i, line in enumerate(header[1:], start=2):
            w = line.split()
            if not w or w[0] in ("comment", "obj_info"):
                continue
            if w[0] == "format" and len(w) >= 2 and w[1] in ("ascii", "binary_little_endian", "binary_big_endian"):
                self.fmt = w[1]
            elif w[0] == "element" and len(w) == 3 and w[2].isdigit():
                self.elements.append(_PlyElement(w[1], int(w[2])))
            elif w[0] == "property" and self.elements and self._property(w):
                continue
            else:
                raise _fail(p, f"malformed PLY header (line {i}: {_shown(line.strip()[:60])})")
        if self.fmt is None:
            raise _fail(p, "malformed PLY header (no 'format ascii' or 'format binary_…_endian 1.0' line)")

    def _property(self, w: list[str]) -> bool:
        """Add the property of header words ``w`` to the last element; False when the line is not one."""
        if len(w) == 3 and w[1] in _PLY_TYPES:
            self.elements[-1].props.append((w[2], _PLY_TYPES[w[1]], None))
            return True
        if len(w) == 5 and w[1] == "list" and w[2] in _PLY_TYPES and w[3] in _PLY_TYPES:
            self.elements[-1].props.append((w[4], _PLY_TYPES[w[3]], _PLY_TYPES[w[2]]))
            return True
        return False

    def __getitem__(self, name: str) -> _PlyElement:
        return next(e for e in self.elements if e.name == name)

    def read(self, data: bytes, start: int) -> None:
        """Read every element from ``data`` (the whole file) at byte ``start`` (the body's first)."""
        if self.fmt == "ascii":
            tokens, at = data[start:].split(), 0
            try:
                for el in self.elements:
                    self.reading = el.name
                    at = self._ascii(el, tokens, at)
                if at == len(tokens):
                    return
            except (ValueError, IndexError):
                pass
            # rows longer than the header says (MeshLab's faces with texcoords): each row is its own line
            self._ascii_lines(data[start:])
            return
        order = "<" if self.fmt == "binary_little_endian" else ">"
        at = start
        for el in self.elements:
            self.reading = el.name
            at = self._binary(el, data, at, order)

    @staticmethod
    def _ascii(el: _PlyElement, tokens: list[bytes], at: int) -> int:
        """Read ``el`` from the whitespace-separated tokens from ``at``; the position after it."""
        if all(c is None for _, _, c in el.props):  # fixed rows: one array
            k = len(el.props)
            rows = np.array(tokens[at: at + k * el.count], dtype=np.float64)
            if len(rows) < k * el.count:
                raise _Corrupt(f"{el.count} rows declared, fewer found")
            rows = rows.reshape(el.count, k)
            el.data = {name: rows[:, j].astype(t) for j, (name, t, _) in enumerate(el.props)}
            return at + k * el.count
        cols: dict = {name: [] for name, _, _ in el.props}
        for _ in range(el.count):
            for name, _, c in el.props:
                if c is None:
                    cols[name].append(float(tokens[at]))
                    at += 1
                else:
                    n = int(tokens[at])
                    cols[name].append(np.array(tokens[at + 1: at + 1 + n], dtype=np.float64).astype(np.int64))
                    if len(cols[name][-1]) < n:
                        raise _Corrupt("a list is cut short")
                    at += 1 + n
        el.data = {name: _PlyList.column(cols[name], t, c) for name, t, c in el.props}
        return at

    def _ascii_lines(self, body: bytes) -> None:
        """Read every element one row per line, the properties from each line's start, the rest ignored."""
        lines = [w for w in (line.split() for line in body.splitlines()) if w]
        at = 0
        for el in self.elements:
            self.reading = el.name
            if at + el.count > len(lines):
                raise _Corrupt(f"{el.count} rows declared, fewer found")
            cols: dict = {name: [] for name, _, _ in el.props}
            for w in lines[at: at + el.count]:
                k = 0
                for name, _, c in el.props:
                    if c is None:
                        cols[name].append(float(w[k]))
                        k += 1
                        continue
                    n = int(w[k])
                    if k + 1 + n > len(w):
                        raise _Corrupt("a list is cut short")
                    cols[name].append(np.array(w[k + 1: k + 1 + n], dtype=np.float64).astype(np.int64))
                    k += 1 + n
            el.data = {name: _PlyList.column(cols[name], t, c) for name, t, c in el.props}
            at += el.count

    @staticmethod
    def _binary(el: _PlyElement, body: bytes, at: int, order: str) -> int:
        """Read ``el`` from ``body`` at byte ``at`` (``order``: < or >); the position after it. Rows whose lists
        all have the first row's lengths (faces of triangles) are read as one structured array."""
        first = _PlyList.first_lengths(el, body, at, order)
        dtype = _PlyList.row_dtype(el, first, order)
        size = dtype.itemsize * el.count
        if at + size <= len(body):
            rows = np.frombuffer(body, dtype=dtype, count=el.count, offset=at)
            if _PlyList.uniform(el, rows, first):
                el.data = {name: (rows[name].astype(t) if c is None else rows[name].astype(np.int64))
                           for name, t, c in el.props}
                return at + size
        return _PlyList.rows(el, body, at, order)
