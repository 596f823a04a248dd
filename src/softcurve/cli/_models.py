"""The model of a command.

Compiling a robot's model to C takes seconds for one segment and minutes for several (or
with obstacles); the library is then cached, and later runs load it in milliseconds. The
library says so itself (``softcurve.compiled``'s log: what it compiles, where it is
cached, how long it took), and the command shows it as ``softcurve COMMAND: ...`` lines
on stderr (``softcurve.cli``, ``_library_lines``); a model whose library is already
cached, one that is not compiled (``compile=False``: nothing is built before its first
use, nothing cached) and ``--quiet`` print nothing.
"""

from __future__ import annotations


def build_model(
    robot,
    *,
    environment=None,
    quadrature_nodes: int | None = None,
    compile: bool = True,
):
    """``Model(robot, ...)`` with the model's defaults for what is not given.

    Parameters
    ----------
    robot : Robot
        The robot.
    environment : Environment, optional
        Its obstacles and contact law (default: the free robot).
    quadrature_nodes : int, optional
        Gauss-Legendre nodes per segment (default: the model's).
    compile : bool
        Compile to C (default).

    Returns
    -------
    Model
        The model.
    """
    from softcurve.compiled import Model

    options = {"environment": environment}
    if quadrature_nodes is not None:
        options["quadrature_nodes"] = quadrature_nodes
    return Model(robot, compile=compile, **options)
