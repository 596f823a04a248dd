"""Scales of the trajectory figures: which part of the time axis shows the motion, which
signals are round-off rather than motion, and equal 3-D axes."""

from __future__ import annotations

import numpy as np

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
