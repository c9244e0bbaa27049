"""``heatparam batch`` on 1 vs 2 local Dask workers: wall time of the whole batch. A markdown table on stdout.

Usage: ``python bench/bench_batch.py [--repeat R] [--heavy | --tiny N]`` — the folder of ``tests/test_batch.py``
(19 meshes: 15 generated shapes at coarse resolution, halftunnel.off, woody.obj and cow.off from ../shared/meshes,
a malformed OBJ and ``part.obj`` in two subfolders); ``--heavy`` adds camelhead.off, beetle.off and
bump-domain.obj so that the pipeline, not the per-mesh process start, dominates; ``--tiny N`` is a folder of N
meshes of at most 320 faces instead (open patches, closed primitives, a torus, with seeded random sizes), where
the per-mesh overhead dominates (the files-per-second figure). Each run is a fresh
``--force`` batch into a new folder; wall time includes starting the LocalCluster. Also printed: the sum of the
meshes' task seconds (each mesh's process, start to end) and the mean per-mesh overhead (task seconds minus the
pipeline's own timings).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from common import SHARED, machine

from heatparam import datasets
from heatparam.batching import run_batch


def _write_obj(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F.tolist()))


def make_folder(root: Path, heavy: bool) -> None:
    """The test folder (same shapes and resolutions as tests/test_batch.py, all written as OBJ here)."""
    gen = {
        "disk": lambda h: datasets.flat_disk(h=h), "square": lambda h: datasets.flat_square(h=h),
        "cylinder": lambda h: datasets.cylinder_patch(h=h), "cylholes": lambda h: datasets.cylinder_with_holes(h=h),
        "cone": lambda h: datasets.cone_s_strip(h=h / 2), "cap": lambda h: datasets.curved_cap_with_holes(h=h),
    }
    for name, make in gen.items():
        for h in (0.15, 0.2):
            s = make(h)
            _write_obj(root / f"generated/{name}_{int(h * 100)}.obj", s.V, s.F)
    big = datasets.scale_shape(datasets.cylinder_patch(h=0.15), 25.0)
    _write_obj(root / "generated/deep/cylinder_mm.obj", big.V, big.F)
    a, b = datasets.flat_disk(h=0.18), datasets.cylinder_with_holes(h=0.14)
    _write_obj(root / "a/part.obj", a.V, a.F)
    _write_obj(root / "b/part.obj", b.V, b.F)
    names = ["halftunnel.off", "woody.obj", "cow.off"] + (["camelhead.off", "beetle.off", "bump-domain.obj"]
                                                         if heavy else [])
    (root / "shared").mkdir()
    for name in names:
        (root / "shared" / name).write_bytes((SHARED / name).read_bytes())
    (root / "bad").mkdir()
    (root / "bad" / "broken.obj").write_text("v 0 0 0\nv 1 0\nf 1 2 three\n")


def make_tiny(root: Path, n: int) -> None:
    """``n`` meshes of at most 320 faces: open patches and closed primitives of seeded random size and shape."""
    import trimesh

    rng = np.random.default_rng(7)
    makers = [
        lambda: _shape(datasets.flat_disk(h=rng.uniform(0.18, 0.3))),
        lambda: _shape(datasets.cylinder_patch(h=rng.uniform(0.22, 0.35))),
        lambda: _shape(datasets.curved_cap_with_holes(h=rng.uniform(0.25, 0.35))),
        lambda: _arrays(trimesh.creation.icosphere(1, radius=rng.uniform(0.5, 2))),
        lambda: _arrays(trimesh.creation.box(rng.uniform(0.5, 2, 3))),
        lambda: _arrays(trimesh.creation.cylinder(rng.uniform(0.5, 1), rng.uniform(1, 3),
                                                  sections=int(rng.integers(8, 24)))),
        lambda: _arrays(trimesh.creation.cone(rng.uniform(0.5, 1), rng.uniform(1, 3),
                                              sections=int(rng.integers(8, 24)))),
        lambda: _arrays(trimesh.creation.torus(1, rng.uniform(0.2, 0.4), 16, 8)),
    ]
    for i in range(n):
        V, F = makers[i % len(makers)]()
        assert len(F) <= 320, (i, len(F))
        _write_obj(root / f"tiny/{i:03d}.obj", V, F)


def _shape(s) -> tuple[np.ndarray, np.ndarray]:
    return s.V, s.F


def _arrays(m) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--heavy", action="store_true")
    ap.add_argument("--tiny", type=int, default=0, metavar="N")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "meshes"
        if args.tiny:
            make_tiny(root, args.tiny)
        else:
            make_folder(root, args.heavy)
        n = sum(1 for p in root.rglob("*") if p.is_file())
        print(f"# heatparam batch, 1 vs 2 workers — {time.strftime('%Y-%m-%d')} — {machine()}\n")
        print(f"{n} meshes{' (with --heavy)' if args.heavy else ''}, LocalCluster of single-threaded worker "
              "processes, --force each run.\n")
        print("| workers | run | wall s | ok | refused | failed | sum of task s | mean per-mesh overhead s |")
        print("|---|---|---|---|---|---|---|---|")
        best = {}
        for run in range(args.repeat):
            for workers in (1, 2):
                out = Path(tmp) / f"out{workers}-{run}"
                t = time.perf_counter()
                s = run_batch([root], out, workers=workers, force=True)
                wall = time.perf_counter() - t
                best[workers] = min(best.get(workers, np.inf), wall)
                task_s = sum(r["seconds"] for r in s["rows"])
                over = []
                for r in s["rows"]:
                    if r["status"] == "ok":
                        rep = json.loads((out / r["output"]).with_suffix(".json").read_text())
                        over.append(r["seconds"] - sum(rep["timings_s"].values()))
                c = s["counts"]
                print(f"| {workers} | {run + 1} | {wall:.1f} ({n / wall:.1f} files/s) | {c['ok']} | {c['refused']} | "
                      f"{c['failed']} | {task_s:.1f} | {np.mean(over):.2f} |", flush=True)
        print(f"\nwall time ratio 1 worker / 2 workers (best of {args.repeat}): {best[1] / best[2]:.2f}")


if __name__ == "__main__":
    main()
