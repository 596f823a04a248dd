"""One result protocol for the package: a :class:`Status`, a message and ``success``.

Every result that softcurve returns (trajectories, batches, equilibria, linearizations,
fit reports, sweep summaries, closed-loop runs) is an immutable object with

- ``status``: a :class:`Status`, whose text says what happened and what to try;
- ``message``: the specific account of this run (where it stopped, which member
  failed, the solver's words);
- ``success``: ``status is Status.SUCCESS``.

:class:`Status` is a ``str`` enumeration: ``status == "success"`` holds, and the value
is what files (trajectory CSV, sweep tables) store.
"""

from __future__ import annotations

import enum


class Status(str, enum.Enum):
    """How a computation ended; ``str(status)`` reads as advice for the user.

    Attributes
    ----------
    SUCCESS
        Finished as asked.
    INTEGRATION_FAILED
        The integrator stopped before the end time.
    LEFT_DOMAIN
        The state left the model's domain (a segment length reached zero, a bend beyond
        a full turn, a value became non-finite) or its actuator's (a tendon length or a
        chamber volume reached zero).
    NOT_CONVERGED
        An iterative solver did not reach its tolerance.
    EVALUATION_LIMIT
        The evaluation budget ran out before convergence.
    INFEASIBLE
        No admissible point satisfies the request within the bounds.
    NOT_IDENTIFIABLE
        The data do not determine every free parameter.
    PARTIAL
        Some members of a batch, points of a map or chunks of a sweep failed.
    INTERRUPTED
        The run was stopped from outside before it finished.
    """

    advice: str

    def __new__(cls, value: str, advice: str):
        member = str.__new__(cls, value)
        member._value_ = value
        member.advice = advice
        return member

    SUCCESS = ("success", "finished as asked")
    INTEGRATION_FAILED = (
        "integration_failed",
        "the integrator stopped before the end time; try the stiff method (bdf), looser "
        "tolerances or a larger step budget, and check that the initial state and inputs "
        "are physical",
    )
    LEFT_DOMAIN = (
        "left_domain",
        "the state left the model's domain (each element's: a length or stretch of at most "
        "10 rest lengths and > 0, a bend or twist of at most one turn, a shear of at most 45 "
        "degrees, finite values) or its actuator's (tendon lengths and chamber volumes > 0; "
        "docs/model.md); check the initial state, the inputs and the stiffness, which may "
        "be too soft for the loads",
    )
    NOT_CONVERGED = (
        "not_converged",
        "the solver did not converge; try another initial guess or a looser tolerance",
    )
    EVALUATION_LIMIT = (
        "evaluation_limit",
        "the evaluation budget ran out before convergence; raise it, or start closer to "
        "the solution",
    )
    INFEASIBLE = (
        "infeasible",
        "no admissible point satisfies the request within the bounds; widen the bounds or "
        "move the target",
    )
    NOT_IDENTIFIABLE = (
        "not_identifiable",
        "the data do not determine every free parameter; fix some of them or add "
        "experiments that excite them",
    )
    PARTIAL = (
        "partial",
        "some parts failed; the message and each part's own status say which and why",
    )
    INTERRUPTED = (
        "interrupted",
        "the run was stopped before it finished; run it again to resume where it stopped",
    )

    def __str__(self) -> str:
        return f"{self.value}: {self.advice}"

    @classmethod
    def parse(cls, value) -> Status:
        """The member whose value is ``value`` (a member passes through).

        Parameters
        ----------
        value : str or Status
            A member's value, e.g. ``"success"`` as stored in files.

        Examples
        --------
        >>> Status.parse("left_domain") is Status.LEFT_DOMAIN
        True
        >>> str(Status.SUCCESS)
        'success: finished as asked'
        """
        return value if isinstance(value, cls) else cls(str(value))


class Result:
    """Mixin of every result type: ``success`` from ``status``.

    Subclasses are frozen dataclasses with the fields ``status`` (:class:`Status`) and
    ``message`` (str).
    """

    __slots__ = ()

    status: Status
    message: str

    @property
    def success(self) -> bool:
        """Whether :attr:`status` is :attr:`Status.SUCCESS`."""
        return self.status is Status.SUCCESS
