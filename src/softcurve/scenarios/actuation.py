"""Actuators from configuration tables: the ``[actuation]`` table of a scenario file.

Translates a table (keys and values as TOML gives them) into a description of
:mod:`softcurve.description.bellows` or :mod:`softcurve.description.tendons`; no
physics here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, fields

from softcurve.base.validation import ParameterError, real_scalar
from softcurve.description.actuator import Actuator
from softcurve.description.bellows import Bellows, ConstantPressureMap, PneumaticActuator
from softcurve.description.tendons import Tendon, TendonActuator

_ENTRY_KEYS = {
    "bellows": {"azimuth", "distance", "area", "p_min", "p_max", "segments"},
    "tendons": {"azimuth", "distance", "t_max", "t_min", "anchor", "friction"},
}
"""Keys of one table of an explicit ``bellows`` or ``tendons`` list."""

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
    "tendons": {
        "kind",
        "distance",
        "t_max",
        "t_min",
        "azimuths",
        "friction",
        "time_constant",
        "tendons",
    },
    "constant": {"kind", "matrix", "p_min", "p_max", "time_constant"},
    "authors_fit": {"kind", "a_e", "a_k", "azimuths", "p_min", "p_max", "time_constant"},
}

_REQUIRED = {
    "bellows": ("distance", "area", "p_max"),
    "tendons": ("distance", "t_max"),
    "constant": ("matrix", "p_max"),
    "authors_fit": ("p_max",),
}
"""Required keys of each kind (for bellows and tendons: without an explicit list)."""


def from_mapping(
    mapping: Mapping, *, n_segments: int = 1, where: str = "actuation", robot=None
) -> Actuator:
    """An actuator from a configuration table (e.g. TOML ``[actuation]``).

    ``kind = "bellows"`` (default): either ``distance``, ``area``, ``p_max`` (and optional
    ``azimuths`` [rad], ``p_min``) for three bellows per segment, or a list ``bellows`` of
    tables with keys ``azimuth, distance, area, p_max, p_min, segments``.
    ``kind = "tendons"`` (the default next to a ``tendons`` list): either ``distance``
    [m], ``t_max`` [N] (and optional ``t_min`` [N], ``azimuths`` [rad], ``friction``) for
    three tendons tied to the tip of every segment
    (:meth:`TendonActuator.three_per_segment`), or a list ``tendons`` of tables with keys
    ``azimuth, distance, t_max, t_min, anchor, friction`` (:class:`Tendon`).
    ``kind = "constant"``: ``matrix`` (n x m), ``p_max``, ``p_min``.
    ``kind = "authors_fit"``: ``a_e``, ``a_k``, ``p_max``, ``p_min``, ``azimuths``.
    Every kind accepts ``time_constant`` [s]. Unknown keys raise :class:`ParameterError`
    naming them, as does any bad value (prefixed by ``where``).

    Parameters
    ----------
    mapping : Mapping
        The table, keys as above.
    n_segments : int
        Number of constant-curvature segments of the robot driven (without ``robot``).
    where : str
        Where the table came from, for messages.
    robot : Robot, optional
        The robot driven: bellows and tendons then run along its elements (any kind;
        three per soft segment for the short forms), and its ``n`` is the actuator's.
    """
    if not isinstance(mapping, Mapping):
        raise ParameterError(f"{where} must be a table, got {type(mapping).__name__}")
    kind = mapping.get("kind", "tendons" if "tendons" in mapping else "bellows")
    if kind not in _KEYS:
        raise ParameterError(f"{where}.kind must be one of {sorted(_KEYS)}, got {kind!r}")
    unknown = sorted(set(mapping) - _KEYS[kind])
    if unknown:
        raise ParameterError(
            f"{where}: unknown key(s) {unknown} for kind {kind!r}; allowed: {sorted(_KEYS[kind])}"
        )
    args = {k: v for k, v in mapping.items() if k != "kind"}
    explicit = kind in _ENTRY_KEYS and kind in args  # a list of bellows or of tendons
    missing = [k for k in (() if explicit else _REQUIRED[kind]) if k not in args]
    if missing:
        raise ParameterError(f"{where}: missing required key(s) {missing} for kind {kind!r}")
    try:
        if "azimuths" in args:
            args["azimuths"] = _azimuths(args["azimuths"])
        if kind == "constant":
            args["constant"] = args.pop("matrix")
            result = ConstantPressureMap(**args)
        elif kind == "authors_fit":
            result = ConstantPressureMap.authors_fit(**args)
        elif robot is not None and not robot.constant_curvature:
            chain = {"elements": robot}
            if explicit:
                result = _listed(kind, args, chain)
            elif kind == "tendons":
                result = TendonActuator.three_per_segment(**chain, **args)
            else:
                result = PneumaticActuator.three_bellows(**chain, **args)
        elif explicit:
            result = _listed(kind, args, {"n_segments": n_segments})
        elif kind == "tendons":
            result = TendonActuator.three_per_segment(n_segments=n_segments, **args)
        else:
            result = PneumaticActuator.three_bellows(n_segments=n_segments, **args)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    n = 3 * n_segments if robot is None else robot.n
    if result.n != n:
        raise ParameterError(
            f"{where}: the actuator acts on n = {result.n} coordinates, the robot has {n}"
        )
    return result


def _azimuths(value) -> tuple[float, ...]:
    """``azimuths`` as a non-empty tuple of finite numbers [rad]."""
    if isinstance(value, str | bytes | Mapping) or not hasattr(value, "__iter__"):
        raise ParameterError(f"azimuths must be an array of angles [rad], got {value!r}")
    angles = tuple(real_scalar(f"azimuths[{i}]", a) for i, a in enumerate(value))
    if not angles:
        raise ParameterError("azimuths must hold at least one angle [rad], got none")
    return angles


def _listed(kind: str, args: dict, chain: dict) -> Actuator:
    """The actuator of an explicit list of ``bellows`` or ``tendons`` tables, on the chain
    ``chain`` (``{"n_segments": N}`` or ``{"elements": robot}``)."""
    extra = sorted(set(args) - {kind, "time_constant"})
    if extra:
        raise ParameterError(f"keys {extra} are not allowed next to a {kind!r} list")
    tables = args[kind]
    if isinstance(tables, Mapping) or not isinstance(tables, list | tuple) or not tables:
        raise ParameterError(f"{kind} must be a non-empty array of tables ([[actuation.{kind}]])")
    element = Bellows if kind == "bellows" else Tendon
    entries = []
    for i, table in enumerate(tables):
        if not isinstance(table, Mapping):
            raise ParameterError(f"{kind}[{i}] must be a table, got {type(table).__name__}")
        bad = sorted(set(table) - _ENTRY_KEYS[kind])
        if bad:
            raise ParameterError(
                f"{kind}[{i}]: unknown key(s) {bad}; allowed: {sorted(_ENTRY_KEYS[kind])}"
            )
        missing = [f.name for f in fields(element) if f.default is MISSING and f.name not in table]
        if missing:
            raise ParameterError(f"{kind}[{i}]: missing required key(s) {missing}")
        try:
            entries.append(element(**table))
        except ParameterError as exc:
            raise ParameterError(f"{kind}[{i}]: {exc}") from None
    build = PneumaticActuator if kind == "bellows" else TendonActuator
    return build(tuple(entries), time_constant=args.get("time_constant"), **chain)
