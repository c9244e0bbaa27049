"""Hostile datasets built in code: long thin limbs on a curved surface, slivers and needles (issue 16).

Each function returns plain arrays ``V (n,3) float64, F (m,3) int64`` (counter-clockwise faces, one border).
"""

from __future__ import annotations

import re
import struct

import numpy as np

from heatparam.datasets import mesh_domain, polygon


def limbs_outline(n_limbs: int = 5, body: float = 0.6, limb_length: float = 3.0, limb_width: float = 0.08,
                  h: float = 0.04) -> np.ndarray:
    """A star-like figure: a round body with ``n_limbs`` long thin straight limbs. (k,2) counter-clockwise loop."""
    corners = []
    for i in range(n_limbs):
        a = 2 * np.pi * i / n_limbs
        d = np.array([np.cos(a), np.sin(a)])
        nrm = np.array([-d[1], d[0]])
        half = 0.5 * limb_width
        base = np.sqrt(body**2 - half**2) * d
        corners += [base - half * nrm, base + limb_length * d - half * nrm, base + limb_length * d + half * nrm,
                    base + half * nrm]
        # body arc up to the next limb
        a_next = 2 * np.pi * (i + 1) / n_limbs
        da = np.arcsin(half / body)
        for t in np.linspace(a + da, a_next - da, 8)[1:-1]:
            corners.append(body * np.array([np.cos(t), np.sin(t)]))
    return polygon(np.array(corners), h)


def thin_limbs_disk(n_limbs: int = 5, limb_length: float = 3.0, limb_width: float = 0.08, h: float = 0.04,
                    bend: float = 1.0, twist: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A figure with long thin limbs (a disk) on a curved surface: the limbs curl down a cylinder-like bend of
    curvature ``bend`` and twist by ``twist`` radians per unit length (not developable when both are set).

    Returns V (n,3), F (m,3)."""
    uv, F = mesh_domain([limbs_outline(n_limbs, 0.6, limb_length, limb_width, h)], h)
    r = np.linalg.norm(uv, axis=1)
    ang = np.arctan2(uv[:, 1], uv[:, 0])
    # each point curls around its own radial direction: arc length r along a circle of curvature `bend`
    k = max(bend, 1e-12)
    z = (np.cos(k * r) - 1) / k
    rr = np.sin(k * r) / k
    ang = ang + twist * r
    V = np.column_stack([rr * np.cos(ang), rr * np.sin(ang), z])
    return V, F


def degrade(V: np.ndarray, F: np.ndarray, slivers: float = 0.02, needles: float = 0.02, seed: int = 0,
            squeeze: float = 1e-6) -> np.ndarray:
    """A copy of V with nearly degenerate triangles, as in real scans: for a fraction ``slivers`` of the faces,
    one corner is moved onto the opposite edge up to ``squeeze`` × its height (slivers); for a fraction
    ``needles``, one corner is moved onto another up to ``squeeze`` × the edge (needles). Border vertices move
    too. (n,3)."""
    rng = np.random.default_rng(seed)
    V = V.copy()
    m = len(F)
    for f in rng.choice(m, int(slivers * m), replace=False):
        a, b, c = F[f]
        t = rng.uniform(0.2, 0.8)
        foot = V[b] + t * (V[c] - V[b])
        V[a] = foot + squeeze * (V[a] - foot)
    for f in rng.choice(m, int(needles * m), replace=False):
        a, b, _ = F[f]
        V[a] = V[b] + squeeze * (V[a] - V[b])
    return V


def split_edge(V: np.ndarray, F: np.ndarray, f: int, t: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Edge (a, b) = (F[f,0], F[f,1]) split at ``t`` by a new vertex p on it, in face f only, as a repair that
    closes a T-junction leaves it (issue 45): f = (a, b, c) becomes (a, p, c) and (p, b, c), and the zero-area face
    (p, a, b) closes the gap to the face across a-b (unchanged). Manifold and oriented, one zero-area face (collinear
    corners, no zero-length edge). V (n+1,3), F (m+2,3)."""
    a, b, c = (int(x) for x in F[f])
    p = len(V)
    V = np.vstack([V, V[a] + t * (V[b] - V[a])])
    F = np.vstack([F, [[p, b, c], [p, a, b]]]).astype(np.int64)
    F[f] = [a, p, c]
    return V, F


def collinear_corner(V: np.ndarray, F: np.ndarray, f: int) -> np.ndarray:
    """A copy of V with corner 0 of face f moved to the midpoint of the opposite edge: face f's three corners
    collinear, the faces around it stretched (issue 45). (n,3)."""
    V = V.copy()
    V[F[f, 0]] = 0.5 * (V[F[f, 1]] + V[F[f, 2]])
    return V


def ply_bytes(V: np.ndarray, faces: list | None = None, strips: list | None = None, fmt: str = "ascii",
              vtype: str = "float", index_name: str = "vertex_indices", extra: bool = True) -> bytes:
    """A PLY file as exporters write them (issue 45): ``fmt`` ascii, binary_little_endian or binary_big_endian;
    vertices x, y, z of ``vtype`` (float or double), with extra properties (a normal, a colour) when ``extra``;
    a ``face`` element of polygons ``faces`` (lists of indices, with a uchar flag after the list when ``extra``)
    and / or a ``tristrips`` element of one row per strip (int lists, -1 restarts), the list named ``index_name``;
    neither: a point cloud."""
    head = [f"ply\nformat {fmt} 1.0\ncomment made by a scanner\nelement vertex {len(V)}"]
    head += [f"property {vtype} {c}" for c in "xyz"]
    head += ["property float nx", "property uchar red"] if extra else []
    if faces is not None:
        head += [f"element face {len(faces)}", f"property list uchar int {index_name}"]
        head += ["property uchar flags"] if extra else []
    if strips is not None:
        head += [f"element tristrips {len(strips)}", f"property list int int {index_name}"]
    head = ("\n".join(head) + "\nend_header\n").encode()
    rows = [[*(float(x) for x in v), *([0.5, 7] if extra else [])] for v in V]
    lists = [[len(f), *f, *([1] if extra else [])] for f in faces or []] + [[len(s), *s] for s in strips or []]
    if fmt == "ascii":
        return head + "".join(" ".join(map(repr, r)) + "\n" for r in rows + lists).encode()
    e = "<" if fmt == "binary_little_endian" else ">"
    vfmt = e + ("3f" if vtype == "float" else "3d") + ("fB" if extra else "")
    body = b"".join(struct.pack(vfmt, *r) for r in rows)
    nf = len(faces or [])
    body += b"".join(struct.pack(e + f"B{len(r) - 1 - extra}i" + ("B" if extra else ""), *r) for r in lists[:nf])
    body += b"".join(struct.pack(e + f"i{len(s)}i", len(s), *s) for s in strips or [])
    return head + body


#: what no message may show (issue 45): Python's None, an object repr or address, an exception's class name, a nan
#: where a number belongs, a traceback
LEAKED = re.compile(r"\bNone\b|<[A-Za-z_][\w.]*( object|:| at 0x|>)|0x[0-9a-f]{6,}|\b\w*(Error|Exception|Warning)\b"
                    r"|\bnan\b|Traceback")


def leaked(message: str, *given) -> list[str]:
    """The parts of ``message`` that no message may show (LEAKED), once the values a user gave (echoed back as given:
    "got nan") are taken out."""
    for g in given:
        message = message.replace(repr(g), "").replace(str(g), "")
    return [m.group(0) for m in LEAKED.finditer(message)]
