"""The seams stage: flatten the surface cut open from every hole to the border when that is asked for or, with
``seams auto``, clearly better (``SEAM_TRY_EXCESS``, ``SEAM_MIN_GAIN``).

A map must keep each hole a hole; where the surface's curvature pushes a hole's side over another boundary (the
crossings of libigl's SLIM maps on halftunnel and beetle) a bijective map has to squeeze the band between them.
Cutting the holes open to the border (``mesh.seams.hole_seams``: a minimum spanning tree of shortest paths) removes
the constraint instead of fighting it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.layout.conformal import SCP_CUT_MAX_ITERS
from heatparam.layout.projection import NO_MEAN_PLANE, projection_layout
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.mesh.validate import validate_mesh
from heatparam.options import SEAM_MIN_GAIN, SEAM_PAUSE_EXCESS, SEAM_PAUSE_FLOOR, SEAM_TRY_EXCESS
from heatparam.pipeline.report import Flat
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine import Pausing
from heatparam.refine.newton import Stop
from heatparam.refine.reopen_slits import reopen_crossing_slits
from heatparam.refine.start import separated_boundary, unflipped

#: Why the cut-open mesh's conformal layout is not computed: its projection, the same map with the slits reopened
#: (``layout.projection``), is bijective and beat the conformal layout as the start of the map without seams. There
#: it beat the cut mesh's conformal layout (inverse iteration, unconverged) too on 13 of 13 tuning parts with holes
#: (seeds 0-29 of ``bench/large_family.py``), which costs 1-3 s at 200k-400k faces.
PROJECTION_STARTED = ("the map without seams started from the projection onto the mean plane, lower in energy than "
                      "the conformal layout, and the cut mesh's projection (its slits reopened) is bijective")


class Cut(NamedTuple):
    """A mesh cut open along seams: the cut surface (its F is the input's, row for row), ``source`` (n_s,) the
    vertex of the uncut surface each of its vertices copies, ``paths`` the seams' vertex paths (uncut ids)."""

    surface: Surface
    source: np.ndarray
    paths: list[np.ndarray]


class SeamResult(NamedTuple):
    """The seams stage's value: the flattening to keep (finished; the one without seams when not cut), the cut
    (None when not cut), the report's ``seams`` part, warnings, and the flattening without seams as the stage
    left it (``uncut``: the kept one when not cut; when cut, possibly paused, as its report says, and reduced to
    its map, metrics and report)."""

    flat: Flat
    cut: Cut | None
    report: dict
    warnings: list[str]
    uncut: Flat


def seam_pause(surface: Surface, opts) -> Pausing:
    """How the trial flattening without seams of ``surface`` may pause (``refine.Pausing``).

    The polish pauses at ``SEAM_PAUSE_EXCESS`` when ``seams auto`` may try the cut-open mesh (holes, a refined map),
    so that a trial the map will not keep is not polished to the end; else never (``holes`` keeps the cut map,
    ``none`` tries nothing). Its coarse levels may pause too while their iso mean exceeds the value above which the
    cut is tried for any finished map (:func:`_surely_tried`), where the map without seams was kept on no mesh
    measured (BENCHMARKS.md §16). The cut map pauses at its fine level only: it is usually kept, and finishing a
    paused coarse level drops the fine iterations made from it."""
    auto = opts.seams == "auto" and opts.refine != "none" and surface.info.n_holes > 0
    if not auto:
        return Pausing()
    return Pausing(SEAM_PAUSE_EXCESS, 1.0 + SEAM_TRY_EXCESS / SEAM_PAUSE_FLOOR)


def seams_stage(surface: Surface, opts, prog: Progress, flat: Flat, flatten: Callable[..., Flat]) -> SeamResult:
    """``Options.seams``: the flattening (``flatten``, as ``pipeline.flatten``) of the surface cut open from every
    hole to the border when it is asked for or (``auto``) clearly better than ``flat``. The returned flattening is
    finished (``flat`` may come paused: :func:`seam_pause`).

    ``seams auto`` decides on paused polishes where it can (:func:`_decide`): the kept map is then finished, the
    other one not; the report's ``seams.paused`` says which iso means were read on a paused map.
    """
    rep: dict = {"mode": opts.seams, "used": False}
    if flat.resume is not None and not _surely_tried(flat):
        flat = flat.resume()  # whether the cut is tried at all depends on the finished map's iso mean
    reason = _no_cut_reason(surface, opts, flat)
    cut = None
    if reason is None:
        with prog.stage("seams", "cut open"):
            cut, reason = _cut_open(surface)
    if reason is not None:
        flat = _finished(flat)
        return SeamResult(flat, None, rep | {"reason": reason}, [], flat)
    lengths = [float(np.linalg.norm(np.diff(surface.V[p], axis=0), axis=1).sum()) for p in cut.paths]
    rep.update(seams=len(cut.paths), length=round(sum(lengths), 9), longest=round(max(lengths), 9),
               split_vertices=int(len(cut.surface.V) - len(surface.V)))
    starts: dict[str, np.ndarray] = {}
    if opts.refine != "none":
        projected, rep["projection_reopened"] = _reopened_projection(cut.surface, cut.source)
        if projected is not None and flat.method["refine"].get("start", {}).get("layout") == "projection":
            cut.surface.conformal_skipped = PROJECTION_STARTED
        with prog.stage("seams", "conformal start"):
            x, rep["conformal_reopened"] = _reopened_conformal(cut.surface, cut.source)
        if x is not None:
            starts["conformal_reopened"] = x
        if projected is not None:
            starts["projection_reopened"] = projected
    # the cut map, when paused, keeps its factorization: it is usually kept and finished next (4.5 s to rebuild
    # at 311k vertices); when the map without seams is kept instead, the cut map is dropped first. A trial pauses
    # first where its coarse level hands over (:func:`coarse_bound`). A trial's fine level starts from the raw
    # prolongation: :func:`_decide` may read the map without seams where it is provisional (``multilevel.Levels``),
    # with a floor measured on fine pauses that a provisional map can undercut (held-out 1003: 1.3678 provisional,
    # 1.1165 finished), and there a smoothed trial (``refine.smoother``: 1.1778, raw 1.6931) was kept over it
    excess = seam_pause(surface, opts).excess
    pausing = Pausing(excess, park=False, fine_start=excess > 0, raw_start=excess > 0)
    # where no start of the cut mesh is bijective, its smoothed conformal layout is, its slits reopened like the
    # conformal one's (a noisy border folds both), before Tutte's
    reopen = functools.partial(_reopened, cut_surface=cut.surface, source=cut.source)
    maps = _Maps(flat, flatten(cut.surface, opts, prog, seamed=True, starts=starts or None, pausing=pausing,
                               repair=reopen))
    del flat  # from here on only ``maps`` holds the two maps, so that the one not kept can be freed
    return _chosen(opts, maps, cut, rep, float(surface.frame.lengths_to_model(sum(lengths))))


@dataclass
class _Maps:
    """The two flattenings compared, without and with seams: the only reference to each, so that the map not kept
    (its polish state, possibly an unparked factorization, its heat-stage layout) is freed, by reassigning its
    attribute, before the kept one is finished (where the peak memory is)."""

    without: Flat
    cut: Flat


def _cut_open(surface: Surface) -> tuple[Cut | None, str | None]:
    """The surface cut open from every hole to the border (``mesh.seams.hole_seams``), or why not."""
    paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
    Vs, Fs, src = cut_open(surface.V, surface.F, paths)
    try:
        # the inverse iteration's layout, not the converged eigenvector: on beetle upsampled that one's slits
        # cross where several seams meet a hole (layout.conformal.SCP_CUT_MAX_ITERS)
        cut_surface = Surface(Vs, Fs, validate_mesh(Vs, Fs), conformal_method="inverse",
                              conformal_max_solves=SCP_CUT_MAX_ITERS)
    except HeatparamError as exc:  # a seam set that does not leave a disk (never seen): keep the map
        return None, f"the cut-open mesh is not a disk ({exc})"
    return Cut(cut_surface, src, paths), None


def _chosen(opts, maps: _Maps, cut: Cut, rep: dict, length: float) -> SeamResult:
    """The seams stage's value once both maps exist: the one kept finished, the other left where it is (``length``:
    the seams' in model units, for the warning)."""
    coarse_reason = None
    if opts.seams == "auto":
        coarse_reason = coarse_bound(maps.without, maps.cut)
        if coarse_reason is not None:
            better = False
            rep["coarse_iso_means"] = {k: f.method["refine"]["multilevel"]["coarse_iso_mean"]
                                       for k, f in (("without", maps.without), ("with", maps.cut))}
        else:
            if _at_fine_start(maps.cut):  # on to where a trial's fine polish pauses
                maps.cut = maps.cut.resume(SEAM_PAUSE_EXCESS)
            better, maps.without, maps.cut = _decide(maps.without, maps.cut)
    else:
        better = True
    paused = [name for name, f, kept in (("without", maps.without, not better), ("with", maps.cut, better))
              if f.resume is not None and not kept]
    if better:
        maps.without = _left(maps.without)
        maps.cut = _finished(maps.cut)
    else:
        maps.cut = _left(maps.cut)
        maps.without = _finished(maps.without)
    flat, cut_flat = maps.without, maps.cut
    iso, iso_s = flat.summary["iso_mean"], cut_flat.summary["iso_mean"]
    rep.update(iso_mean_without=iso, iso_mean_with=iso_s, bijective_with=cut_flat.summary["bijective"])
    if paused:
        rep["paused"] = {"maps": paused, "pause_excess": SEAM_PAUSE_EXCESS, "floor": SEAM_PAUSE_FLOOR,
                         "note": ("the iso mean of these maps was read where their polish paused; the decision "
                                  "held for any finished value from the floor × their excess over 1 to all of it, "
                                  "so they were not finished")}
    was_paused = " (paused)" if paused else ""
    if not better:
        rep["reason"] = coarse_reason or (
            f"the cut-open map is not {SEAM_MIN_GAIN:.0%} better (iso mean {iso_s:.4f}{was_paused} vs "
            f"{iso:.4f}{'' if cut_flat.summary['bijective'] else ', not bijective'}); kept without seams")
        return SeamResult(flat, None, rep, [], flat)
    rep["used"] = True
    rep["reason"] = (f"the holes cost distortion: iso mean {iso:.4f}{was_paused} without seams, {iso_s:.4f} with "
                     f"{len(cut.paths)} (seams='none' keeps one uncut piece)" if opts.seams == "auto"
                     else "requested (seams='holes')")
    warning = (f"the map has seams: {len(cut.paths)} cut(s), {length:.6g} {opts.unit_name} long in all, join the holes "
               f"to the border (iso mean {iso:.4f}{' where its polish paused' if paused else ''} → {iso_s:.4f}); the "
               "OBJ's vt rows split along them (seams='none': one uncut piece)")
    return SeamResult(cut_flat, cut, rep, [*cut_flat.warnings, warning], flat)


def _reopened_conformal(cut_surface: Surface, source: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """The cut surface's conformal layout with its crossing slits reopened (``refine.reopen_slits``), offered to the
    refinement as the start candidate ``"conformal_reopened"`` when the layout crosses only there; (layout or None,
    the report's ``seams.conformal_reopened``)."""
    try:
        uv = cut_surface.conformal()
    except HeatparamError as exc:  # the refinement's own start check reports it again; Tutte still serves
        return None, {"reason": f"no conformal layout ({exc})"}
    if not np.isfinite(uv).all():
        return None, {"reason": "the conformal layout has non-finite coordinates"}
    return _reopened(uv, cut_surface, source)


def _reopened_projection(cut_surface: Surface, source: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """The cut surface's projection onto its mean plane (``layout.projection``), where every slit is closed (its
    two sides project onto each other), with its slits reopened (``refine.reopen_slits``): the start candidate
    ``"projection_reopened"`` of a height-field-like part; (layout or None, the report's ``seams.projection_reopened``).
    """
    uv = projection_layout(cut_surface.V, cut_surface.F)
    if uv is None:
        return None, {"reason": NO_MEAN_PLANE}
    return _reopened(uv, cut_surface, source)


def _reopened(uv: np.ndarray, cut_surface: Surface, source: np.ndarray) -> tuple[np.ndarray | None, dict]:
    """The cut surface's layout ``uv`` (n,2) with its crossing slits reopened (``refine.reopen_slits``), its border
    ears first unflipped where they are its only flipped faces (``refine.start.unflipped``: a range image's border
    slivers fold in a projection). Folds elsewhere are not repaired: a held-out mask's projection, 126 folds
    repaired and its slits reopened, started its cut map towards iso 1.0360 where Tutte's reached 1.0198."""
    g, area = cut_surface.gradients()
    z, repair = unflipped(uv, cut_surface.F, g, area, cut_surface.info.boundary_loops, ears_only=True)
    if z is None and repair["flips"]:
        return None, {"reason": f"the layout has {repair['flips']} flipped faces ({repair['reason']})"}
    x, report = reopen_crossing_slits(uv if z is None else z, cut_surface.F, source)
    if z is not None:
        report = {"unflipped": repair, **report}
    if x is None:
        return None, report
    x, separated = separated_boundary(x, cut_surface.F, cut_surface.info.boundary_loops)
    return x, report | separated


def _left(f: Flat) -> Flat:
    """``f`` as the map the seams stage does not keep: its map, metrics and report only."""
    return f._replace(layout=None, fill_surface=None, resume=None)


def _finished(f: Flat) -> Flat:
    return f if f.resume is None else f.resume()


def _range(f: Flat) -> tuple[float, float]:
    """The iso means the finished map of ``f`` may have: exact when finished, else from ``SEAM_PAUSE_FLOOR`` of the
    paused excess to the paused value."""
    iso = f.summary["iso_mean"]
    return (iso, iso) if f.resume is None else (1.0 + SEAM_PAUSE_FLOOR * (iso - 1.0), iso)


def _surely_tried(flat: Flat) -> bool:
    """Whether ``seams auto`` tries the cut for any finished value of the paused map ``flat`` (bijective: the
    polish keeps it so)."""
    return flat.summary["bijective"] and _range(flat)[0] > 1.0 + SEAM_TRY_EXCESS


def _decide(flat: Flat, cut: Flat) -> tuple[bool, Flat, Flat]:
    """``seams auto``'s rule — keep the cut map when it is bijective and (the map without seams is not, or) its
    iso mean is at least ``SEAM_MIN_GAIN`` lower — on paused maps when the rule gives the same answer for every
    finished value they may have (:func:`_range`); otherwise both are finished and it is applied to them.
    Returns (keep the cut?, flat, cut), finished where that was needed."""
    for _ in range(2):
        if cut.summary["bijective"] and flat.summary["bijective"]:
            (u_lo, u_hi), (c_lo, c_hi) = _range(flat), _range(cut)
            if c_hi <= u_lo * (1 - SEAM_MIN_GAIN):
                return True, flat, cut
            if c_lo > u_hi * (1 - SEAM_MIN_GAIN):
                return False, flat, cut
        elif flat.resume is None and cut.resume is None:
            break
        cut = _finished(cut)  # first: it may hold its factorization (not parked), which finishing frees
        flat = _finished(flat)
    better = cut.summary["bijective"] and (not flat.summary["bijective"]
                                           or cut.summary["iso_mean"] <= flat.summary["iso_mean"] * (1 - SEAM_MIN_GAIN))
    return better, flat, cut


def _at_fine_start(f: Flat) -> bool:
    """Whether the flattening ``f`` paused before its fine polish's first iteration (``Pausing.fine_start``)."""
    refine = f.method.get("refine", {})
    return (f.resume is not None and refine.get("multilevel", {}).get("used", False)
            and refine["polish"]["iterations"] == 0)


def coarse_bound(flat: Flat, cut: Flat) -> str | None:
    """Why the cut map ``cut``, paused where its coarse level handed over (``Pausing.fine_start``), cannot be kept:
    its coarse level is not ``SEAM_MIN_GAIN`` × the fine iso mean of the map without seams ``flat`` better than
    that map's coarse level (None: the rule does not rule the cut out, or cannot be applied).

    :func:`noise_bound`'s argument with the cut's own coarse level in place of the best case (an isometry): what a
    cut removes is the smooth stretch the holes force, which a coarse level resolves as well as the fine one, so
    the fine iso mean drops by about what the coarse one drops (measured: halftunnel↑50k 0.491 coarse, 0.483
    fine), while scan noise, in the fine mesh only, stays in both maps. Needs both coarse levels, the cut's
    stopped where its energy no longer fell (converged, or stalled at the barrier: gains below the tolerance; not
    at an iteration cap or a failure), and the map without seams bijective; the latter's coarse iso mean, when its
    level paused, is an upper bound and only makes the rule more cautious."""
    if not (_at_fine_start(cut) and flat.summary["bijective"]):
        return None
    mu, mc = flat.method["refine"].get("multilevel", {}), cut.method["refine"]["multilevel"]
    stop = mc["coarse_polish"]
    if not (mu.get("used") and mu.get("coarse_iso_mean") is not None
            and (stop["converged"] or stop["stop"] == Stop.STALLED.value)):
        return None
    gain, lo = mu["coarse_iso_mean"] - mc["coarse_iso_mean"], _range(flat)[0]
    if gain >= SEAM_MIN_GAIN * lo:
        return None
    change = f"lowers the coarse level's iso mean by {gain:.4f} only" if gain > 0 else \
        "does not lower the coarse level's iso mean"
    return (f"the cut {change} ({mu['coarse_iso_mean']:.4f} → {mc['coarse_iso_mean']:.4f}), less than "
            f"{SEAM_MIN_GAIN:.0%} of the map without seams' {flat.summary['iso_mean']:.4f}: the rest of its distortion "
            "is the fine mesh's (noise), which a cut keeps, so the cut map was not polished on; kept without seams")


def _no_cut_reason(surface: Surface, opts, flat: Flat) -> str | None:
    """Why the surface is not cut (None: try cutting it)."""
    if opts.seams == "none":
        return "disabled (seams='none')"
    if surface.info.n_holes == 0:
        return "no holes"
    if opts.seams == "auto":
        if opts.refine == "none":
            return "the raw map (refine='none') is not cut (seams='holes' cuts it)"
        iso = flat.summary["iso_mean"]
        if flat.summary["bijective"] and iso <= 1 + SEAM_TRY_EXCESS:  # options.SEAM_TRY_EXCESS: nothing to gain
            return (f"the map without seams is bijective and near-isometric (iso mean {iso:.4f}): no cut map could "
                    f"lower it by {SEAM_MIN_GAIN:.0%} (an iso mean is at least 1)")
        return noise_bound(flat)
    return None


def noise_bound(flat: Flat) -> str | None:
    """Why no cut map can be kept although the map without seams is far from an isometry: its coarse level is
    close to one (None: the bound does not rule the cut out).

    A cut removes the distortion the holes force on the map: a smooth stretch that the coarse level (a subset of
    the vertices, ``refine.multilevel``) resolves as well as the fine one, so the fine map's iso mean can drop by
    at most about what the coarse map's can, and that is less than its excess over 1 (a map's iso mean is ≥ 1).
    Distortion the fine level adds on top (scan noise: a coarse mesh's longer edges carry it less) stays in both
    maps. So when ``coarse iso mean - 1 < SEAM_MIN_GAIN × fine iso mean`` (the fine one's lowest finished value
    when paused: :func:`_range`; the coarse one's paused value, an upper bound, when its level paused) the cut-open
    map cannot be ``SEAM_MIN_GAIN`` better and is not tried. Measured drops of iso mean, coarse → fine level, where
    both maps were finished or paused (docs/history.md §19): halftunnel↑50k 0.491 → 0.483, a curved cap with holes
    and noise 0.2 × edge 0.013 → 0.005, a cylinder with holes and noise 0.2 × edge 0.0001 → 0.00002."""
    ml = flat.method["refine"].get("multilevel", {})
    coarse = ml.get("coarse_iso_mean")
    if not (ml.get("used") and coarse is not None and flat.summary["bijective"]):
        return None
    lo = _range(flat)[0]
    if coarse - 1.0 >= SEAM_MIN_GAIN * lo:
        return None
    return (f"the map without seams (iso mean {flat.summary['iso_mean']:.4f}) is within {coarse - 1.0:.2%} of an "
            f"isometry at its coarse level ({ml['coarse_vertices']} vertices): its distortion is the fine mesh's "
            f"(noise), not the holes', and no cut map could lower it by {SEAM_MIN_GAIN:.0%}")
