"""Shared fixtures: small generated meshes and the public test meshes in ../shared/meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import Delaunay

SHARED_MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"


def imports_numba(code: str) -> bool:
    """Whether running ``code`` in a fresh interpreter imports numba (0.1-0.5 s a process)."""
    import subprocess
    import sys

    code += "\nimport sys\nprint('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return out.stdout.strip() == "True"


def shared_mesh(name: str) -> Path:
    p = SHARED_MESHES / name
    if not p.exists():
        pytest.skip(f"{p} not found (the shared test meshes live beside the repo)")
    return p


def flat_disk(n_ring: int = 24, radius: float = 1.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """An irregular Delaunay triangulation of a flat disk (z = 0), counter-clockwise faces."""
    rng = np.random.default_rng(seed)
    pts = [np.zeros((1, 2))]
    for r in range(1, n_ring + 1):
        rad = radius * r / n_ring
        k = max(6, int(round(2 * np.pi * r)))
        a = np.linspace(0, 2 * np.pi, k, endpoint=False) + rng.uniform(0, 2 * np.pi)
        jitter = 0.0 if r == n_ring else 0.25 * radius / n_ring
        p = np.column_stack([rad * np.cos(a), rad * np.sin(a)]) + rng.uniform(-jitter, jitter, (k, 2))
        pts.append(p)
    P = np.concatenate(pts)
    F = Delaunay(P).simplices.astype(np.int64)
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[cw] = F[cw][:, ::-1]
    return np.column_stack([P, np.zeros(len(P))]), F


@pytest.fixture(scope="session")
def disk():
    return flat_disk()


def excess_cone(rings: int = 8, sectors: int = 64, wave: float = 0.35, k: int = 5):
    """A cone over a wavy closed curve on the unit sphere (apex angle ~1.6 × 2π), cut open along one generator: a
    disk whose isometric layout, a sector wider than 2π, overlaps itself."""
    psi = np.linspace(0.0, 2 * np.pi, sectors + 1)
    c = np.column_stack([np.cos(psi), np.sin(psi), wave * np.sin(k * psi)])
    c /= np.linalg.norm(c, axis=1)[:, None]
    V = np.vstack([np.zeros((1, 3))] + [r * c for r in np.linspace(0, 1, rings + 1)[1:]])

    def idx(i, j):
        return 1 + i * (sectors + 1) + j

    F = [[0, idx(0, j), idx(0, j + 1)] for j in range(sectors)]
    for i in range(rings - 1):
        for j in range(sectors):
            a, b, cc, d = idx(i, j), idx(i, j + 1), idx(i + 1, j + 1), idx(i + 1, j)
            F += [[a, d, cc], [a, cc, b]]
    return V, np.array(F, dtype=np.int64)


def slit_fan(sectors: int = 12, apex: float = 0.0, turn: float = 2 * np.pi) -> tuple[np.ndarray, np.ndarray]:
    """One ring of triangles around a centre (vertex 0) at height ``apex`` over a rim on the unit circle, cut open
    along the edge from the centre to the rim's first vertex (a second vertex on that ray, 1.2 out, closes the
    ring): a disk. Flat (apex 0) its isometric layout closes the cut, its border touching itself at the centre
    only (the cut's sides of different lengths, as on a CAD part: no two rim edges meet); a cone (apex > 0) has
    less than 2π there. ``turn``: the rim's angle in the plane (the mesh's own flat layout: 2π closes the cut)."""
    psi = np.linspace(0.0, turn, sectors + 1)
    r = np.r_[np.ones(sectors), 1.2]
    V = np.vstack([[0.0, 0.0, apex], np.column_stack([r * np.cos(psi), r * np.sin(psi), np.zeros(sectors + 1)])])
    F = np.array([[0, j + 1, j + 2] for j in range(sectors)], dtype=np.int64)
    return V, F


def with_ear(V: np.ndarray, F: np.ndarray, uv: np.ndarray, fold: bool) -> tuple[np.ndarray, np.ndarray, int]:
    """(V, F) with one more triangle on its border, over the bottom boundary edge nearest a fifth of the width of
    the flat layout ``uv``: a scan's border ear whose tip is a new vertex. ``fold``: the ear is folded under the
    surface (a projection flips it); else its tip is the edge's midpoint (a zero-area face). Returns (V, F, tip)."""
    from heatparam.mesh.topology import boundary_edges

    be = boundary_edges(F)  # oriented as in their faces: the surface on the left in uv
    lo = uv[:, 1].min()
    mid_uv = 0.5 * (uv[be[:, 0]] + uv[be[:, 1]])
    bottom = np.flatnonzero(np.isclose(mid_uv[:, 1], lo, atol=1e-9))
    target = uv[:, 0].min() + 0.2 * np.ptp(uv[:, 0])
    u, w = be[bottom[np.argmin(np.abs(mid_uv[bottom, 0] - target))]]
    face = np.flatnonzero(((F == u) | (F == w)).sum(axis=1) == 2)[0]
    k = [v for v in F[face] if v not in (u, w)][0]
    mid, edge = 0.5 * (V[u] + V[w]), V[w] - V[u]
    inward = V[k] - mid - (V[k] - mid) @ edge / (edge @ edge) * edge
    inward /= np.linalg.norm(inward)
    normal = np.cross(edge, inward)
    normal /= np.linalg.norm(normal)
    L = float(np.linalg.norm(edge))
    tip = mid + (0.4 * L * inward - 0.5 * L * normal if fold else 0.0)
    return np.vstack([V, tip]), np.vstack([F, [w, u, len(V)]]), len(V)


def spiked_cylinder(amp: float = 6.0) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder patch rolled past a half turn (angle 4.5, edge h = 0.06: 2258 vertices) whose border has six
    spikes, every 37th boundary vertex pushed ``amp`` × h outwards: scanner outliers at the border, which fold its
    conformal layout (its projection folds anyway) but not the conformal layout of the surface smoothed."""
    from heatparam import datasets
    from heatparam.mesh.topology import boundary_loops

    s = datasets.cylinder_patch(angle=4.5, h=0.06)
    V = s.V.copy()
    for v in boundary_loops(s.F)[0][::37][:6]:
        radial = V[v] * [1.0, 0.0, 1.0]  # the patch is rolled around the y axis
        V[v] += amp * 0.06 * radial / np.linalg.norm(radial)
    return V, s.F


def assert_corner_lengths_kept(corner_uv: np.ndarray, V: np.ndarray, F: np.ndarray, rtol: float) -> None:
    """Every face's corner-to-corner UV lengths (``corner_uv`` (3m,2), row ``3 f + j``) are its 3D edge lengths: the
    layout of a flat surface is an isometry."""
    U = corner_uv.reshape(-1, 3, 2)
    P = V[F]
    for j in range(3):
        lu = np.linalg.norm(U[:, (j + 1) % 3] - U[:, j], axis=1)
        lp = np.linalg.norm(P[:, (j + 1) % 3] - P[:, j], axis=1)
        np.testing.assert_allclose(lu, lp, rtol=rtol)
