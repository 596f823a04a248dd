"""Obstacles and contact law from configuration tables: the ``[environment]`` table of a
scenario file (docs/configuration.md, docs/contact.md).

Translates a table (keys and values as TOML gives them) into a
:class:`~softcurve.description.environment.Environment`; no physics here::

    [environment]
    contact_radius = [0.005]          # optional, one per segment [m]

    [environment.law]                 # softcurve.ContactLaw
    stiffness = 1e7
    damping = 1.0

    [[environment.obstacles]]
    kind = "plane"                    # or "sphere", "capsule"
    point = [0.03, 0.0, 0.0]
    normal = [-1.0, 0.0, 0.0]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, fields

from softcurve.base.validation import ParameterError
from softcurve.description.environment import Capsule, ContactLaw, Environment, Plane, Sphere

KINDS = {"plane": Plane, "sphere": Sphere, "capsule": Capsule}
"""Obstacle kinds by their ``kind`` key."""
_KEYS = {"law", "obstacles", "contact_radius"}


def _keys(cls) -> list[str]:
    """The keys a table of ``cls`` takes: its constructor's (not fields it derives, such
    as a capsule's unit ``axis``)."""
    return [f.name for f in fields(cls) if f.init]


def _required(cls) -> list[str]:
    return [f.name for f in fields(cls) if f.init and f.default is MISSING]


def _table(where: str, value, what: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise ParameterError(f"{where} must be {what}, got {type(value).__name__} {value!r}")
    return value


def _build(cls, table: Mapping, where: str, skip=()):
    """``cls(**table)`` with unknown and missing keys named."""
    allowed = _keys(cls)
    unknown = sorted(set(table) - set(allowed) - set(skip))
    if unknown:
        raise ParameterError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    missing = [k for k in _required(cls) if k not in table]
    if missing:
        raise ParameterError(f"{where}: missing required key(s) {missing}")
    try:
        return cls(**{k: v for k, v in table.items() if k not in skip})
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None


def obstacle_from_mapping(table: Mapping, where: str = "obstacle"):
    """One obstacle from a table with ``kind = "plane"`` (``point``, ``normal``),
    ``"sphere"`` (``center``, ``radius``) or ``"capsule"`` (``a``, ``b``, ``radius``).

    Parameters
    ----------
    table : Mapping
        The table; points in metres, in the robot's base frame.
    where : str
        Where the table came from, for messages.
    """
    table = _table(where, table, "a table")
    kind = table.get("kind")
    if kind not in KINDS:
        raise ParameterError(f"{where}.kind must be one of {sorted(KINDS)}, got {kind!r}")
    return _build(KINDS[kind], table, where, skip=("kind",))


def environment_from_mapping(mapping: Mapping, *, where: str = "environment") -> Environment:
    """An :class:`Environment` from a configuration table (e.g. TOML ``[environment]``).

    Keys: ``obstacles`` (required, an array of tables, see :func:`obstacle_from_mapping`),
    ``law`` (required, the keyword arguments of :class:`ContactLaw`) and
    ``contact_radius`` (optional, one radius [m] per segment). Unknown keys raise
    :class:`ParameterError` naming them, as does any bad value (prefixed by ``where``).

    Parameters
    ----------
    mapping : Mapping
        The table, keys as above.
    where : str
        Where the table came from, for messages.
    """
    mapping = _table(where, mapping, "a table")
    unknown = sorted(set(mapping) - _KEYS)
    if unknown:
        raise ParameterError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_KEYS)}")
    missing = [k for k in ("law", "obstacles") if k not in mapping]
    if missing:
        raise ParameterError(f"{where}: missing required key(s) {missing}")
    law = _build(ContactLaw, _table(f"{where}.law", mapping["law"], "a table"), f"{where}.law")
    tables = mapping["obstacles"]
    if isinstance(tables, Mapping) or not isinstance(tables, list | tuple) or not tables:
        raise ParameterError(
            f"{where}.obstacles must be a non-empty array of tables ([[{where}.obstacles]])"
        )
    obstacles = [obstacle_from_mapping(t, f"{where}.obstacles[{i}]") for i, t in enumerate(tables)]
    radius = mapping.get("contact_radius")
    if radius is not None and (isinstance(radius, str | Mapping) or not isinstance(radius, list)):
        raise ParameterError(
            f"{where}.contact_radius must be an array of radii [m], one per segment, got {radius!r}"
        )
    try:
        return Environment(tuple(obstacles), law, None if radius is None else tuple(radius))
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
