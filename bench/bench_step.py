"""STEP output measured the way a user checks it (issue 45): written by ``write_step`` at the default
``--fit-tolerance`` (0.1% of the bounding-box diagonal), read back by OpenCascade and compared with the mesh both ways.
A markdown table on stdout, deviations in units of the tolerance.

Usage: ``python bench/bench_step.py [--large] [--profile] [--maps DIR] [case ...]`` (``--maps``: keep each case's
mesh and map in DIR/<case>.npz and reuse them, so that only the STEP output is measured again), or
``python bench/bench_step.py --family SEEDS`` (``1000-1019`` or ``3,7,12``: the generated CAD parts of
``cad_family.draw``, a row per part with the faces a CAD user expects beside the faces written and the acceptance
of issue 45, then the distribution; seeds 0-99 are for tuning, 1000 on are held out). Cases: ``developable``
(``datasets.cylinder_with_holes``), ``camelhead``, ``cap`` (a coarse, strongly curved cap: ``curved_cap_with_holes``
on a sphere of radius 1.4, h 0.06), ``cow`` and ``bunny`` (closed: atlases), ``chamfer`` (a closed box with a 45°
chamfer along one edge: creases of 90° and 45°) and ``fandisk`` (a closed extrusion of a profile with a circular arc
between two chamfers: creases of 29°, 59° and 90°, and a smooth bend), ``head`` (camelhead decimated by
``igl.decimate`` to 2.9k faces and flattened with ``seams="none"``: the issue's coarse, strongly curved open head,
whose surface rippled 0.38% off the mesh with +2.1% area). ``--large`` adds camelhead upsampled to ~90k faces and
``cad100k``, a generated CAD part (``cad_family`` seed 3) meshed uniformly to ~100k faces (fit time and memory).
``--profile``: a cProfile of each ``write_step`` call, its top functions by cumulative time on stderr. The two CAD
parts check the crease rule (``step._creases``).

Measures, per case:

- **surface → mesh**: the read-back shape tessellated by ``BRepMesh_IncrementalMesh`` (linear deflection 0.1
  tolerance, angular 0.5 rad, on a copy of low tolerances: ``step.tessellation``), the distance of every
  tessellation node (on the surface, inside the trims) to the mesh (``igl.point_mesh_squared_distance``): max and
  99th percentile;
- **mesh → surface**: the distance of every vertex of a triangle (the bunny has 1113 unreferenced ones) to that
  tessellation (an estimate within the deflection, 0.1 tolerance, of the distance to the surface);
- area of the read-back shape against the mesh's; ``BRepCheck_Analyzer`` on the shape and on every face; shells and
  free edges (edges with one face; a closed mesh should give one shell and none), solids (a closed one is written as
  a solid);
- the seconds of ``write_step`` (fit, trim, sew, write), the process's peak resident memory while it ran (sampled
  every 20 ms by a thread) and the number of warnings it returned.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import cad_family
import numpy as np
from common import SHARED, load, machine, seeds, upsampled_camelhead

import heatparam
from heatparam import datasets
from heatparam.formats import load_mesh
from heatparam.formats.step import _closed, _count, _topology, read_step, tessellation, write_step

DEFLECTION = 0.1  # x tolerance


def _weld(V: np.ndarray, F: np.ndarray, digits: int = 9) -> tuple[np.ndarray, np.ndarray]:
    key = np.round(V, digits)
    U, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    F = inv.reshape(-1)[F]
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]
    used, F = np.unique(F, return_inverse=True)
    return V[first][used], F.reshape(-1, 3)


def extrusion(profile: np.ndarray, depth: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed prism: the counter-clockwise (k,2) profile loop (x, z) extruded along y over ``depth``, capped by
    ``datasets.mesh_domain`` triangulations of the profile; outward oriented."""
    uv, Fc = datasets.mesh_domain([profile], h)
    k = len(profile)
    ny = max(1, int(np.ceil(depth / h)))
    ys = np.linspace(0.0, depth, ny + 1)
    side = np.array([[x, y, z] for y in ys for x, z in profile])
    quads = [(j * k + i, j * k + (i + 1) % k, (j + 1) * k + (i + 1) % k, (j + 1) * k + i)
             for j in range(ny) for i in range(k)]
    Fs = np.array([(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads])
    front = np.column_stack([uv[:, 0], np.zeros(len(uv)), uv[:, 1]])  # y = 0, outward -y
    back = np.column_stack([uv[:, 0], np.full(len(uv), depth), uv[:, 1]])
    V = np.vstack([side, front, back])
    n1, n2 = len(side), len(side) + len(uv)
    F = np.vstack([Fs[:, ::-1], Fc + n1, Fc[:, ::-1] + n2])
    V, F = _weld(V, F)
    # outward: the signed volume positive
    vol = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum()
    return V, (F if vol > 0 else F[:, ::-1])


def _polyline(points, h: float) -> np.ndarray:
    """Samples at spacing <= h along the open polyline through ``points``, the last point excluded."""
    from heatparam.datasets import _segment

    return np.vstack([_segment(points[i], points[i + 1], h) for i in range(len(points) - 1)])


def fandisk_like(h: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    """Profile: a 2 x 0.6 block, chamfers at both top corners and a circular-arc hump (chord 1, 120°) between them,
    extruded 1.2: creases of 90° (block), 59° (block/chamfer) and 29° (chamfer/arc)."""
    from heatparam.datasets import _arc

    a = np.deg2rad(60.0)
    r = 0.5 / np.sin(a)
    arc = _arc((1.0, 0.9 - r * np.cos(a)), r, np.pi / 2 - a, np.pi / 2 + a, h)  # (1.5, 0.9) -> (0.5, 0.9)
    profile = np.vstack([_polyline([(0.0, 0.0), (2.0, 0.0), (2.0, 0.6), (1.5, 0.9)], h), arc,
                         _polyline([(0.5, 0.9), (0.0, 0.6), (0.0, 0.0)], h)])
    return extrusion(profile, 1.2, h)


def chamfered_box(h: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A 1.6 x 1.0 x 0.8 box (extruded along y) with a 45° chamfer of 0.3 along one top edge."""
    from heatparam.datasets import polygon

    profile = polygon(np.array([[0.0, 0.0], [1.6, 0.0], [1.6, 0.5], [1.3, 0.8], [0.0, 0.8]]), h)
    return extrusion(profile, 1.0, h)


def _case(name: str):
    if name == "developable":
        V, F, _ = load("cylinder_with_holes")
        return V, F
    if name == "cap":
        s = datasets.curved_cap_with_holes(sphere_radius=1.4, h=0.06)
        return s.V, s.F
    if name == "camelhead":
        return load_mesh(SHARED / "camelhead.off")
    if name == "cow":
        return load_mesh(SHARED / "cow.off")
    if name == "bunny":
        return load_mesh(SHARED / "stanford-bunny.obj")
    if name == "chamfer":
        return chamfered_box()
    if name == "fandisk":
        return fandisk_like()
    if name == "camelhead100k":
        return upsampled_camelhead(60_000)
    if name == "cad100k":  # a generated CAD part (cad_family seed 3: a notch, chamfers, fillets) at ~100k faces
        V, F, _, _ = cad_family.draw(3, faces=85_000)
        return V, F
    if name == "head":
        import igl

        V, F = load_mesh(SHARED / "camelhead.off")
        U, G, _, _ = igl.decimate(V, F, 2900)
        return U, G
    raise SystemExit(f"unknown case {name}")


def measure(path, V: np.ndarray, F: np.ndarray, tol: float) -> dict:
    import igl
    from OCP.BRepCheck import BRepCheck_Analyzer

    from heatparam.formats.step import _area

    shape, _ = read_step(path)
    tess = tessellation(shape, DEFLECTION * tol)
    per_face, nodes, tris, invalid, empty = [], [], [], 0, 0
    off = 0
    for face, P, T in tess:
        invalid += not BRepCheck_Analyzer(face).IsValid()
        if not len(P):
            empty += 1
            continue
        d2, _, _ = igl.point_mesh_squared_distance(P, V, F)
        per_face.append(np.sqrt(d2))
        nodes.append(P)
        tris.append(T + off)
        off += len(P)
    s2m = np.concatenate(per_face)
    d2, _, _ = igl.point_mesh_squared_distance(V[np.unique(F)], np.vstack(nodes), np.vstack(tris))  # used ones
    m2s = np.sqrt(d2)
    mesh_area = float(0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum())
    shells, free = _topology(shape)
    solids = _count(shape, "SOLID")
    return {"s2m_max": s2m.max() / tol, "s2m_p99": np.percentile(s2m, 99) / tol, "m2s_max": m2s.max() / tol,
            "m2s_p99": np.percentile(m2s, 99) / tol, "area": 100 * (_area(shape) / mesh_area - 1),
            "valid": BRepCheck_Analyzer(shape).IsValid(), "invalid_faces": invalid, "untessellated": empty,
            "faces": len(tess), "shells": shells, "free_edges": free, "solids": solids,
            "worst_face": float(max(f.max() for f in per_face) / tol)}


class PeakRSS:
    """The largest resident set size of this process (MB) while a ``with`` block runs, sampled by a thread."""

    def __enter__(self):
        import threading

        import psutil

        self.proc, self.peak, self.done = psutil.Process(), 0.0, threading.Event()
        self.thread = threading.Thread(target=self._sample, daemon=True)
        self.thread.start()
        return self

    def _sample(self) -> None:
        while not self.done.wait(0.02):
            self.peak = max(self.peak, self.proc.memory_info().rss / 2**20)

    def __exit__(self, *exc):
        self.done.set()
        self.thread.join()
        self.peak = max(self.peak, self.proc.memory_info().rss / 2**20)


def _timed_write(out: Path, V, F, uv, Fuv, uv_vertex, chart, profile: bool) -> tuple[dict, float, float]:
    """write_step's report, seconds and peak resident MB; with ``profile`` its cProfile's top 25 on stderr."""
    import cProfile
    import pstats

    prof = cProfile.Profile() if profile else None
    with PeakRSS() as mem:
        t = time.perf_counter()
        if prof:
            prof.enable()
        rep = write_step(out, V, F, uv, Fuv, uv_vertex, chart=chart)
        if prof:
            prof.disable()
        sec = time.perf_counter() - t
    if prof:
        pstats.Stats(prof, stream=sys.stderr).sort_stats("cumulative").print_stats(25)
    return rep, sec, mem.peak


def _mapped(name: str, maps: Path | None):
    """(V, F, uv, Fuv, uv_vertex, chart or None) of a case, from ``maps``/<name>.npz when there."""
    cached = maps / f"{name}.npz" if maps else None
    if cached and cached.exists():
        z = np.load(cached)
        return tuple(z[k] if k in z else None for k in ("V", "F", "uv", "Fuv", "uv_vertex", "chart"))
    V, F = _case(name)
    r = heatparam.parameterize(V, F, seams="none") if name == "head" else heatparam.parameterize(V, F)
    chart = getattr(r, "chart", None)
    if cached:
        maps.mkdir(parents=True, exist_ok=True)
        extra = {} if chart is None else {"chart": chart}
        np.savez(cached, V=V, F=F, uv=r.uv, Fuv=r.Fuv, uv_vertex=r.uv_vertex, **extra)
    return V, F, r.uv, r.Fuv, r.uv_vertex, chart


FAMILY_HEAD = ("| seed | part | faces (mesh) | expected faces | STEP faces | creases | splits | s→m max | s→m p99 "
               "| m→s max | m→s p99 | area % | valid | invalid faces | unmeshed faces | shells | free edges | solids "
               "| warnings | map s | write_step s | accepted |")


def _accepted(m: dict, warnings: int) -> str:
    """The issue's acceptance for one part: "yes", or what fails; a miss over the tolerance without a warning is
    a silent miss."""
    fails = [f"{k} {m[k]:.2f}" for k in ("s2m_max", "m2s_max") if m[k] > 1.5]
    fails += [f"area {m['area']:+.2f}%"] if abs(m["area"]) > 1.0 else []
    fails += [] if m["valid"] and not m["invalid_faces"] else ["invalid"]
    fails += [f"{m['untessellated']} faces not meshed by OpenCascade"] if m["untessellated"] else []
    fails += [] if (m["shells"], m["free_edges"], m["solids"]) == (1, 0, 1) else ["not one closed solid"]
    fails += ["silent miss"] if max(m["s2m_max"], m["m2s_max"]) > 1.0 and not warnings else []
    return "yes" if not fails else "NO: " + ", ".join(fails)


def family(drawn: list[int]) -> None:
    """The per-part table of the generated CAD parts (``cad_family.draw``) and the distribution over them."""
    print(f"# STEP of generated CAD parts (cad_family seeds {drawn[0]}-{drawn[-1]}) — {time.strftime('%Y-%m-%d')} "
          f"— {machine()}\n")
    print(FAMILY_HEAD)
    print("|" + "---|" * FAMILY_HEAD.count(" | ") + "---|")
    rows = []
    for seed in drawn:
        V, F, desc, expected = cad_family.draw(seed)
        t = time.perf_counter()
        r = heatparam.parameterize(V, F)
        t_map = time.perf_counter() - t
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / f"part{seed}.step"
            t = time.perf_counter()
            rep = write_step(out, V, F, r.uv, r.Fuv, r.uv_vertex, chart=getattr(r, "chart", None))
            sec = time.perf_counter() - t
            m = measure(out, V, F, rep["tolerance"])
        ok = _accepted(m, len(rep["warnings"]))
        rows.append((m, sec, m["faces"] - expected["faces"], ok == "yes"))
        print(f"| {seed} | {desc} | {len(F)} | {expected['faces']} | {m['faces']} | {rep['creases']} "
              f"| {rep['tolerance_splits']} | {m['s2m_max']:.2f} | {m['s2m_p99']:.2f} | {m['m2s_max']:.2f} "
              f"| {m['m2s_p99']:.2f} | {m['area']:+.2f} | {'yes' if m['valid'] else 'NO'} | {m['invalid_faces']} "
              f"| {m['untessellated']} | {m['shells']} | {m['free_edges']} | {m['solids']} | {len(rep['warnings'])} "
              f"| {t_map:.1f} | {sec:.1f} | {ok} |", flush=True)
        for w in rep["warnings"]:
            print(f"  <!-- seed {seed}: {w} -->", file=sys.stderr)
    _distribution(rows)


def _distribution(rows: list[tuple]) -> None:
    print(f"\n{sum(r[3] for r in rows)} of {len(rows)} parts accepted\n")
    print("| over the parts | s→m max | m→s max | abs(area) % | write_step s | STEP faces − expected |")
    print("|---|---|---|---|---|---|")
    cols = [[r[0]["s2m_max"] for r in rows], [r[0]["m2s_max"] for r in rows], [abs(r[0]["area"]) for r in rows],
            [r[1] for r in rows], [r[2] for r in rows]]
    print("| median | " + " | ".join(f"{np.median(c):.2f}" for c in cols) + " |")
    print("| worst | " + " | ".join(f"{max(c, key=abs):.2f}" for c in cols) + " |")
    print(f"| parts with more / fewer / the expected faces | | | | | {sum(c > 0 for c in cols[4])} / "
          f"{sum(c < 0 for c in cols[4])} / {sum(c == 0 for c in cols[4])} |")


def main(argv: list[str]) -> None:
    if "--family" in argv:
        family(seeds(argv[argv.index("--family") + 1]))
        return
    maps = Path(argv[argv.index("--maps") + 1]) if "--maps" in argv else None
    argv = [a for i, a in enumerate(argv) if a != "--maps" and (i == 0 or argv[i - 1] != "--maps")]
    names = [a for a in argv if not a.startswith("--")] or [
        "developable", "camelhead", "cap", "cow", "bunny", "chamfer", "fandisk", "head"]
    if "--large" in argv:
        names += ["camelhead100k", "cad100k"]
    print(f"# STEP read back vs mesh — {time.strftime('%Y-%m-%d')} — {machine()}\n")
    print("deviations in units of the fit tolerance (0.1% of the diagonal); s→m: tessellation nodes of the read-back "
          f"shape to the mesh, m→s: mesh vertices to that tessellation (deflection {DEFLECTION} tol)\n")
    print("| case | faces (mesh) | closed | charts | STEP faces | s→m max | s→m p99 | m→s max | m→s p99 | area % "
          "| valid | invalid faces | unmeshed faces | shells | free edges | solids | warnings | write_step s "
          "| peak MB (write_step) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        V, F, uv, Fuv, uv_vertex, chart = _mapped(name, maps)
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / f"{name}.step"
            rep, sec, peak = _timed_write(out, V, F, uv, Fuv, uv_vertex, chart, "--profile" in argv)
            m = measure(out, V, F, rep["tolerance"])
        print(f"| {name} | {len(F)} | {'yes' if _closed(F) else 'no'} | {len(rep['charts'])} | {m['faces']} "
              f"| {m['s2m_max']:.2f} | {m['s2m_p99']:.2f} | {m['m2s_max']:.2f} | {m['m2s_p99']:.2f} | {m['area']:+.2f} "
              f"| {'yes' if m['valid'] else 'NO'} | {m['invalid_faces']} | {m['untessellated']} | {m['shells']} "
              f"| {m['free_edges']} | {m['solids']} "
              f"| {len(rep['warnings'])} | {sec:.1f} | {peak:.0f} |", flush=True)
        if "max_surface_deviation" in rep:  # what write_step itself measured and reports
            print(f"  <!-- {name}: reported max {rep['max_deviation'] / rep['tolerance']:.2f} tol (vertices "
                  f"{rep['max_vertex_deviation'] / rep['tolerance']:.2f}, surface "
                  f"{rep['max_surface_deviation'] / rep['tolerance']:.2f}), {rep.get('creases')} crease edges, "
                  f"{rep.get('slit_cuts')} slit cuts, {rep.get('tolerance_splits')} splits for the tolerance -->",
                  file=sys.stderr)
        for w in rep["warnings"]:
            print(f"  <!-- {name}: {w} -->", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1:])
