"""Shared fixtures: small generated meshes and the public test meshes in ../shared/meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import Delaunay

SHARED_MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"


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
