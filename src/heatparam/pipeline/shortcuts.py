"""When the heat stage cannot change the map, or cannot pay for itself, skip it (``Options.mds_start = "auto"``).

The refinement starts from the lower-energy bijective layout of MDS and the conformal layout (spectral, no pins).
The heat stage (fill, geodesics, MDS) is not computed when

(a) the conformal layout is bijective and within ``ISOMETRIC_START_EXCESS`` of an isometry (developable parts): no
    start can be better, the map is bit for bit the same;
(b) the mesh has at least ``CONFORMAL_START_MIN_VERTICES`` vertices and the conformal layout is bijective: measured
    on every such part, the polish from it reached the same map quality (iso mean ±5e-6) in less total time than
    with the heat stage, whose layout had the lower energy on the noisy ones but no fewer Newton iterations
    (``options.CONFORMAL_START_MIN_VERTICES``); the maps differ only within the polish's tolerance. A conformal
    layout with a few flipped faces counts once they are repaired (``refine.start.repaired_layout``, as MDS's are).
    Where it is not bijective the heat stage runs: MDS may be the only bijective start;
(c) the surface is the seams stage's cut-open mesh: it is not filled (a fill would close the seams), geodesics run
    around the slits, and MDS lost to LSCM or Tutte on every seamed map measured (beetle: 4106 flipped faces;
    halftunnel: energy 1.435 vs LSCM 1.218; a 200k mask scan: not bijective). The same map;
(d) the flattening is the seams stage's trial without seams (``seams auto`` on a mesh with holes) of at least
    ``CONFORMAL_START_MIN_VERTICES`` vertices, and the conformal layout is not bijective even after the repair of
    a few flips: on both such parts measured the MDS layout folded too (halftunnel upsampled to 201k: 52,925 flipped
    faces; a cylinder with holes and noise 0.3 × the edge at 182k: 249, beyond repair), the trial started from Tutte
    either way and the kept map was the same, so the heat stage (22-31 s there) is skipped: 67-81 → 58 s and
    254 → 247 s (docs/history.md §18e). Where the trial's map is kept it has started from the conformal layout of
    the smoothed surface, or Tutte (``refine.start.SmoothedStart``); ``mds_start='always'`` computes the heat stage.

Tests compare (a) and (c) with ``mds_start="always"`` bit for bit, (b) and (d) by map quality.
"""

from __future__ import annotations

from typing import NamedTuple

from heatparam.options import CONFORMAL_START_MIN_VERTICES, ISOMETRIC_START_EXCESS
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine.start import LscmStart, lscm_start


class StartCheck(NamedTuple):
    """The start checks' value: the conformal start judged (or None when not checked) and why the heat stage is
    skipped (None: it runs)."""

    lscm: LscmStart | None
    skipped: str | None


def heat_stage_optional(opts) -> bool:
    """Whether ``mds_start auto`` may skip the fill, geodesics and MDS: not when any of them was asked for."""
    return opts.fill == "auto" and opts.geodesics == "auto" and opts.stress == "none" and opts.landmarks == 0


def start_checks(surface: Surface, opts, prog: Progress, seamed: bool = False, trial: bool = False) -> StartCheck:
    """Whether the fill, geodesics and MDS can be skipped (cases (a)-(d) of the module docstring; ``seamed``: the
    surface is the seams stage's cut-open mesh; ``trial``: the flattening is the seams stage's trial without seams,
    which may pause and be dropped)."""
    if opts.refine == "none" or opts.mds_start == "always" or not heat_stage_optional(opts):
        return StartCheck(None, None)
    with prog.stage("start check"):
        lscm = lscm_start(surface.V, surface.F, surface.conformal, surface.gradients())
    if opts.mds_start == "never":
        return StartCheck(lscm, "skipped: mds_start='never' (the refinement starts from the conformal layout, or the "
                                "smoothed surface's, or Tutte when neither is bijective)")
    if lscm.near_isometric:
        return StartCheck(lscm, (f"skipped: the conformal layout is bijective and within {ISOMETRIC_START_EXCESS:g} of "
                                 f"an isometry (energy {lscm.energy:.7f}), so it starts the refinement "
                                 "(mds_start='always' computes them)"))
    if seamed:
        return StartCheck(lscm, ("skipped: the surface is cut open along seams and not filled, so geodesics run "
                                 "around the slits and the MDS layout folds across them (mds_start='always' "
                                 "computes them)"))
    if len(surface.V) < CONFORMAL_START_MIN_VERTICES:
        return StartCheck(lscm, None)
    if lscm.energy is None:
        if trial:
            return StartCheck(lscm, ("skipped: the map without seams is the seams stage's trial on a large mesh whose "
                                     "conformal layout is not bijective even repaired, where MDS folded too on every "
                                     "part measured; it starts from the smoothed surface's conformal layout or Tutte "
                                     "(mds_start='always' computes them)"))
        return StartCheck(lscm, None)
    fixed = f"{lscm.flips} flipped faces repaired, " if lscm.repair is not None else ""
    return StartCheck(lscm, (f"skipped: the conformal layout is bijective ({fixed}energy {lscm.energy:.4f}) on a "
                             f"mesh of >= {CONFORMAL_START_MIN_VERTICES} vertices, where the polish from it reached "
                             "the same map quality in less time than with the heat stage on every part measured "
                             "(mds_start='always' computes them)"))
