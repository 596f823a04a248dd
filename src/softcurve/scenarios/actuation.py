"""Actuators from configuration tables: the ``[actuation]`` table of a scenario file.

Translates a table (keys and values as TOML gives them) into a description of
:mod:`softcurve.description.pneumatic`; no physics here.
"""

from __future__ import annotations

from collections.abc import Mapping

from softcurve.base.validation import ParameterError
from softcurve.description.actuator import Actuator
from softcurve.description.pneumatic import Bellows, ConstantPressureMap, PneumaticActuator

_BELLOWS_KEYS = {"azimuth", "distance", "area", "p_min", "p_max", "segments"}
_KEYS = {
    "bellows": {
        "kind",
        "distance",
        "area",
        "azimuths",
        "p_min",
        "p_max",
        "time_constant",
        "bellows",
    },
    "constant": {"kind", "matrix", "p_min", "p_max", "time_constant"},
    "authors_fit": {"kind", "a_e", "a_k", "azimuths", "p_min", "p_max", "time_constant"},
}


def from_mapping(mapping: Mapping, *, n_segments: int = 1, where: str = "actuation") -> Actuator:
    """An actuator from a configuration table (e.g. TOML ``[actuation]``).

    ``kind = "bellows"`` (default): either ``distance``, ``area``, ``p_max`` (and optional
    ``azimuths`` [rad], ``p_min``) for three bellows per segment, or a list ``bellows`` of
    tables with keys ``azimuth, distance, area, p_max, p_min, segments``.
    ``kind = "constant"``: ``matrix`` (n x m), ``p_max``, ``p_min``.
    ``kind = "authors_fit"``: ``a_e``, ``a_k``, ``p_max``, ``p_min``, ``azimuths``.
    Every kind accepts ``time_constant`` [s]. Unknown keys raise :class:`ParameterError`
    naming them, as does any bad value (prefixed by ``where``).

    Parameters
    ----------
    mapping : Mapping
        The table, keys as above.
    n_segments : int
        Number of segments of the robot driven.
    where : str
        Where the table came from, for messages.
    """
    if not isinstance(mapping, Mapping):
        raise ParameterError(f"{where} must be a table, got {type(mapping).__name__}")
    kind = mapping.get("kind", "bellows")
    if kind not in _KEYS:
        raise ParameterError(f"{where}.kind must be one of {sorted(_KEYS)}, got {kind!r}")
    unknown = sorted(set(mapping) - _KEYS[kind])
    if unknown:
        raise ParameterError(
            f"{where}: unknown key(s) {unknown} for kind {kind!r}; allowed: {sorted(_KEYS[kind])}"
        )
    args = {k: v for k, v in mapping.items() if k != "kind"}
    required = {"constant": ("matrix", "p_max"), "authors_fit": ("p_max",)}.get(
        kind, () if "bellows" in args else ("distance", "area", "p_max")
    )
    missing = [k for k in required if k not in args]
    if missing:
        raise ParameterError(f"{where}: missing required key(s) {missing} for kind {kind!r}")
    try:
        if kind == "constant":
            args["constant"] = args.pop("matrix")
            result = ConstantPressureMap(**args)
        elif kind == "authors_fit":
            result = ConstantPressureMap.authors_fit(**args)
        elif "bellows" in args:
            extra = sorted(set(args) - {"bellows", "time_constant"})
            if extra:
                raise ParameterError(f"keys {extra} are not allowed next to a 'bellows' list")
            tables = args["bellows"]
            chambers = []
            for i, table in enumerate(tables):
                if not isinstance(table, Mapping):
                    raise ParameterError(f"bellows[{i}] must be a table")
                bad = sorted(set(table) - _BELLOWS_KEYS)
                if bad:
                    raise ParameterError(
                        f"bellows[{i}]: unknown key(s) {bad}; allowed: {sorted(_BELLOWS_KEYS)}"
                    )
                try:
                    chambers.append(Bellows(**table))
                except TypeError as exc:
                    raise ParameterError(f"bellows[{i}]: {exc}") from None
            result = PneumaticActuator(
                tuple(chambers), n_segments=n_segments, time_constant=args.get("time_constant")
            )
        else:
            result = PneumaticActuator.three_bellows(n_segments=n_segments, **args)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    if result.n != 3 * n_segments:
        raise ParameterError(
            f"{where}: the actuator acts on n = {result.n} coordinates, "
            f"the robot has {3 * n_segments}"
        )
    return result
