"""The heatparam options the operators offer and Blender's scene units as heatparam's ``--units``: plain data, no
``bpy`` (the test suite compares them with heatparam's own tables without Blender).

heatparam runs as a separate program (``runner``), so its tables cannot be imported here: :data:`KNOBS` copies the
entries of ``heatparam.options.OPTIONS`` that the operators offer and :data:`METRES` the metres per unit of
``heatparam.formats.units.UNITS``; ``tests/test_blender.py`` fails when either drifts from heatparam's.
"""

from __future__ import annotations

from typing import Any, NamedTuple


class Knob(NamedTuple):
    """One heatparam option as an operator property: its name (heatparam's), kind (``choice``, ``float``,
    ``int``), default, allowed choices or range, command-line flag and the options table's one-line help."""

    name: str
    kind: str
    default: Any
    flag: str
    help: str
    choices: tuple = ()
    low: float | None = None
    high: float | None = None


KNOBS: dict[str, Knob] = {k.name: k for k in (
    Knob("pack", "choice", "scale", "--pack", "true scale, or UVs in [0,1]²", ("scale", "texture")),
    Knob("max_distortion", "float", 0.0, "--max-distortion", "chart distortion bound; 0 = auto (1.05)",
         low=0.0, high=100.0),
    Knob("max_charts", "int", 0, "--max-charts", "cap on the charts per part; 0 = none", low=0, high=10**6),
    Knob("padding", "float", 4.0, "--padding", "gutter between charts, pixels", low=0.0, high=1e4),
    Knob("resolution", "int", 1024, "--resolution", "texture size in pixels", low=16, high=2**20),
    Knob("seams", "choice", "auto", "--seams", "cut holes open to the border", ("auto", "holes", "none")),
)}

#: heatparam's unit names (``--units``) and their length in metres
METRES: dict[str, float] = {"mm": 0.001, "cm": 0.01, "m": 1.0, "in": 0.0254, "ft": 0.3048}
#: Blender's ``unit_settings.length_unit`` → heatparam's unit name
BLENDER_UNITS: dict[str, str] = {"MILLIMETERS": "mm", "CENTIMETERS": "cm", "METERS": "m", "INCHES": "in",
                                 "FEET": "ft"}
#: Blender's length units heatparam has no name for → the nearest one it has (a pattern in km or miles is unlikely;
#: Adaptive shows whichever unit fits a value, so its system's base unit stands for it)
NEAREST_UNIT: dict[str, str] = {"MICROMETERS": "MILLIMETERS", "KILOMETERS": "METERS", "THOU": "INCHES",
                                "MILES": "FEET", "ADAPTIVE_METRIC": "METERS", "ADAPTIVE_IMPERIAL": "INCHES"}


def scene_units(system: str, length_unit: str, scale_length: float) -> tuple[str | None, float]:
    """heatparam's unit for a scene's unit settings and the factor that turns Blender units into it.

    Parameters
    ----------
    system : ``unit_settings.system`` (``METRIC``, ``IMPERIAL``, ``NONE``).
    length_unit : ``unit_settings.length_unit`` (``MILLIMETERS``, ``ADAPTIVE``, ...).
    scale_length : ``unit_settings.scale_length``: metres per Blender unit.

    Returns
    -------
    (unit, factor): coordinates × factor are lengths in ``unit``. Without a unit system (``NONE``) the unit is None
    and the factor 1: heatparam then reads the coordinates in its default unit, as ``heatparam unwrap`` does without
    ``--units``.
    """
    if system == "NONE":
        return None, 1.0
    if length_unit == "ADAPTIVE":
        length_unit = f"ADAPTIVE_{system}"
    unit = BLENDER_UNITS[NEAREST_UNIT.get(length_unit, length_unit)]
    return unit, float(scale_length) / METRES[unit]


def knob_args(values: dict[str, Any]) -> list[str]:
    """``heatparam unwrap`` flags for knob values (``{"pack": "texture"}`` → ``["--pack", "texture"]``)."""
    return [a for name, v in values.items() for a in (KNOBS[name].flag, f"{v:g}" if isinstance(v, float) else str(v))]
