"""Model units declared with ``--units``: their DXF ``$INSUNITS`` codes and their size in millimetres."""

from __future__ import annotations

#: unit name → (DXF $INSUNITS code, millimetres per unit)
UNITS: dict[str, tuple[int, float]] = {
    "mm": (4, 1.0),
    "cm": (5, 10.0),
    "m": (6, 1000.0),
    "in": (1, 25.4),
    "ft": (2, 304.8),
}
DEFAULT_UNITS = "mm"


def insunits(units: str) -> int:
    """DXF ``$INSUNITS`` code of a unit name (mm 4, cm 5, m 6, in 1, ft 2)."""
    return UNITS[units][0]


def svg_length(value: float, units: str) -> str:
    """A physical SVG length for ``value`` model units: kept in mm, cm or in; m → mm, ft → in."""
    if units in ("mm", "cm", "in"):
        return f"{value:.6g}{units}"
    if units == "m":
        return f"{value * 1000.0:.6g}mm"
    return f"{value * 12.0:.6g}in"
