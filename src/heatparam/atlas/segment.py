"""Charts of one clean component: normal-cone region growing, then merges checked by a flattening.

1. Growing (like D-Charts / xatlas): farthest-point seeds on the face graph grow together, a face joining the
   chart whose mean normal it deviates least from, while that deviation stays within ``cone`` degrees; sharp
   creases (dihedral angle above ``crease``) are never crossed, and a face joins only where the chart stays a
   topological disk (it touches the chart along one edge with its third vertex new, or along two edges).
   Faces left over seed further rounds.
2. Each region is checked by a quick flattening (LSCM at true area): a region whose map has a flipped face,
   crossing boundaries or isometric distortion above the bound is split — grown again at the same cone from
   ``SPLIT_SEEDS`` farthest seeds of its own (with half the cone when it stays one piece) — and its pieces are
   checked in turn (the paper's future work b: split where the flattening is not bijective or exceeds the bound).
3. Merging (the paper's future work turned around: a merge is kept only while the flattening stays bijective and
   within the bound): neighbouring charts are glued along one stretch of their common border (longest first;
   stretches end at cone points, vertices of large angle defect such as a cube's corners), the rest of the
   common border stays a seam inside the merged chart. A chart is therefore always a disk: a cube becomes a
   net, a cylinder's side an unrolled rectangle. A merge is tested by extending the larger chart's layout over
   the smaller one (LSCM of the smaller chart with the stretch pinned where the larger chart has it): the cost of
   a test is the smaller chart's, where flattening the whole union cost both (cow: 97k faces flattened in 556
   tests → 21k; docs/history.md §21); where the stretch is not one arc of both borders (a chart's own seam ends on it:
   the union would have a hole) the union is flattened whole and its disk test decides. Every chart keeps the
   layout its last test checked (``Segmentation.corner_uv``).
4. Straightening: each seam between two charts is replaced by the shortest edge path between its ends through
   the two charts, where both still flatten bijectively within the bound (their kept faces where they were, the
   faces that change chart laid out as LSCM extensions of them): the cone's borders wander (beetle's seams between
   charts were 1.6× their shortest paths).

A chart is a set of faces plus the half-edges glued inside it (``Segmentation.glued``). Step 1 is ``atlas.grow``,
step 2 ``atlas.flatten``, step 3 ``atlas.merge`` (its stretches: ``atlas.stretches``), step 4 ``atlas.straighten``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from heatparam.atlas.chart_topology import Topology, glue_inside
from heatparam.atlas.flatten import flatten_charts
from heatparam.atlas.grow import DEFAULT_CONE, grow
from heatparam.atlas.merge import Layouts, merge
from heatparam.atlas.straighten import straighten

__all__ = ["PROXY_SLACK", "SPLIT_SEEDS", "Segmentation", "proxy_bound", "segment"]

#: A region that fails its check is grown again at the same cone from this many farthest seeds of its own (grown
#: again with half the cone it shattered into pieces for the merge to glue back: more, longer seams; BENCHMARKS §22)
SPLIT_SEEDS = 3
PROXY_SLACK = 1.5  # the LSCM proxy's distortion excess may exceed the bound's excess by this factor


@dataclass
class Segmentation:
    """chart (m,) int64 chart id per face (0..k-1); glued (3m,) bool, half-edges welded inside their chart;
    corner_uv (3m,2) each face corner's place in its chart's checked layout (row ``3 f + j``: corner j of face f);
    checked (k,) bool, the charts whose layout ``corner_uv`` is bijective and within the bound; iso (k,) its
    area-weighted isometric distortion (inf where not checked)."""

    chart: np.ndarray
    glued: np.ndarray
    stats: dict
    corner_uv: np.ndarray | None = None
    checked: np.ndarray | None = None
    iso: np.ndarray | None = None


def proxy_bound(max_distortion: float) -> float:
    """The bound an LSCM layout is held to (``PROXY_SLACK``: the polish lowers LSCM's area distortion)."""
    return 1.0 + PROXY_SLACK * (max_distortion - 1.0)


def segment(topo: Topology, max_distortion: float, max_charts: int | None = None, cone_deg: float = DEFAULT_CONE,
            seed: int = 0, target_faces: int = 2000) -> Segmentation:
    """Charts of one component (module docstring). Each chart's layout (``Segmentation.corner_uv``) is bijective
    and within the bound, except where a region would not flatten even grown at the narrowest cone
    (``Segmentation.checked``)."""
    m = len(topo.F)
    glued = np.zeros(3 * m, dtype=bool)
    bound = proxy_bound(max_distortion)
    charts: list[np.ndarray] = []
    layouts = Layouts(m)
    stats = {"grown": 0, "regrown": 0, "merges": 0, "merge_tests": 0}
    work = [(np.arange(m), cone_deg, target_faces, False)]
    while work:  # one generation at a time: its regions checked in one flattening (one LSCM solve)
        regions, cones = [], []
        for faces, cone, target, split in work:
            grown = grow(topo, faces, cone, target, seed)
            while split and len(grown) == 1 and cone >= 2.0:  # a failed region that did not split (the border
                cone *= 0.5  # straightening can empty a tiny piece): a narrower cone
                grown = grow(topo, faces, cone, target, seed)
            regions += grown
            cones += [cone] * len(grown)
        work = []
        stats["grown"] += len(regions)
        inside = glue_inside(topo, np.concatenate(regions))  # welded within each region only (chart_mesh's group)
        fl = flatten_charts(topo, regions, inside, bound)
        ok = fl.ok(bound)
        keep = [bool(ok[i]) or len(reg) == 1 or cone < 2.0 for i, (reg, cone) in enumerate(zip(regions, cones,
                                                                                                 strict=True))]
        kept = [i for i, k in enumerate(keep) if k]
        layouts.add(list(range(len(charts), len(charts) + len(kept))), regions, fl, kept, [ok[i] for i in kept])
        for reg, cone, k in zip(regions, cones, keep, strict=True):
            if k:
                glued |= glue_inside(topo, reg)
                charts.append(reg)
            else:
                stats["regrown"] += 1
                work.append((reg, cone, -(-len(reg) // SPLIT_SEEDS), True))  # SPLIT_SEEDS seeds of its own
    chart = np.empty(m, dtype=np.int64)
    for i, c in enumerate(charts):
        chart[c] = i
    t = time.perf_counter()
    chart, glued, nmerge, ntest = merge(topo, chart, glued, bound, layouts)
    stats["capped"] = False
    if max_charts is not None and chart.max() + 1 > max_charts:
        # the user's cap beats the bound: keep merging while the merged chart stays bijective
        chart, glued, n2, t2 = merge(topo, chart, glued, np.inf, layouts, stop_at=max_charts)
        nmerge, ntest = nmerge + n2, ntest + t2
        stats["capped"] = True
    stats["merge_seconds"] = round(time.perf_counter() - t, 3)
    stats["merges"], stats["merge_tests"] = nmerge, ntest
    t = time.perf_counter()
    stats["straightening"] = straighten(topo, chart, glued, np.inf if stats["capped"] else bound, layouts)
    stats["straightening"]["seconds"] = round(time.perf_counter() - t, 3)
    return Segmentation(chart=chart, glued=glued, stats=stats, corner_uv=layouts.uv,
                        checked=layouts.checked(), iso=layouts.iso())
