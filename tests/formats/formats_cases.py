"""Maps shared by the output-format tests: a developable part with holes, a two-chart atlas of it, halftunnel."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

import heatparam
from heatparam import datasets, formats

from conftest import shared_mesh


@dataclass
class Map:
    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    Fuv: np.ndarray
    uv_vertex: np.ndarray
    chart: np.ndarray | None = None

    @property
    def arrays(self):
        return self.V, self.F, self.uv, self.Fuv, self.uv_vertex, self.chart


def write_off(path, V, F):
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
        np.savetxt(fh, V, fmt="%.17g")
        np.savetxt(fh, np.column_stack([np.full(len(F), 3), F]), fmt="%d")
    return path


@functools.cache
def cylinder_map() -> Map:
    """cylinder_with_holes (developable: outline with a notch, two round holes) flattened by heatparam."""
    sh = datasets.cylinder_with_holes()
    r = heatparam.parameterize(sh.V, sh.F, progress=False)
    return Map(sh.V, sh.F, r.uv, r.Fuv, r.uv_vertex)


def split_charts(m: Map, chart: np.ndarray) -> Map:
    """The map ``m`` cut into the charts ``chart`` (m,) (each with its own uv rows), every chart moved to the
    origin so that their bounding boxes overlap."""
    Fuv = m.Fuv.copy()
    uvs, vs, n = [], [], 0
    for c in np.unique(chart):
        f = np.flatnonzero(chart == c)
        rows = np.unique(m.Fuv[f])
        remap = np.full(len(m.uv), -1)
        remap[rows] = np.arange(len(rows)) + n
        Fuv[f] = remap[m.Fuv[f]]
        n += len(rows)
        uvs.append(m.uv[rows] - m.uv[rows].min(axis=0))
        vs.append(m.uv_vertex[rows])
    return Map(m.V, m.F, np.concatenate(uvs), Fuv, np.concatenate(vs), chart)


@functools.cache
def two_chart_atlas() -> Map:
    """The cylinder map cut along the straight line x = -0.2 of its flat layout (clear of holes and notch) into
    two charts with their own uv rows, both moved to the origin so that their bounding boxes overlap."""
    sh = datasets.cylinder_with_holes()
    return split_charts(cylinder_map(), (sh.uv_true[sh.F].mean(axis=1)[:, 0] > -0.2).astype(np.int64))


@functools.cache
def halftunnel_map() -> Map:
    """halftunnel.off with the default seams (its holes cut open to the border)."""
    V, F = formats.load_mesh(shared_mesh("halftunnel.off"))
    r = heatparam.parameterize(V, F, progress=False)
    assert r.seamed
    return Map(V, F, r.uv, r.Fuv, r.uv_vertex)


def polyline_length(P: np.ndarray, closed: bool = True) -> float:
    P = np.asarray(P, dtype=np.float64)
    Q = np.roll(P, -1, axis=0) if closed else P[1:]
    return float(np.linalg.norm(Q - P[: len(Q)], axis=1).sum())


def edge_stretch_bounds(m: Map) -> tuple[float, float]:
    """[min sigma2, max sigma1] of the map's faces (true scale, no normalization): every UV edge's length over its
    3D length lies in this range, so does every boundary loop's."""
    from heatparam.metrics import face_jacobian_singular_values

    s1, s2, _, _ = face_jacobian_singular_values(m.V, m.F, m.uv, m.Fuv)
    return float(s2.min()), float(s1.max())
