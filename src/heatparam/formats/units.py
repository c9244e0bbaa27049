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
#: Sizes across (mm) outside which a part read in the default unit was most likely modelled in another one: meshes
#: normalized to about 1 unit (cow 1.04, camelhead and beetle 1.0) are read as 1 mm parts, and no pattern covers 100 m.
PLAUSIBLE_MM = (10.0, 100_000.0)


def assumed_units_warning(size: float, units: str = DEFAULT_UNITS) -> str | None:
    """The warning for a model whose unit was not given and that is ``size`` ``units`` across: None when that is a
    plausible size (:data:`PLAUSIBLE_MM`), else what was assumed and what to pass."""
    mm = size * UNITS[units][1]
    if PLAUSIBLE_MM[0] <= mm <= PLAUSIBLE_MM[1]:
        return None
    others = ", ".join(u for u in UNITS if u != units)
    bound = f"under {PLAUSIBLE_MM[0]:g} mm" if mm < PLAUSIBLE_MM[0] else f"over {PLAUSIBLE_MM[1] / 1000:g} m"
    return (f"no --units given: the model is read in {units}, which makes the part {size:.3g} {units} across "
            f"({bound}); pass --units with the unit it was modelled in ({others}), or scale the mesh to one of them")


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


def uv_unit(units: str | None, texture: int | None = None) -> str:
    """What one UV unit is, for axis labels: the model's unit, or texture space (``texture``: its size in pixels,
    ``pack texture``, where UVs are in [0,1]²)."""
    return f"texture space, 1 = {texture} px" if texture else (units or "model units")


def uv_length(x: float, units: str | None, texture: int | None = None) -> str:
    """A UV length as a label: ``0.2 mm``, or in texture space ``0.2 = 204.8 px`` (``texture``: pixels across)."""
    return f"{x:g} = {x * texture:g} px" if texture else f"{x:g} {units or 'model units'}"
