"""Weights of the residuals: per signal, per sample, or per time window.

A fit minimizes ``sum_e sum_t sum_j (w_e[t, j] (y_e[t, j] - m_e[t, j]))^2`` over the
experiments ``e``, samples ``t`` and signals ``j``. :func:`weight_matrix` builds the
``(T, k)`` matrix ``w`` of one experiment from any of these forms:

- ``None``: all ones;
- array, shape ``(k,)``: one weight per signal (e.g. the inverse of its noise level);
- array, shape ``(T,)`` (when ``T != k``) or ``(T, k)``: per sample (and signal);
- callable ``w(t)`` of the sample times [s] returning shape ``(T,)`` or ``(T, k)``;
- list of windows, each a tuple ``(t0, t1, weight)``: samples with ``t0 <= t <= t1`` get
  ``weight`` (later windows win where they overlap), the others 1; e.g.
  ``[(0.0, 5.0, 0.0)]`` ignores a settling period of 5 s. Windows are tuples, so that a
  ``(T, 3)`` nested list of per-sample weights is never read as windows.

Weights are >= 0 and not all zero. In a fit of several experiments, ``weights`` applies
to each; a dict ``{experiment name: weights}`` gives each its own.
"""

from __future__ import annotations

import numpy as np

from softcurve.base.validation import ParameterError

WEIGHTS_DOC = (
    "None, array_like (k,), (T,) or (T, k), callable, list of (t0, t1, w), or dict",
    "Residual weights [1/signal unit]: per signal, per sample, a callable ``w(t)`` of "
    "the sample times [s], or windows ``(t0, t1, weight)`` (other samples 1); a dict "
    "``{experiment name: weights}`` per experiment (docs/identify.md).",
)
"""The documentation of the fits' ``weights`` argument."""


def _windows(spec, t) -> np.ndarray:
    w = np.ones(t.size)
    for window in spec:
        try:
            t0, t1, value = (float(v) for v in window)
        except (TypeError, ValueError):
            raise ParameterError(
                f"weights: a window is (t0 [s], t1 [s], weight), got {window!r}"
            ) from None
        if not t0 <= t1:
            raise ParameterError(f"weights: window {window!r} has t0 > t1")
        w[(t >= t0) & (t <= t1)] = value
    return w


def weight_matrix(spec, t: np.ndarray, k: int, name: str = "") -> np.ndarray:
    """The ``(T, k)`` weights of one experiment.

    Parameters
    ----------
    spec : see the module
        The weights as given to the fit (for this experiment).
    t : ndarray, shape (T,)
        Sample times [s].
    k : int
        Number of signals.
    name : str
        The experiment, for messages.
    """
    where = f"weights of experiment {name!r}" if name else "weights"
    if spec is None:
        return np.ones((t.size, k))
    if callable(spec):
        w = np.asarray(spec(t), dtype=np.float64)
    elif isinstance(spec, list | tuple) and spec and all(isinstance(r, tuple) for r in spec):
        w = _windows(spec, t)
    else:
        w = np.asarray(spec, dtype=np.float64)
    if w.ndim == 1 and w.shape == (k,):
        w = np.tile(w, (t.size, 1))
        if not np.all(w > 0):
            raise ParameterError(f"{where}: one weight per signal must be > 0, got {spec!r}")
    elif w.ndim == 1 and w.shape == (t.size,):
        w = np.repeat(w[:, None], k, axis=1)
    if w.shape != (t.size, k):
        raise ParameterError(
            f"{where}: expected shape ({k},) per signal, ({t.size},) per sample or "
            f"({t.size}, {k}), got {w.shape}"
        )
    if not (np.all(np.isfinite(w)) and np.all(w >= 0) and np.any(w > 0)):
        raise ParameterError(f"{where}: must be finite, >= 0 and not all zero")
    return w
