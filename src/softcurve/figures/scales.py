"""Scales of the trajectory figures: which part of the time axis shows the motion (or the
contact, or its impact), which signals are round-off rather than motion, and equal 3-D
axes."""

from __future__ import annotations

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, real_scalar

NOISE = 1e-9
"""A signal whose magnitude stays below this fraction of the robot's scale (its length
for positions and lengths, one over it for curvatures) is round-off of an exact zero
(e.g. ``ky`` of a planar run, 1e-26 1/m) and is drawn as zero."""
SETTLED = 0.02
"""The motion has settled when every state stays within this fraction of its range of
the final value."""
WINDOW_MARGIN = 0.25
"""The automatic time window ends this fraction of the settling time after it."""
CONTACT_MARGIN = 0.25
"""The contact figure shows the contact and this fraction of its duration on either side,
so that the force is seen rising from zero and returning to it."""
IMPACT_LEVEL = 0.5
"""An impact lasts while the force stays above this fraction of its peak (the width at
half the peak)."""
SHORT_IMPACT = 0.05
"""An impact lasting less than this fraction of the contact shown is a spike on its axis:
the contact figure adds a zoom on it."""


def negligible(values, scale: float, tolerance: float = NOISE) -> bool:
    """True when every entry of ``values`` is below ``tolerance * scale`` in magnitude.

    Parameters
    ----------
    values : array_like, shape (T,)
        The signal [any unit].
    scale : float
        The robot's scale in the signal's unit [same unit].
    tolerance : float, optional
        Relative tolerance, dimensionless.

    Returns
    -------
    bool
    """
    values = np.asarray(values, dtype=np.float64)
    return bool(values.size) and bool(np.all(np.abs(values) <= tolerance * abs(scale)))


def settled_time(t, signals, fraction: float = SETTLED) -> float:
    """The time after which every signal stays within ``fraction`` of its range of its
    final value; ``t[-1]`` if it never settles.

    Parameters
    ----------
    t : array_like, shape (T,)
        Times [s].
    signals : array_like, shape (T, k)
        The signals [any units].
    fraction : float, optional
        Tolerance relative to each signal's range, dimensionless.

    Returns
    -------
    float
        The settling time [s].
    """
    t = np.asarray(t, dtype=np.float64)
    signals = np.asarray(signals, dtype=np.float64).reshape(t.size, -1)
    if t.size < 2:
        return float(t[-1]) if t.size else 0.0
    span = np.ptp(signals, axis=0)
    deviation = np.abs(signals - signals[-1]) > fraction * np.where(span > 0, span, np.inf)
    moving = np.flatnonzero(deviation.any(axis=1))
    return float(t[min(moving[-1] + 1, t.size - 1)]) if moving.size else float(t[0])


def time_window(t, signals, window) -> tuple[float, float]:
    """The time range a states figure shows.

    Parameters
    ----------
    t : array_like, shape (T,)
        Times [s].
    signals : array_like, shape (T, k)
        The signals drawn [any units].
    window : "auto", "all" or (float, float)
        ``"auto"``: from the start to a quarter past the time the signals settle
        (:func:`settled_time`); ``"all"``: the whole record; or ``(start, end)`` [s].

    Returns
    -------
    tuple of float
        ``(start, end)`` [s].
    """
    t = np.asarray(t, dtype=np.float64)
    if not t.size:
        return (0.0, 1.0)
    whole = (float(t[0]), float(t[-1]))
    if isinstance(window, str):
        if window == "all":
            return whole
        if window != "auto":
            raise ParameterError(f"window must be 'auto', 'all' or (start, end), got {window!r}")
        settled = settled_time(t, signals)
        end = t[0] + (1 + WINDOW_MARGIN) * (settled - t[0])
        return whole if end >= t[-1] or settled <= t[0] else (whole[0], float(end))
    try:
        start, end = window
    except (TypeError, ValueError):
        raise ParameterError(
            f"window must be 'auto', 'all' or (start, end), got {window!r}"
        ) from None
    start, end = real_scalar("window start", start), real_scalar("window end", end)
    if not end > start:
        raise ParameterError(f"window must have end > start, got ({start}, {end})")
    return (start, end)


def window_note(t, start: float, end: float) -> str:
    """``", t = 0 .. 0.654 s of 10 s"`` when ``(start, end)`` is not the whole record,
    ``", t = 0 .. 10 s"`` when it is: what a figure's title adds to say which window it
    shows.

    Parameters
    ----------
    t : array_like, shape (T,)
        The record's times [s].
    start, end : float
        The window shown [s].

    Returns
    -------
    str
    """
    t = np.asarray(t, dtype=np.float64)
    if t.size > 1 and (start, end) != (t[0], t[-1]):
        return f", t = {start:.3g} .. {end:.3g} s of {t[-1]:.3g} s"
    return f", t = {start:.3g} .. {end:.3g} s" if t.size > 1 else ""


def _around(t, first: int, last: int, margin: float) -> tuple[float, float]:
    """From the sample before ``first`` to the one after ``last`` (where the signal is
    back at its level), widened by ``margin`` of that span on either side, within ``t``."""
    start, end = t[max(first - 1, 0)], t[min(last + 1, t.size - 1)]
    pad = margin * (end - start)
    return (float(max(start - pad, t[0])), float(min(end + pad, t[-1])))


_FORCE_WINDOW = {
    "t": ("array_like, shape (T,)", "Times [s]."),
    "magnitude": (
        "array_like, shape (T, k)",
        "The force of each obstacle [N] (zero out of contact).",
    ),
}
"""The arguments of the contact figure's two windows."""
_forces_window = parameters_from(
    _FORCE_WINDOW, returns=("tuple of float or None", "``(start, end)`` [s].")
)


def _samples(t, magnitude) -> tuple[np.ndarray, np.ndarray]:
    """``t`` (T,) and the forces as (T, k) float arrays (k = 0 for an empty record)."""
    t = np.asarray(t, dtype=np.float64)
    return t, np.asarray(magnitude, dtype=np.float64).reshape(t.size, -1 if t.size else 0)


@_forces_window
def contact_window(t, magnitude) -> tuple[float, float] | None:
    """The time range of the contact: from the last sample before any force to the first
    after the last, with ``CONTACT_MARGIN`` of it on either side; None without contact
    (or samples).

    Parameters
    ----------
    %(t)s
    %(magnitude)s
    """
    t, forces = _samples(t, magnitude)
    touching = np.flatnonzero(np.any(forces > 0, axis=1))
    if not touching.size:
        return None
    return _around(t, touching[0], touching[-1], CONTACT_MARGIN)


@_forces_window
def impact_window(t, magnitude) -> tuple[float, float] | None:
    """The time range of the largest force's impact: the samples around its peak above
    ``IMPACT_LEVEL`` of it, from the sample before to the one after, widened by that span
    on either side; None without contact (or samples).

    Parameters
    ----------
    %(t)s
    %(magnitude)s
    """
    t, forces = _samples(t, magnitude)
    largest = forces.max(axis=1, initial=0.0)
    if not largest.max(initial=0.0) > 0:
        return None
    peak = int(largest.argmax())
    high = largest >= IMPACT_LEVEL * largest[peak]
    low = np.flatnonzero(~high)
    first = low[low < peak].max(initial=-1) + 1
    last = low[low > peak].min(initial=t.size) - 1
    return _around(t, first, last, 1.0)


def equal_limits(points, least: float = 0.0) -> np.ndarray:
    """Axis limits of equal length around ``points``, for a 3-D axes of equal scales.

    Parameters
    ----------
    points : array_like, shape (k, 3)
        What must be inside [any length unit].
    least : float, optional
        The smallest half-width [same unit].

    Returns
    -------
    ndarray, shape (3, 2)
        ``(low, high)`` per axis.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2
    half = max(0.55 * float((high - low).max()), least, np.finfo(float).tiny)
    return np.stack([centre - half, centre + half], axis=1)
