"""The model of a command, built where the user sees that it is built.

Compiling a robot's model to C takes seconds for one segment and minutes for several (or
with obstacles); the library is then cached, and later runs load it in milliseconds.
Before a command compiles one it says so on stderr, with where it is cached, and after it
how long it took, with the seconds so far redrawn below the first line while it builds
when a progress bar is shown; a model whose library is already cached, one that is not
compiled (``compile=False``: nothing is built before its first use, nothing cached) and
``--quiet`` print nothing.
"""

from __future__ import annotations

import sys
import time

from softcurve.base.progress import elapsed_line


def build_model(
    command: str,
    robot,
    *,
    environment=None,
    quadrature_nodes: int | None = None,
    compile: bool = True,
    quiet: bool = False,
    progress: bool = False,
):
    """``Model(robot, ...)``, with a line on stderr before and after compiling it.

    Parameters
    ----------
    command : str
        The subcommand, e.g. ``"simulate"``: the lines begin ``softcurve simulate:``.
    robot : Robot
        The robot.
    environment : Environment, optional
        Its obstacles and contact law (default: the free robot).
    quadrature_nodes : int, optional
        Gauss-Legendre nodes per segment (default: the model's).
    compile : bool
        Compile to C (default); with False nothing is compiled and nothing printed.
    quiet : bool
        Print nothing (``--quiet``).
    progress : bool
        Redraw the seconds so far while it compiles (``--progress``; default no).

    Returns
    -------
    Model
        The model.
    """
    from softcurve.compiled import Model

    options = {"environment": environment}
    if quadrature_nodes is not None:
        options["quadrature_nodes"] = quadrature_nodes
    if not compile or quiet or Model.is_cached(robot, **options):
        return Model(robot, compile=compile, **options)
    segments = f"{robot.n_segments} segment{'s' if robot.n_segments != 1 else ''}"
    obstacles = "" if environment is None else " and its obstacles"
    print(
        f"softcurve {command}: building the compiled model of {segments}{obstacles} (C, "
        f"cached in {Model.cache_folder()} for later runs) ...",
        file=sys.stderr,
        flush=True,
    )
    start = time.perf_counter()
    with elapsed_line(f"softcurve {command}: compiling", progress):
        model = Model(robot, **options)
    took = time.perf_counter() - start
    library = model.compiled_library
    if library is None:  # the CompilerWarning above says why
        done = "not compiled: it runs in CasADi's virtual machine"
    elif library.parent != Model.cache_folder():  # the CacheWarning above says why
        done = f"kept as {library} for this process only (see the warning)"
    else:
        done = f"cached as {library}"
    print(f"softcurve {command}: model built in {took:.1f} s, {done}", file=sys.stderr)
    return model
