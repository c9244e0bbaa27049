"""The seams stage's cut mesh: its heat stage is skipped (same maps), and the uncut map as a start candidate
(``refine.seam_start.open_slits``): bijective, judged with the others, and where it helps and where it does not."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets, metrics, parameterize
from heatparam.formats import load_mesh
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.options import make_options
from heatparam.pipeline import flatten
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine import LscmStart, refine
from heatparam.refine.scaffold import build_scaffold
from heatparam.refine.seam_start import SLIT_MIN_AREA_FRACTION, open_slits

from conftest import shared_mesh

NO_LSCM = LscmStart(None, -1, -1, None, "left out by the test")


def _cap():
    """A strongly curved cap (sphere radius 1.5) with two eye holes and a mouth slot, ~1.2k vertices."""
    s = datasets.curved_cap_with_holes(sphere_radius=1.5, h=0.05)
    return s.V, s.F


def _halftunnel():
    return load_mesh(shared_mesh("halftunnel.off"))


def _cut_case(V, F):
    """(cut V, cut F, source, the uncut map laid on the cut mesh, the opened start, its report)."""
    surface = Surface.validated(V, F)[0]
    flat = flatten(surface, make_options(None), Progress(False))
    paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
    Vs, Fs, src = cut_open(surface.V, surface.F, paths)
    closed = flat.uv[src]
    x, rep = open_slits(closed, Fs, src)
    return Vs, Fs, src, closed, x, rep


def _signed(uv, F):
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])


@pytest.mark.parametrize("case", [_cap, _halftunnel], ids=["curved cap", "halftunnel"])
def test_opened_slits_are_bijective(case):
    Vs, Fs, src, closed, x, rep = _cut_case(*case())
    assert x is not None, rep
    assert rep["moved"] == int((np.bincount(src)[src] > 1).sum())
    # closed slits: the boundary touches itself, so the scaffold cannot be built around it
    loops = [np.asarray(lp) for lp in Surface.validated(Vs, Fs)[2].boundary_loops]
    with pytest.raises(ValueError):
        build_scaffold(closed, loops)
    s = metrics.summary(Vs, Fs, x)
    assert s["flips"] == 0 and s["boundary_crossings"] == 0
    assert (_signed(x, Fs) >= SLIT_MIN_AREA_FRACTION * _signed(closed, Fs) - 1e-15).all()
    # every copy of a seam vertex now has its own position
    order = np.argsort(src, kind="stable")
    same = src[order][1:] == src[order][:-1]
    gap = np.linalg.norm(x[order][1:][same] - x[order][:-1][same], axis=1)
    assert len(gap) and gap.min() > 0
    build_scaffold(x, loops)


def test_uncut_start_on_a_cap_saves_iterations():
    """Where the seams need not open far (a cap whose cut map is near-isometric), the uncut start is close to the
    cut map's minimum: fewer Newton iterations than Tutte's embedding, measured in this run, the same energy."""
    Vs, Fs, _, _, x, _ = _cut_case(*_cap())
    y_u, r_u = refine(Vs, Fs, None, lscm=NO_LSCM, extra_starts={"uncut": x})
    y_t, r_t = refine(Vs, Fs, None, lscm=NO_LSCM)
    assert r_u["start"]["layout"] == "uncut" and r_t["start"]["layout"] == "tutte"
    assert r_u["start"]["energy"]["uncut"] < r_t["polish"]["energy_start"]
    assert r_u["polish"]["iterations"] < r_t["polish"]["iterations"]
    assert r_u["bijective"] and r_t["bijective"]
    assert r_u["polish"]["energy_end"] <= r_t["polish"]["energy_end"] * (1 + 1e-6)
    iso_u, iso_t = (metrics.summary(Vs, Fs, y)["iso_mean"] for y in (y_u, y_t))
    assert iso_u <= iso_t * (1 + 1e-5)


def test_uncut_start_on_halftunnel_loses():
    """Why it is not the default: on halftunnel the slits must open far, and the polish from the uncut start ends
    in a worse minimum than from Tutte's embedding; offered beside LSCM, the lower-energy LSCM start wins."""
    Vs, Fs, _, _, x, _ = _cut_case(*_halftunnel())
    _, r_u = refine(Vs, Fs, None, lscm=NO_LSCM, extra_starts={"uncut": x})
    _, r_t = refine(Vs, Fs, None, lscm=NO_LSCM)
    assert r_u["bijective"] and r_t["bijective"]
    assert r_u["polish"]["energy_end"] > r_t["polish"]["energy_end"] * 1.01
    _, r = refine(Vs, Fs, None, extra_starts={"uncut": x})
    e = r["start"]["energy"]
    assert r["start"]["layout"] == "conformal" and e["conformal"] < e["uncut"]


@pytest.mark.parametrize("case,kw,why", [(_halftunnel, {}, "the surface is cut open along seams"),
                                         (_cap, {"seams": "holes"}, "the conformal layout is bijective and within")],
                         ids=["halftunnel", "cap"])
def test_cut_mesh_skips_the_heat_stage_with_the_same_map(case, kw, why):
    V, F = case()
    a = parameterize(V, F, **kw)
    b = parameterize(V, F, mds_start="always", **kw)
    assert a.seamed and b.seamed
    assert a.report["method"]["geodesics"].startswith(f"skipped: {why}")
    assert not b.report["method"]["geodesics"].startswith("skipped")
    assert np.array_equal(a.uv, b.uv) and np.array_equal(a.Fuv, b.Fuv)
