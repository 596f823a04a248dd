"""Units of measured signals and inputs: known units, conversion to SI, mismatch checks.

An :class:`~softcurve.identification.experiments.Experiment` converts each column once,
when it is built, from the unit it was recorded in to the SI unit of its kind (pressure
to Pa, length to m, curvature to 1/m, force to N), and records the original unit.
Angles are the exception: they stay in the unit recorded, ``"deg"`` or ``"rad"``,
because output maps give either (``bending_angle_map(degrees=...)``); the maps' units are
then compared by :func:`check_units`, which catches a signal or input whose unit is not
the one a map expects (psi data labelled as such are converted to Pa at load; an
unlabelled column, unit ``""``, cannot be checked).
"""

from __future__ import annotations

from softcurve.identification.experiments._errors import UnitError

POUND_FORCE_PER_SQUARE_INCH = 0.45359237 * 9.80665 / 0.0254**2
"""1 psi [Pa]: one pound-force (0.45359237 kg at standard gravity 9.80665 m/s^2, both
exact by definition) per square inch (0.0254 m exactly): 6894.757... Pa."""

UNITS = {
    "pressure": ("Pa", {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "mbar": 1e2, "bar": 1e5,
                        "psi": POUND_FORCE_PER_SQUARE_INCH}),
    "length": ("m", {"m": 1.0, "cm": 1e-2, "mm": 1e-3}),
    "curvature": ("1/m", {"1/m": 1.0, "1/cm": 1e2, "1/mm": 1e3}),
    "force": ("N", {"N": 1.0, "mN": 1e-3}),
    "angle": (None, {"rad": 1.0, "deg": 1.0}),
    "acceleration": ("m/s^2", {"m/s^2": 1.0, "g": 1.0}),
    "none": ("", {"": 1.0, "-": 1.0, "1": 1.0}),
}  # fmt: skip
"""Kind -> (SI unit, {unit: factor to SI}); an SI unit None keeps the unit recorded.
``"g"`` (standard gravities, as an accelerometer reports) is kept as recorded too, since
:func:`~softcurve.identification.maps.imu_orientation_map` gives it."""

KEPT = {"rad", "deg", "g"}
"""Units that stay as recorded (no conversion)."""


def kind_of(unit: str) -> str | None:
    """The kind of a known unit (``"pressure"``, ``"length"``, ...), or None.

    Parameters
    ----------
    unit : str
        A unit, e.g. ``"kPa"``.
    """
    for kind, (_, table) in UNITS.items():
        if unit in table:
            return kind
    return None


def allowed_units() -> list[str]:
    """Every known unit, by kind."""
    return [u for _, table in UNITS.values() for u in table]


def to_si(name: str, unit: str, where: str) -> tuple[str, float]:
    """``(unit stored, factor)``: the values of a column recorded in ``unit`` are stored
    times ``factor`` in the unit stored (SI, or the unit itself for angles).

    Parameters
    ----------
    name : str
        The column (signal or input), for the message.
    unit : str
        Its unit as recorded.
    where : str
        The experiment or file, for the message.
    """
    unit = str(unit).strip()
    kind = kind_of(unit)
    if kind is None:
        raise UnitError(
            f"{where}: {name!r} has the unknown unit {unit!r}; known units: "
            + "; ".join(f"{k} {sorted(t)}" for k, (_, t) in UNITS.items() if k != "none")
            + " (or '' when unspecified)"
        )
    si, table = UNITS[kind]
    if unit in KEPT:
        return unit, 1.0
    return si, table[unit]


def _compatible(unit: str) -> list[str]:
    kind = kind_of(unit)
    if kind is None or unit in KEPT:
        return [unit]
    return sorted(UNITS[kind][1])


def _check(where, kind, name, recorded, stored, expected, hint) -> None:
    if not stored or not expected or stored == expected:
        return
    source = f" (recorded in {recorded!r})" if recorded and recorded != stored else ""
    converted = source and stored not in KEPT and kind_of(stored) is not None
    if converted and expected not in KEPT and kind_of(expected) == kind_of(stored):
        # e.g. a SensorFrame(scale=1000, unit="mm") against data labelled "mm"
        scale = " (a scale of 1)" if kind == "signal" else ""
        raise UnitError(
            f"{where}: {kind} {name!r} is in {stored!r}{source}, converted at load, but "
            f"the {hint} gives {expected!r}: experiments are SI after loading, so build "
            f"the map in {stored!r}{scale}"
        )
    raise UnitError(
        f"{where}: {kind} {name!r} is in {stored!r}{source} but the {hint} expects "
        f"{expected!r}; label it with one of {_compatible(expected)} (converted at load) "
        "or use a map in its unit"
    )


def check_units(experiment, *, output=None, input_map=None, signals=None) -> None:
    """Raise :class:`UnitError` where a column's unit is not the one its map expects.

    Signals are matched to the output map's outputs in order, inputs to the input map's
    ``units`` (when it gives them; their count must then equal the experiment's number
    of inputs). Columns or maps with unit ``""`` are not checked.

    Parameters
    ----------
    experiment : Experiment
        The experiment (its ``units`` and ``source_units``).
    output : OutputMap, optional
        The output map.
    input_map : InputMap, optional
        The input map.
    signals : list of str, optional
        The experiment's signals matched to the outputs, in order (default: the output
        map's names).
    """
    where = f"experiment {experiment.name!r}"
    recorded = getattr(experiment, "source_units", {})
    if output is not None:
        names = list(output.names) if signals is None else list(signals)
        for name, expected in zip(names, output.units, strict=False):
            stored = experiment.units.get(name, "")
            _check(where, "signal", name, recorded.get(name), stored, expected, "output map")
    expected_inputs = tuple(getattr(input_map, "units", ()) or ())
    if expected_inputs:
        names = list(experiment.inputs)
        if len(names) != len(expected_inputs):
            raise UnitError(
                f"{where}: the input map reads {len(expected_inputs)} inputs "
                f"{expected_inputs}, the experiment has {len(names)}: {names}"
            )
        for name, expected in zip(names, expected_inputs, strict=True):
            stored = experiment.units.get(name, "")
            _check(where, "input", name, recorded.get(name), stored, expected, "input map")
