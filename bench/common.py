"""Shared helpers for the benchmarks (not part of the library): mesh generation and isolated runs.

Every measured run happens in a fresh subprocess so that its peak RSS is its own.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"


def machine() -> str:
    import psutil

    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"{psutil.virtual_memory().total / 2**30:.0f} GiB, Python {platform.python_version()}")


def seeds(spec: str) -> list[int]:
    """``1000-1019``, ``0,3,7`` or both mixed, as a list of ints."""
    out: list[int] = []
    for part in spec.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def load(name: str):
    """A generated shape (``heatparam.datasets`` function name) or a ../shared/meshes file: (V, F, uv_true or None)."""
    from heatparam import datasets
    from heatparam.formats import load_mesh

    if hasattr(datasets, name):
        s = getattr(datasets, name)()
        return s.V, s.F, s.uv_true
    V, F = load_mesh(SHARED / name)
    return V, F, None


def upsampled_camelhead(target: int) -> tuple[np.ndarray, np.ndarray]:
    """camelhead.off, midpoint-subdivided (igl.upsample) until it has about ``target`` vertices."""
    import igl

    from heatparam.formats import load_mesh

    V, F = load_mesh(SHARED / "camelhead.off")
    while len(V) * 4 <= target * 1.5:
        V, F = igl.upsample(V, F)
    return V, F


def run_isolated(code: str, payload: dict) -> dict:
    """Run ``code`` in a fresh Python; it reads ``payload`` from sys.argv[1] (JSON) and prints one JSON line."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as fh:
        json.dump(payload, fh)
    try:
        r = subprocess.run([sys.executable, "-c", code, fh.name], capture_output=True, text=True)
    finally:
        os.unlink(fh.name)
    if r.returncode != 0:
        return {"error": (r.stderr.strip().splitlines() or ["failed"])[-1]}
    return json.loads(r.stdout.strip().splitlines()[-1])


PEAK_RSS = """
import resource, sys
def peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
"""


def noisy_cylinder_patch(target: int, sigma: float, draw: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A generated cylinder patch of about ``target`` vertices with scanner-like noise: the ``draw``-th
    (n,3) standard normal field of seed 0 times ``sigma`` × the mean edge length, added to the vertices.
    Returns (V, F, uv_true): uv_true is the noise-free flat layout."""
    from heatparam import datasets

    s = datasets.cylinder_patch(h=0.04 * float(np.sqrt(2213 / target)))  # 2213 vertices at the default h
    h = float(np.mean(np.linalg.norm(s.V[s.F[:, 1]] - s.V[s.F[:, 0]], axis=1)))
    rng = np.random.default_rng(0)
    noise = [rng.standard_normal(s.V.shape) for _ in range(draw + 1)][draw]
    return s.V + sigma * h * noise, s.F, s.uv_true

