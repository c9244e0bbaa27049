"""Record the maps of every mesh that flattens (../shared/meshes and the generated surfaces), default options and
``refine="none"``, so that a restructuring of the code can be shown to leave them unchanged.

    python tests/baseline/record.py            # writes tests/baseline/maps.npz and maps.json

Run it only on purpose (it overwrites the reference); ``tests/test_baseline.py`` compares against it.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SHARED = HERE.parents[2] / "shared" / "meshes"
MESHES = ("camelhead.off", "halftunnel.off", "beetle.off", "bump-domain.obj", "woody.obj")
SHAPES = ("cylinder_patch", "cylinder_with_holes", "cone_s_strip", "curved_cap_with_holes", "flat_disk",
          "flat_square")
MODES = {"default": {}, "raw": {"refine": "none"}}
#: report metrics compared (the rest of the report holds timings and machine facts)
METRICS = ("flips", "boundary_crossings", "iso_mean", "iso_p95", "bijective", "stress_rel_rms")


def cases(load: bool = True, only: str | None = None):
    """(name, V, F) of every recorded surface (``load=False``: V, F None; ``only``: that one)."""
    try:
        from heatparam import datasets
        from heatparam.formats import load_mesh
    except ImportError:  # the layout before issue 13 (the reference was recorded with it)
        from heatparam.io import load_mesh

        from heatparam import shapes as datasets

    for name in MESHES:
        if only in (None, name):
            yield (name, *(load_mesh(SHARED / name) if load else (None, None)))
    for name in SHAPES:
        if only in (None, f"generated:{name}"):
            s = getattr(datasets, name)() if load else None
            yield f"generated:{name}", *((s.V, s.F) if load else (None, None))


def environment() -> dict:
    """What the recorded bits depend on besides the code: the CPU (model and instruction-set flags: numpy's
    OpenBLAS and MKL choose their kernels by them) and the numerical libraries' versions. The same code gave maps
    within 1e-8 of the extent but not bit for bit on another machine of this project's kind (stop 19: camelhead,
    halftunnel, beetle, the curved cap; no numpy, scipy or MKL version nor MKL_CBWR setting reproduced the bits)."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    cpu, flags = platform.processor(), ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and not cpu:
                cpu = value.strip()
            if key.strip() == "flags" and not flags:
                flags = hashlib.sha256(" ".join(sorted(value.split())).encode()).hexdigest()[:16]
    except OSError:
        pass
    versions = {}
    for pkg in ("numpy", "scipy", "mkl", "pypardiso", "libigl", "gpytoolbox", "cholespy"):
        try:
            versions[pkg] = version(pkg)
        except PackageNotFoundError:
            versions[pkg] = None
    return {"machine": platform.machine(), "cpu": cpu, "cpu_flags": flags, "packages": versions}


def digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]


def run(V, F, mode: str):
    import heatparam

    r = heatparam.parameterize(V, F, seed=0, **MODES[mode])
    m = r.report["metrics"]
    return r.uv, r.Fuv, {k: m.get(k) for k in METRICS}


def main() -> None:
    arrays, table = {}, {"_environment": environment()}
    for name, V, F in cases():
        for mode in MODES:
            uv, Fuv, met = run(V, F, mode)
            key = f"{name}|{mode}"
            arrays[key] = uv
            table[key] = {"uv_sha": digest(uv), "fuv_sha": digest(np.asarray(Fuv, dtype=np.int64)),
                          "metrics": met}
            print(key, table[key], file=sys.stderr, flush=True)
    np.savez_compressed(HERE / "maps.npz", **arrays)
    (HERE / "maps.json").write_text(json.dumps(table, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
