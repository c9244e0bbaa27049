"""The one table of output formats: what ``unwrap -o``, ``--report``, ``--preview`` and ``batch --format`` accept,
and how each is written from a finished run.

A new output format is a module in ``heatparam.formats`` with a ``write_<format>(path, ...)`` over plain arrays,
plus one :class:`Exporter` line in :data:`EXPORTERS` whose ``write`` hands it the run. Nothing else lists formats:
the output checks (``formats.outputs.plan_outputs``), the unwrap job (``heatparam.unwrap``), the batch runner and
the command line all read this table. Importing this module loads no numerics (``heatparam --help`` reads it);
each ``write`` imports its writer when it runs.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from heatparam.errors import HeatparamError
from heatparam.version import __version__


@dataclass(frozen=True)
class Run:
    """A finished run and the settings of its outputs: what every exporter's ``write`` is handed.

    V, F : the input mesh. result : the pipeline's ``Result`` (``uv, Fuv, uv_vertex, report``, ``chart`` for an
    atlas, ``fill_surface``). units : the model's units. pattern : the laid-out flat pattern when a format that
    draws it was asked for, else None. strain_map, fit_tolerance : as ``heatparam unwrap``'s flags. names : the
    final file name of each planned format (a writer that records its own name, as STEP does, writes to a
    temporary).
    """

    V: Any
    F: Any
    result: Any
    units: str
    pattern: Any = None
    strain_map: bool = False
    fit_tolerance: float | None = None
    names: dict[str, str] = field(default_factory=dict)

    @property
    def chart(self):
        return getattr(self.result, "chart", None)

    @property
    def title(self) -> str:
        """The input's file name (annotations and the preview's title)."""
        return Path(self.result.report.get("input", "")).name

    @property
    def texture(self) -> int | None:
        """The texture's size in pixels when the UVs are texture space ([0,1]², an atlas packed with ``pack
        texture``), else None (true scale, model units)."""
        atlas = self.result.report.get("method", {}).get("atlas")
        if atlas and atlas.get("parameters", {}).get("pack") == "texture":
            return int(self.result.report["parameters"]["resolution"])
        return None

    @property
    def header(self) -> str:
        """The comment line of the mesh formats: what the texture coordinates are."""
        if self.texture:
            return (f"heatparam {__version__}: vt = texture space [0,1]^2 ({self.texture} px at --resolution; "
                    f"model units: {self.units})")
        return f"heatparam {__version__}: vt = true-scale UV in {self.units} (model units: {self.units})"


#: ``write(path, run)`` writes the whole file at ``path`` and returns the facts the report lists about it (a dict
#: with at least ``format``).
Writer = Callable[[Path, Run], dict]


@dataclass(frozen=True)
class Exporter:
    """One output format.

    name : the format's name (``batch --format``, the report's ``format``). suffixes : the file extensions that
    select it, the first one canonical. module : the module holding its writer, imported to check it is usable.
    write : writes it from a :class:`Run`; None for a file that a command writes itself (``geodesics``' array).
    requires : a module outside heatparam's own that the writer needs. map : written by ``unwrap -o``.
    batch : offered by ``batch --format``. pattern : drawn from the laid-out flat pattern.
    """

    name: str
    suffixes: tuple[str, ...]
    module: str
    write: Writer | None = None
    requires: str | None = None
    map: bool = False
    batch: bool = False
    pattern: bool = False

    def check_importable(self) -> None:
        """A one-line error when this installation cannot import the writer (before any computation)."""
        try:
            importlib.import_module(self.module)
        except ImportError as exc:
            raise HeatparamError(f"{self.name.upper()} output ({'/'.join(self.suffixes)}) is unavailable in this "
                                 f"installation ({exc})") from None

    def missing_requirement(self) -> str | None:
        """The module this format needs and this installation lacks, found without importing it; else None."""
        if self.requires is None:
            return None
        try:
            found = importlib.util.find_spec(self.requires) is not None
        except ModuleNotFoundError:  # a parent package of a dotted name is missing
            found = False
        return None if found else self.requires


def _obj(path: Path, run: Run) -> dict:
    from heatparam.formats.uvobj import save_uv_obj

    r = run.result
    save_uv_obj(path, run.V, run.F, r.uv, header=run.header, Fuv=r.Fuv)
    return {"format": "obj", "units": run.units}


def _ply(path: Path, run: Run) -> dict:
    from heatparam.formats.meshuv import write_ply

    r = run.result
    return write_ply(path, run.V, r.uv, r.Fuv, r.uv_vertex, units=run.units, comment=run.header)


def _glb(path: Path, run: Run) -> dict:
    from heatparam.formats.meshuv import write_glb

    r = run.result
    return write_glb(path, run.V, r.uv, r.Fuv, r.uv_vertex, units=run.units, comment=run.header)


def _dxf(path: Path, run: Run) -> dict:
    from heatparam.formats.dxf import write_dxf

    return write_dxf(path, run.pattern, units=run.units, title=run.title)


def _svg(path: Path, run: Run) -> dict:
    from heatparam.formats.svg import write_svg

    return write_svg(path, run.pattern, units=run.units, title=run.title, V=run.V, strain_map=run.strain_map,
                     texture=run.texture)


def _step(path: Path, run: Run) -> dict:
    """The STEP file; where it misses the fit tolerance (or is invalid, or unsewn) its warnings join the report's,
    which the caller prints, instead of Python warnings."""
    import warnings

    from heatparam.formats.step import StepToleranceWarning, write_step

    r = run.result
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepToleranceWarning)
        info = write_step(path, run.V, run.F, r.uv, r.Fuv, r.uv_vertex, chart=run.chart, units=run.units,
                          tolerance=run.fit_tolerance, name=run.names.get("step"))
    r.report.setdefault("warnings", []).extend(f"STEP: {w}" for w in info["warnings"])
    return info


def _preview(path: Path, run: Run) -> dict:
    from heatparam.formats.preview import save_preview

    r = run.result
    save_preview(path, run.V[r.uv_vertex], r.Fuv, r.uv, title=run.title or "map", fill_surface=r.fill_surface,
                 units=run.units, metrics=r.report["metrics"], vertex=r.uv_vertex, chart=run.chart,
                 texture=run.texture)
    return {"format": "png"}


def _report(path: Path, run: Run) -> dict:
    from heatparam.formats.files import save_json

    save_json(path, run.result.report)
    return {"format": "json"}


#: Every output format, in the order ``batch --format``'s help lists them.
EXPORTERS = (
    Exporter("obj", (".obj",), "heatparam.formats.uvobj", _obj, map=True, batch=True),
    Exporter("json", (".json",), "heatparam.formats.files", _report, batch=True),  # the report, always written
    Exporter("ply", (".ply",), "heatparam.formats.meshuv", _ply, map=True, batch=True),
    Exporter("glb", (".glb",), "heatparam.formats.meshuv", _glb, "trimesh", map=True, batch=True),
    Exporter("dxf", (".dxf",), "heatparam.formats.dxf", _dxf, "ezdxf", map=True, batch=True, pattern=True),
    Exporter("svg", (".svg",), "heatparam.formats.svg", _svg, map=True, batch=True, pattern=True),
    Exporter("step", (".step", ".stp"), "heatparam.formats.step", _step, "OCP", map=True, batch=True),
    Exporter("png", (".png",), "heatparam.formats.preview", _preview),  # --preview
    Exporter("npy", (".npy",), "heatparam.formats.files"),  # geodesics' distances
)
#: name → exporter
BY_NAME = {e.name: e for e in EXPORTERS}


def by_suffix(suffix: str) -> Exporter | None:
    """The exporter of a file extension (any case, with its dot), or None."""
    return next((e for e in EXPORTERS if suffix.lower() in e.suffixes), None)


def map_formats() -> tuple[str, ...]:
    """The formats ``unwrap -o`` writes."""
    return tuple(e.name for e in EXPORTERS if e.map)


def batch_formats() -> tuple[str, ...]:
    """The names ``batch --format`` accepts."""
    return tuple(e.name for e in EXPORTERS if e.batch)
