"""What a task needs to know about its robot before the first episode, measured once with
the stepper itself (so it holds for any robot, actuator and control period):

- the reachable workspace: the tip after holding random admissible inputs for
  :data:`SETTLE_TIME` (every such point is reachable by construction), its centre and
  radius, which scale the observations and rewards;
- the scale of every state (mean and standard deviation over those runs), so that the
  observed state is of order one;
- the contact force those runs press on the obstacles (the force range of *Press*);
- a closed reachable path (*Track*): the tip under a command rotating through the
  actuators' azimuths (:func:`rotating_inputs`).

The results are cached per process by the setup's content, so environments built alike
(the members of a test, the single environments compared with a vector one) share them.
"""

from __future__ import annotations

import functools
import math
import pickle
import warnings
from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError

CALIBRATION_MEMBERS = 64
"""Random constant inputs held in the calibration, next to the corners (each input alone
at its upper bound). Measured on the paper's robot against 512 members: the workspace's
radius within 2.5 %, its centre within 5 % of the radius and every state scale within
-7 % to +9 % (32 members: centre 15 % off), at an eighth of the cost (1.3 s against 7.9 s
on a loaded 2-core machine)."""
SETTLE_TIME = 1.0
"""How long each calibration input is held [s]: for the paper's robot with one bellow at
full pressure the tip is then within 0.04 mm of where it is after 2 s (1 mm after 0.5 s;
measured with the stepper at a 20 ms period)."""
CALIBRATION_SEED = 2020
"""Seed of the calibration's inputs: fixed, so that the scales and the workspace are the
same in every process and independent of the episodes' seeds."""
TRACK_CYCLE = 2.0
"""Duration [s] of one turn of *Track*'s path: slow next to the paper robot's first
bending mode (about 3 Hz) and fast next to its creep."""
TRACK_AMPLITUDE = 0.8
"""Amplitude of the rotating command as a fraction of half the input range: 0.8 keeps
the command within the bounds with a margin for the policy to correct."""
TRACK_WARMUP = 2
"""Turns simulated before the path is recorded (the start transient has decayed)."""

_CACHE: dict[bytes, object] = {}


def _key(setup, what: str) -> bytes:
    stepper = setup.stepper
    model = stepper.model
    content = (model.robot, model.environment, stepper.actuator, stepper.period,
               stepper.substeps, stepper.method, setup.x0.tobytes(), what)  # fmt: skip
    return pickle.dumps(content)


def _cached(what: str):
    """Decorator: the result of ``measure(setup)`` kept per process under ``what`` and
    the setup's content (:func:`_key`), measured once."""

    def decorate(measure):
        @functools.wraps(measure)
        def cached(setup):
            key = _key(setup, what)
            if key not in _CACHE:
                _CACHE[key] = measure(setup)
            return _CACHE[key]

        return cached

    return decorate


@dataclass(frozen=True)
class Calibration:
    """The workspace and scales of a robot (see the module docstring).

    Attributes
    ----------
    tips : ndarray, shape (K, 3)
        Reachable tip positions [m], world frame.
    forces : ndarray, shape (K, 3)
        Contact force on the robot [N] at each of those tips (zero without obstacles).
    center : ndarray, shape (3,)
        Centre of the workspace [m]: the mean of ``tips``.
    radius : float
        Largest distance of a tip from the centre [m].
    state_mean, state_scale : ndarray, shape (n_state,)
        Mean and standard deviation of each state over the runs (1 where it stays
        constant), in the state's unit.
    """

    tips: np.ndarray
    forces: np.ndarray
    center: np.ndarray
    radius: float
    state_mean: np.ndarray
    state_scale: np.ndarray


@_cached("calibration")
def calibrate(setup) -> Calibration:
    """Hold :data:`CALIBRATION_MEMBERS` random admissible inputs, and each input alone at
    its upper bound (the others at their lower), for :data:`SETTLE_TIME` from the start
    state, in one batch of the stepper (cached). The runs that fail are left out.

    Parameters
    ----------
    setup : Setup
        The robot, actuator and period.

    Warns
    -----
    UserWarning
        Where some runs fail (the robot leaves its domain or the stepper does not follow
        it under inputs within their bounds), with the count and the first reason; a
        ParameterError where all fail.
    """
    stepper = setup.stepper
    rng = np.random.default_rng(CALIBRATION_SEED)
    lower, upper = stepper.lower, stepper.upper
    random = lower + rng.random((CALIBRATION_MEMBERS, lower.size)) * (upper - lower)
    corners = np.where(np.eye(lower.size, dtype=bool), upper, lower)  # one input full
    inputs = np.vstack([random, corners])
    x = np.tile(setup.x0, (inputs.shape[0], 1))
    ok = np.ones(inputs.shape[0], dtype=bool)
    states, reason = [x], None
    for _ in range(max(1, math.ceil(SETTLE_TIME / stepper.period - 1e-9))):
        result = stepper.step(x, inputs)
        x = result.x
        failed = ~(result.ok & np.all(np.isfinite(x), axis=1))
        if reason is None and failed.any():
            reason = result.reasons[int(np.argmax(failed))] or "a state that is not finite"
        ok &= ~failed
        states.append(x)
    if not np.any(ok):
        raise ParameterError(
            f"{setup.source}: every calibration run failed ({reason}): the "
            "robot cannot be simulated with these inputs and period"
        )
    if not np.all(ok):
        warnings.warn(
            f"{setup.source}: {np.count_nonzero(~ok)} of {ok.size} calibration runs "
            f"(inputs within their bounds held for {SETTLE_TIME:g} s from the start) failed "
            f"(first: {reason}): episodes under such inputs end "
            "early, truncated. Damp the robot, narrow its inputs' bounds or give the "
            "stepper more substeps (docs/envs.md).",
            UserWarning,
            stacklevel=2,
        )
    states = np.concatenate([s[ok] for s in states])
    tips, forces = result.tip[ok], result.contact_force[ok]
    center = tips.mean(axis=0)
    radius = float(np.max(np.linalg.norm(tips - center, axis=1)))
    scale = states.std(axis=0)
    floor = 1e-9 * np.maximum(np.abs(states).max(axis=0), 1e-300)
    return Calibration(
        tips=tips,
        forces=forces,
        center=center,
        radius=radius if radius > 0 else 1.0,
        state_mean=states.mean(axis=0),
        state_scale=np.where(scale > floor, scale, 1.0),
    )


def rotating_inputs(stepper, phase):
    """The command of *Track*'s path at ``phase`` [rad]: each input swings about the
    middle of its range by :data:`TRACK_AMPLITUDE` of half the range, peaking when
    ``phase`` passes its actuator's azimuth (inputs without an azimuth: equally spaced).

    Parameters
    ----------
    stepper : Stepper
        Gives the actuator and the bounds.
    phase : ndarray, shape (T,)
        Phases [rad].
    """
    parts = getattr(stepper.actuator, getattr(stepper.actuator, "_parts_field", ""), None)
    m = stepper.lower.size
    if parts is not None and all(hasattr(p, "azimuth") for p in parts):
        azimuths = np.array([p.azimuth for p in parts])
    else:
        azimuths = 2 * np.pi * np.arange(m) / m
    middle, half = (stepper.lower + stepper.upper) / 2, (stepper.upper - stepper.lower) / 2
    swing = np.cos(np.asarray(phase)[:, None] - azimuths[None, :])
    return middle + TRACK_AMPLITUDE * half * swing


@_cached("track")
def track_path(setup) -> np.ndarray:
    """The tip [m] over one turn of the rotating command (:func:`rotating_inputs`), one
    point per control period after :data:`TRACK_WARMUP` turns, shape (P, 3) (cached).

    Parameters
    ----------
    setup : Setup
        The robot, actuator and period.
    """
    stepper = setup.stepper
    per_turn = max(8, round(TRACK_CYCLE / stepper.period))
    steps = (TRACK_WARMUP + 1) * per_turn
    phases = 2 * np.pi * np.arange(1, steps + 1) / per_turn
    commands = rotating_inputs(stepper, phases)
    x, tips = setup.x0[None, :].copy(), []
    for k in range(steps):
        result = stepper.step(x, commands[k : k + 1])
        if not result.ok[0]:
            reason = result.reasons[0]
            raise ParameterError(f"{setup.source}: the path of Track failed: {reason}")
        x = result.x
        tips.append(result.tip[0])
    return np.array(tips[-per_turn:])
