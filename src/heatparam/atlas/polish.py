"""The charts of a segmentation polished together (``refine.charts``), each from its bijective layout.

The layout the segmentation checked (``Segmentation.corner_uv``) is the start; a chart without one starts from its
quick flattening (LSCM) where that is bijective. Starting from the checked layout alone (not the less distorted of
it and a fresh LSCM) gave the same Newton iterations and iso means within 2e-4 without the LSCM (docs/history.md §23a).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from heatparam.atlas.chart_topology import Topology
from heatparam.atlas.flatten import Flattenings, chart_iso, flatten_charts
from heatparam.atlas.segment import Segmentation
from heatparam.refine import RefineParams
from heatparam.refine.charts import refine_charts

__all__ = ["PolishedChart", "polish_charts"]

#: the polish's report keys kept in the atlas report
REPORT_KEYS = ("charts", "iterations", "converged", "stop", "energy_start", "energy_end", "seconds", "used", "reason",
               "scaffolded")


@dataclass
class PolishedChart:
    """A chart the joint polish finished: its faces (component rows), Fl (k,3) local triangles, vert (n_l,)
    component vertex of each row, uv (n_l,2), info (its report entry)."""

    faces: np.ndarray
    Fl: np.ndarray
    vert: np.ndarray
    uv: np.ndarray
    info: dict


def polish_charts(topo: Topology, groups: list[np.ndarray], seg: Segmentation, *, limit: float | None,
                  params: RefineParams | None) -> tuple[list[PolishedChart], list[int], dict]:
    """The charts ``groups`` (face arrays of ``seg``) polished together; ``params`` None: not polished (their
    layouts kept). A chart is done when its polished layout is flip-free and within ``limit`` (None: any).

    Returns (the charts done, the indices of the others — no bijective layout, or failed —, the polish's report).
    """
    fl, ok = _starts(topo, groups, seg)
    good = np.flatnonzero(ok)
    if not len(good):
        return [], list(range(len(groups))), {"charts": 0}
    rows, Fs, vg = _picked(fl.Fl, fl.vgroup, good, len(groups))
    x = fl.uv[rows]
    if params is None:
        rep = {"charts": len(good), "used": False, "reason": "refine none: the LSCM layouts are kept"}
    else:
        x, rep = refine_charts(fl.Vl[rows], Fs, x, vg, len(good), max_iters=params.max_iters, tol=params.tol,
                               backend=params.solver)
    iso, flips = chart_iso(fl.Vl[rows], Fs, x, vg[Fs[:, 0]], len(good))
    crossing = rep.get("boundary_crossings", 0) > 0  # the scaffold rules it out; checked, not assumed
    if params is not None and limit is not None and not crossing:
        over = np.flatnonzero((iso > limit) & (flips == 0))
        if len(over):
            rep["scaffolded"] = _scaffolded(fl.Vl[rows], Fs, x, vg, over, iso, flips, params)
    polished = fl.uv.copy()
    polished[rows] = x
    done, rest = [], [int(i) for i in np.flatnonzero(~ok)]
    for j, i in enumerate(good):
        if crossing or flips[j] or (limit is not None and iso[j] > limit):
            rest.append(int(i))
            continue
        _, Fl, vert, uv = fl.chart(i, polished)
        info = {"iso_mean": float(iso[j]), "flips": 0, "bijective": True, "boundary_crossings": 0,
                "method": "lscm + joint polish"}
        done.append(PolishedChart(groups[i], Fl, vert, uv, info))
    return done, sorted(rest), {k: rep[k] for k in REPORT_KEYS if k in rep}


def _scaffolded(V: np.ndarray, F: np.ndarray, x: np.ndarray, vg: np.ndarray, over: np.ndarray, iso: np.ndarray,
                flips: np.ndarray, params: RefineParams) -> dict:
    """Polish the charts ``over`` (over the bound after the joint polish) again, together and inside a scaffold,
    from where the joint polish left them; ``x`` (n,2), ``iso`` and ``flips`` (k,) updated in place where the
    result is bijective. Without a scaffold a chart stops where its boundary would cross itself, often far above its
    minimum: fandisk's larger chart left at iso mean 1.0576 (> 1.05) went through the whole pipeline (0.7-0.9 s),
    while 2 scaffolded iterations (0.08 s) bring it to 1.0093. Returns the pass's report."""
    rows, Fo, vo = _picked(F, vg, over, len(iso))
    y, rep = refine_charts(V[rows], Fo, x[rows], vo, len(over), max_iters=params.max_iters, tol=params.tol,
                           backend=params.solver, scaffold=True)
    if rep["flips"] == 0 and rep["boundary_crossings"] == 0:
        x[rows] = y
        iso[over], flips[over] = chart_iso(V[rows], Fo, y, vo[Fo[:, 0]], len(over))
    return {k: rep[k] for k in ("charts", "iterations", "stop", "seconds") if k in rep}


def _picked(F: np.ndarray, vchart: np.ndarray, charts: np.ndarray, k: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The charts ``charts`` (of k) of charts set side by side (F (m,3); ``vchart`` (n,) the chart of each row, every
    row in some face): (their rows (r,), their triangles (m_r,3) in those rows' order, each row's chart numbered in
    the order of ``charts`` (r,))."""
    new = np.full(k, -1, dtype=np.int64)
    new[charts] = np.arange(len(charts))
    rows = np.flatnonzero(new[vchart] >= 0)
    loc = np.full(len(vchart), -1, dtype=np.int64)
    loc[rows] = np.arange(len(rows))
    return rows, loc[F[new[vchart[F[:, 0]]] >= 0]], new[vchart[rows]]


def _starts(topo: Topology, groups: list[np.ndarray], seg: Segmentation) -> tuple[Flattenings, np.ndarray]:
    """The charts' meshes with their start layouts (the checked one, else LSCM) and which have a bijective one."""
    fl = flatten_charts(topo, groups, seg.glued, want=~seg.checked)
    ok = fl.ok(np.inf)
    for i in np.flatnonzero(seg.checked & fl.disk):  # never a chart with a hole
        rows = fl.Fl[fl.face_start[i]:fl.face_start[i + 1]].ravel()
        fl.uv[rows] = seg.corner_uv[(3 * groups[i][:, None] + np.arange(3)).ravel()]
        ok[i] = True
    return fl, ok
