"""``heatparam batch`` over the real-file corpus (``bench/corpus.py``), every map judged independently.

Usage: ``python bench/bench_corpus.py [CORPUS] [--out OUT] [--workers 2] [--task-timeout 900] [--resume]
[--xatlas]`` — CORPUS defaults to ``bench/_corpus`` (build it first: ``python bench/corpus.py``).

Runs ``heatparam batch CORPUS -o OUT --workers N --task-timeout S --force`` (what a user runs), then reads
``OUT/summary.json`` for each file's outcome (flattened: charts, iso mean, seconds; refused or failed: the
one-line message) and judges every output OBJ with its own reader and geometry, not heatparam's:

- flips: UV triangles whose signed area has the opposite sign of their chart's total (charts = the connected
  pieces of the UV faces, sharing ``vt`` indices), among those not collapsed;
- collapsed: UV area at most 1e-9 × the file's median UV/3D area ratio × the 3D area, where the 3D area is not
  zero (over 1e-12 × the bbox diagonal²); zero-area 3D faces are counted apart (degenerate input);
- overlaps: pairs of UV triangles (non-degenerate) whose interiors meet, within a chart or across charts —
  candidates from a uniform grid over their bounding boxes, then exact tests: a proper crossing of two edges, or a
  corner or the centroid of one strictly inside the other (orientation signs in float64; shared corners are the
  same numbers, so neighbours touch without counting); each pair flagged gets its intersection area in exact
  rational arithmetic, and one no thicker than 8 ulps of the UV coordinates across the pair's bounding box (a
  line two faces share, written one ulp apart after the charts were moved) is counted apart as rounding.

Prints markdown: counts by outcome, the refusals and failures with their messages, files with flips / overlaps /
collapsed faces, the total time. ``--xatlas`` runs xatlas (pip xatlas) on each flattened file's input in the same
run and judges its maps the same way.
"""

from __future__ import annotations

import argparse
import collections
import datetime
import json
import subprocess
import sys
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
from common import machine

DEFAULT_CORPUS = Path(__file__).resolve().parent / "_corpus"


def read_uv_obj(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A plain OBJ reader for ``v``, ``vt`` and ``f v/vt`` (polygons fan-split): V (n,3), UV (t,2), F (m,3),
    FT (m,3), 0-based."""
    rows: dict[str, list[str]] = {"v": [], "vt": [], "f": []}
    with open(path) as fh:
        for line in fh:
            key = line.split(" ", 1)[0]
            if key in rows:
                rows[key].append(line)
    V = np.array(" ".join(" ".join(r.split()[1:4]) for r in rows["v"]).split(), dtype=np.float64).reshape(-1, 3)
    UV = np.array(" ".join(" ".join(r.split()[1:3]) for r in rows["vt"]).split(), dtype=np.float64).reshape(-1, 2)
    tok = [r.split()[1:] for r in rows["f"]]
    if all(len(t) == 3 for t in tok):
        c = np.array(" ".join(" ".join(t) for t in tok).replace("/", " ").split(), dtype=np.int64)
        c = c.reshape(len(tok), 3, -1)
        F, FT = c[:, :, 0], c[:, :, 1]
    else:
        F, FT = [], []
        for t in tok:
            c = [s.split("/") for s in t]
            for j in range(1, len(c) - 1):
                F.append([int(c[0][0]), int(c[j][0]), int(c[j + 1][0])])
                FT.append([int(c[0][1]), int(c[j][1]), int(c[j + 1][1])])
        F, FT = np.asarray(F, dtype=np.int64).reshape(-1, 3), np.asarray(FT, dtype=np.int64).reshape(-1, 3)
    F = np.where(F < 0, F + len(V), F - 1)
    FT = np.where(FT < 0, FT + len(UV), FT - 1)
    return V, UV, F, FT


def components(FT: np.ndarray, n: int) -> np.ndarray:
    """Chart id per face (m,): faces joined through shared UV vertex indices."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(FT)
    rows = np.repeat(np.arange(m), 3)
    A = coo_matrix((np.ones(3 * m), (rows, FT.ravel() + m)), shape=(m + n, m + n))
    _, lab = connected_components(A, directed=False)
    return lab[:m]


def orient(ax, ay, bx, by, cx, cy):
    """Twice the signed area of (a, b, c), elementwise."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def candidate_pairs(P: np.ndarray) -> np.ndarray:
    """Pairs (k,2), i < j, of triangles P (m,3,2) whose bounding boxes meet, found through a uniform grid."""
    m = len(P)
    if m < 2:
        return np.zeros((0, 2), dtype=np.int64)
    lo, hi = P.min(axis=1), P.max(axis=1)
    cell = max(float(np.median(hi - lo)) * 2.0, 1e-300)
    g0 = np.floor((lo - lo.min(axis=0)) / cell).astype(np.int64)
    g1 = np.floor((hi - lo.min(axis=0)) / cell).astype(np.int64)
    span = np.minimum(g1 - g0 + 1, 64)  # a huge triangle is clamped: its pairs still come from its own cells
    cnt = span[:, 0] * span[:, 1]
    tri = np.repeat(np.arange(m), cnt)
    k = np.arange(len(tri)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    cx = g0[tri, 0] + k % span[tri, 0]
    cy = g0[tri, 1] + k // span[tri, 0]
    key = cx * (int(g1[:, 1].max()) + 2) + cy
    order = np.lexsort((tri, key))
    key, tri = key[order], tri[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    size = np.diff(np.r_[start, len(key)])
    end = np.repeat(start + size, size)
    after = end - np.arange(len(key)) - 1
    first = np.repeat(np.arange(len(key)), after)
    second = first + 1 + np.arange(len(first)) - np.repeat(np.cumsum(after) - after, after)
    a, b = tri[first], tri[second]
    code = np.sort(np.minimum(a, b) * m + np.maximum(a, b))
    code = code[np.r_[True, code[1:] != code[:-1]]]  # one pair met in several cells is tested once
    i, j = code // m, code % m
    pairs = np.stack([i, j], axis=1)
    meet = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    return pairs[meet]


def _strictly_inside(P: np.ndarray, Q: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(k,) whether pts (k,2) lie strictly inside triangles Q (k,3,2) of either orientation."""
    s = [orient(Q[:, a, 0], Q[:, a, 1], Q[:, b, 0], Q[:, b, 1], pts[:, 0], pts[:, 1])
         for a, b in ((0, 1), (1, 2), (2, 0))]
    return ((s[0] > 0) & (s[1] > 0) & (s[2] > 0)) | ((s[0] < 0) & (s[1] < 0) & (s[2] < 0))


def overlapping(P: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(k,) whether the interiors of triangles P[i], P[j] (each (3,2)) meet, for pairs (k,2)."""
    A, B = P[pairs[:, 0]], P[pairs[:, 1]]
    hit = np.zeros(len(pairs), dtype=bool)
    for a in range(3):
        p, q = A[:, a], A[:, (a + 1) % 3]
        for b in range(3):
            r, s = B[:, b], B[:, (b + 1) % 3]
            d1 = orient(p[:, 0], p[:, 1], q[:, 0], q[:, 1], r[:, 0], r[:, 1])
            d2 = orient(p[:, 0], p[:, 1], q[:, 0], q[:, 1], s[:, 0], s[:, 1])
            d3 = orient(r[:, 0], r[:, 1], s[:, 0], s[:, 1], p[:, 0], p[:, 1])
            d4 = orient(r[:, 0], r[:, 1], s[:, 0], s[:, 1], q[:, 0], q[:, 1])
            hit |= (d1 * d2 < 0) & (d3 * d4 < 0)
    for X, Y in ((A, B), (B, A)):
        for c in range(3):
            hit |= _strictly_inside(X, Y, X[:, c])
        hit |= _strictly_inside(X, Y, X.mean(axis=1))
    return hit


def _clip_area(A: list, B: list) -> Fraction:
    """Exact area of the intersection of triangles A and B (3 (x, y) Fractions each): A clipped by B's edges."""
    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    if cross(*B) < 0:
        B = B[::-1]
    poly = list(A)
    for k in range(3):
        p, q = B[k], B[(k + 1) % 3]
        out = []
        for i, cur in enumerate(poly):
            prev = poly[i - 1]
            dc, dp = cross(p, q, cur), cross(p, q, prev)
            if (dc >= 0) != (dp >= 0):
                t = dp / (dp - dc)
                out.append((prev[0] + t * (cur[0] - prev[0]), prev[1] + t * (cur[1] - prev[1])))
            if dc >= 0:
                out.append(cur)
        poly = out
        if not poly:
            return Fraction(0)
    return abs(sum(poly[i - 1][0] * poly[i][1] - poly[i][0] * poly[i - 1][1] for i in range(len(poly)))) / 2


def exact_overlap_areas(P: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(k,) exact intersection areas of the pairs the float test flagged (every float is a fraction): a corner on
    an edge, or collinear edges, can round either way in float64."""
    tri = [[(Fraction(float(x)), Fraction(float(y))) for x, y in t] for t in P]
    return np.array([float(_clip_area(tri[i], tri[j])) for i, j in pairs])


def judge(V: np.ndarray, UV: np.ndarray, F: np.ndarray, FT: np.ndarray) -> dict:
    """Flips, collapsed faces, overlapping pairs (within / across charts) of one map, by the rules above."""
    P = UV[FT]
    a_uv = 0.5 * orient(P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1], P[:, 2, 0], P[:, 2, 1])
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    a3 = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) if len(V) else 0.0
    real = a3 > 1e-12 * diag**2
    ratio = float(np.median(np.abs(a_uv[real]) / a3[real])) if real.any() else 1.0
    collapsed = real & (np.abs(a_uv) <= 1e-9 * ratio * a3)
    chart = components(FT, len(UV))
    total = np.bincount(chart, weights=a_uv)
    live = np.abs(a_uv) > 1e-9 * ratio * np.maximum(a3, 1e-300)
    flips = live & (np.sign(a_uv) != np.sign(total[chart]))
    good = np.flatnonzero(np.abs(a_uv) > 0)
    pairs = good[candidate_pairs(P[good])] if len(good) else np.zeros((0, 2), dtype=np.int64)
    bad = pairs[overlapping(P, pairs)] if len(pairs) else pairs
    used = np.unique(bad)
    area = exact_overlap_areas(P[used], np.searchsorted(used, bad)) if len(bad) else np.zeros(0)
    # an overlap no thicker than 8 ulps of the coordinates across the pair's box is rounding (a shared line
    # written one ulp apart after the charts were moved), counted apart
    L = np.sqrt(np.maximum(np.ptp(P[bad[:, 0]], axis=1), np.ptp(P[bad[:, 1]], axis=1)).max(axis=1) ** 2 * 2)
    noise = area <= 8 * np.spacing(np.abs(UV).max() if len(UV) else 1.0) * L
    rounding, bad = int(noise.sum()), bad[~noise]
    within = int(np.sum(chart[bad[:, 0]] == chart[bad[:, 1]]))
    return {"faces": int(len(F)), "charts": int(chart.max() + 1) if len(chart) else 0,
            "flips": int(flips.sum()), "collapsed": int(collapsed.sum()), "zero_area_3d": int((~real).sum()),
            "overlaps_within": within, "overlaps_across": int(len(bad) - within), "overlaps_rounding": rounding,
            "pairs_tested": int(len(pairs))}


def run_batch(corpus: Path, out: Path, workers: int, timeout: float, resume: bool) -> float:
    cmd = ["heatparam", "batch", str(corpus), "-o", str(out), "--workers", str(workers), "--task-timeout",
           str(timeout), "--quiet"] + ([] if resume else ["--force"])
    print("command:", " ".join(cmd), file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=False)
    return time.perf_counter() - t0


def xatlas_judged(path: Path) -> dict:
    """xatlas (default options) on the file as heatparam reads it, judged the same way."""
    import xatlas

    from heatparam.formats import load_mesh

    V, F = load_mesh(path)
    V32 = V.astype(np.float32)  # what xatlas is given, and so the 3D areas its map is judged against
    t0 = time.perf_counter()
    vmap, FT, UV = xatlas.parametrize(V32, F.astype(np.uint32))
    sec = time.perf_counter() - t0
    res = judge(V32.astype(np.float64)[vmap], UV.astype(np.float64), FT.astype(np.int64), FT.astype(np.int64))
    res["seconds"] = sec
    return res


def judged_rows(rows: list[dict], out: Path, peer: bool) -> list[dict]:
    for r in rows:
        if r["status"] == "ok":
            V, UV, F, FT = read_uv_obj(out / r["output"])
            r["judge"] = judge(V, UV, F, FT)
            if peer:
                try:
                    r["xatlas"] = xatlas_judged(Path(r["input"]))
                except Exception as e:  # noqa: BLE001 - a peer's failure is a result
                    r["xatlas"] = {"error": str(e).splitlines()[0] if str(e) else type(e).__name__}
    return rows


def _defects(j: dict) -> int:
    return j["flips"] + j["collapsed"] + j["overlaps_within"] + j["overlaps_across"]


def print_table(rows: list[dict], corpus: Path, wall: float, cmd: str) -> None:
    count = collections.Counter(r["status"] for r in rows)
    ok = [r for r in rows if r["status"] == "ok"]
    js = [r["judge"] for r in ok]
    rel = {id(r): str(Path(r["input"]).relative_to(corpus)) for r in rows}
    print(f"## heatparam batch over the corpus ({len(rows)} files)\n")
    print(f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, {machine()}; `{cmd}`; "
          f"wall {wall:.0f} s (sum of task seconds {sum(r['seconds'] or 0 for r in rows):.0f} s)\n")
    print("| outcome | files |\n|---|---:|")
    for s in ("ok", "refused", "failed", "skipped"):
        print(f"| {'flattened' if s == 'ok' else s} | {count.get(s, 0)} |")
    print(f"\nflattened: {sum(j['faces'] for j in js)} faces, {sum(j['charts'] for j in js)} charts; "
          f"flips {sum(j['flips'] for j in js)}, collapsed {sum(j['collapsed'] for j in js)}, overlapping pairs "
          f"{sum(j['overlaps_within'] for j in js)} within charts and {sum(j['overlaps_across'] for j in js)} "
          f"across ({sum(j['overlaps_rounding'] for j in js)} more at rounding level, in "
          f"{sum(j['overlaps_rounding'] > 0 for j in js)} files); zero-area input faces "
          f"{sum(j['zero_area_3d'] for j in js)}; "
          f"iso mean median {np.median([r['iso_mean'] for r in ok if r['iso_mean']]):.4f}\n")
    print("| file | outcome | message |\n|---|---|---|")
    for r in rows:
        if r["status"] in ("refused", "failed"):
            print(f"| {rel[id(r)]} | {r['status']} | {r['reason'].replace(str(corpus) + '/', '')} |")
    bad = [r for r in ok if _defects(r["judge"])]
    print(f"\nfiles with flips / collapsed / overlaps: {len(bad)}")
    for r in bad:
        print(f"- {rel[id(r)]}: {r['judge']}")
    peer = [r for r in ok if "xatlas" in r]
    if peer:
        xs = [r["xatlas"] for r in peer if "error" not in r["xatlas"]]
        print(f"\nxatlas on the same {len(peer)} files: {len(peer) - len(xs)} errors; flips "
              f"{sum(x['flips'] for x in xs)}, collapsed {sum(x['collapsed'] for x in xs)}, overlapping pairs "
              f"{sum(x['overlaps_within'] + x['overlaps_across'] for x in xs)} (rounding level "
              f"{sum(x['overlaps_rounding'] for x in xs)}), files with any "
              f"{sum(_defects(x) > 0 for x in xs)}; time {sum(x['seconds'] for x in xs):.0f} s")
        worst = sorted((r for r in peer if "error" not in r["xatlas"]), key=lambda r: -_defects(r["xatlas"]))[:8]
        for r in worst:
            if _defects(r["xatlas"]):
                print(f"- xatlas {rel[id(r)]}: {r['xatlas']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("corpus", nargs="?", default=str(DEFAULT_CORPUS))
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "out" / "corpus"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--task-timeout", type=float, default=900.0)
    ap.add_argument("--resume", action="store_true", help="keep outputs that are up to date (no --force)")
    ap.add_argument("--judge-only", action="store_true", help="judge OUT's last batch, run nothing")
    ap.add_argument("--xatlas", action="store_true", help="also xatlas on each flattened file, same judge")
    args = ap.parse_args()
    corpus, out = Path(args.corpus).resolve(), Path(args.out).resolve()
    if not corpus.is_dir():
        raise SystemExit(f"no corpus at {corpus}: build it with python bench/corpus.py {corpus}")
    wall = 0.0 if args.judge_only else run_batch(corpus, out, args.workers, args.task_timeout, args.resume)
    summary = json.loads((out / "summary.json").read_text())
    wall = wall or float(summary.get("wall_s") or 0.0)
    rows = judged_rows(summary["rows"], out, args.xatlas)
    (out / "judged.json").write_text(json.dumps(rows, indent=1))
    cmd = (f"python bench/bench_corpus.py --workers {args.workers} --task-timeout {args.task_timeout:g}"
           + (" --xatlas" if args.xatlas else ""))
    print_table(rows, corpus, wall, cmd)


if __name__ == "__main__":
    main()
