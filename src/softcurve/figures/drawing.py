"""Where a figure is drawn (a new figure or the caller's Axes), how it is written, and
the backbone shapes that several figures draw."""

from __future__ import annotations

import operator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softcurve.base.files import atomic_path
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.description.elements import RigidBody

RIGID_KIND = RigidBody.kind
RIGID_STYLE = {"color": "0.35", "alpha": 0.85, "lw": 0.0}
"""A rigid body: a dark grey bar, where the soft segments are blue lines."""


def pyplot():
    """``matplotlib.pyplot``, imported on first use, never switching the backend.

    Imported here rather than at module level because it costs about 0.6 s, which
    ``import softcurve`` should not pay when no figure is drawn.
    """
    import matplotlib.pyplot as plt

    return plt


def panels(ax, count: int, what: str, *, rows: int | None = None, projection=None, **figure):
    """The figure and the ``count`` Axes that ``what`` is drawn into, row by row.

    Parameters
    ----------
    ax : None, matplotlib.axes.Axes or sequence of Axes, shape (count,)
        None for a new figure of ``rows`` rows; otherwise the caller's Axes (any nesting,
        read row by row), exactly ``count`` of them.
    count : int
        Number of panels of the plot.
    what : str
        The plot's name, for error messages.
    rows : int, optional
        Rows of a new figure (default: ``count``, one panel per row).
    projection : str, optional
        ``"3d"`` for 3-D panels (the caller's Axes must be 3-D too).
    **figure
        Passed to ``matplotlib.pyplot.subplots`` for a new figure (``figsize``, ``sharex``).

    Returns
    -------
    figure : matplotlib.figure.Figure
        The (root) figure the panels belong to.
    axes : list of matplotlib.axes.Axes, length count
    """
    plt = pyplot()
    if ax is None:
        rows = count if rows is None else rows
        new, grid = plt.subplots(
            rows,
            count // rows,
            squeeze=False,
            layout="constrained",
            subplot_kw=None if projection is None else {"projection": projection},
            **figure,
        )
        return new, list(grid.ravel())
    given = _flatten(ax, plt.Axes, what)
    if len(given) != count:
        one = "an Axes or " if count == 1 else ""
        raise ParameterError(
            f"{what} has {count} panel(s): ax must be None, {one}a sequence of {count} "
            f"Matplotlib Axes, got {len(given)}"
        )
    if projection is not None and any(a.name != projection for a in given):
        raise ParameterError(
            f"{what} needs Axes made with projection={projection!r}, got {[a.name for a in given]}"
        )
    root = given[0].figure
    while not isinstance(root, plt.Figure):  # a SubFigure: its parent holds it
        root = root.figure
    return root, given


def _flatten(ax, axes_type, what: str) -> list:
    if isinstance(ax, axes_type):
        return [ax]
    if isinstance(ax, str | bytes) or not hasattr(ax, "__iter__"):
        raise ParameterError(
            f"ax of {what} must be None, a Matplotlib Axes or a sequence of them, got {ax!r}"
        )
    return [a for item in ax for a in _flatten(item, axes_type, what)]


def whole_number(name: str, value, minimum: int) -> int:
    """``value`` as an int of at least ``minimum``, or raise :class:`ParameterError`.

    Parameters
    ----------
    name : str
        The option's name, for the message.
    value : int
        The number to check [count].
    minimum : int
        Its smallest allowed value [count].

    Returns
    -------
    int
    """
    try:
        number = operator.index(value)
    except TypeError:
        raise ParameterError(f"{name} must be an integer, got {value!r}") from None
    if number < minimum:
        raise ParameterError(f"{name} must be >= {minimum}, got {number}")
    return number


def figure_format(path, what: str | None = None) -> str:
    """The format Matplotlib writes ``path`` in, from its suffix (none: ``"png"``);
    :class:`~softcurve.ParameterError` listing the supported suffixes otherwise. Cheap:
    commands check their figure paths with it before any work.

    Parameters
    ----------
    path : str or pathlib.Path
        The figure's file.
    what : str, optional
        How the user gave it, for the message (e.g. ``"--plot x.xyz"``).

    Returns
    -------
    str
        E.g. ``"png"``, ``"pdf"``, ``"svg"``.
    """
    from matplotlib.backend_bases import FigureCanvasBase

    path = Path(path)
    file_format = path.suffix.lstrip(".").lower() or "png"
    supported = FigureCanvasBase.get_supported_filetypes()
    if file_format not in supported:
        what = what or f"cannot write a figure as {path.name!r}"
        raise ParameterError(
            f"{what}: the suffix must be one of {sorted('.' + s for s in supported)}"
        )
    return file_format


def save_figure(figure, path, *, dpi: float = 110) -> Path:
    """Write ``figure`` to ``path``, whole or not at all.

    The file appears complete or not at all (a temporary file beside it is renamed over
    it), so readers never see half a figure.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
        What a ``.plot()`` method returns.
    path : str or pathlib.Path
        The file; its suffix gives the format (``.png``, ``.pdf``, ``.svg``...; no
        suffix: PNG).
    dpi : float, optional
        Resolution of raster formats [dots per inch].

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import matplotlib.pyplot as plt
    >>> from softcurve.figures import save_figure
    >>> figure, ax = plt.subplots()
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     save_figure(figure, pathlib.Path(folder) / "empty.png").stat().st_size > 0
    True
    >>> plt.close(figure)
    """
    plt = pyplot()
    if not isinstance(figure, plt.Figure):
        raise ParameterError(
            f"figure must be a matplotlib.figure.Figure (what .plot() returns), "
            f"got {type(figure).__name__}"
        )
    dpi = real_scalar("dpi", dpi, positive=True)
    file_format = figure_format(path)
    with atomic_path(path) as tmp:
        figure.savefig(tmp, dpi=dpi, format=file_format)
    return path


def model_rows(model, q, what: str) -> np.ndarray:
    """``q`` as float64 rows, checked to have the coordinates of ``model`` (``robot.n``);
    :class:`~softcurve.ParameterError` naming both sizes otherwise.

    Parameters
    ----------
    model : softcurve.Model
        The model that draws ``q``.
    q : array_like, shape (k, n) or (n,)
        Configurations (``robot.coordinate_names()``).
    what : str
        What ``q`` belongs to, for the message (e.g. ``"the trajectory"``).

    Returns
    -------
    ndarray, shape (k, n)
    """
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    if q.shape[-1] != model.n:
        raise ParameterError(
            f"{what} has {q.shape[-1]} coordinates, the model {model.n} "
            f"({model.robot.n_segments} element(s)): pass the model it was computed with"
        )
    return q


def backbones(model, q, points: int) -> np.ndarray:
    """World positions along the robot, one backbone per configuration.

    Parameters
    ----------
    model : softcurve.Model
        Gives the pose at each material coordinate.
    q : array_like, shape (k, n)
        Configurations (``robot.coordinate_names()``).
    points : int
        Points along each backbone, evenly spaced in ``s`` from base to tip.

    Returns
    -------
    ndarray, shape (k, points, 3)
        Positions [m].
    """
    q = model_rows(model, q, "q")
    if q.shape[0] == 0:
        return np.empty((0, points, 3))
    s = np.linspace(0.0, 1.0, points)
    positions = model.evaluate_along(
        "pose", np.repeat(q, points, axis=0), np.tile(s, q.shape[0])[:, None]
    )[1]
    return positions.reshape(q.shape[0], points, 3)


@dataclass(frozen=True)
class ElementShape:
    """One element of the chain as the figures draw it, at ``k`` configurations.

    Parameters
    ----------
    index : int
        The element's index in ``robot.segments``.
    rigid : bool
        A :class:`~softcurve.RigidBody` (drawn as a thick bar of its own colour), else a
        soft segment.
    radius : float
        Its radius [m].
    backbone : ndarray, shape (k, P, 3)
        World positions along it, base to tip [m].
    stripe : ndarray, shape (k, P, 3)
        A line painted on its surface: the backbone moved by ``radius`` along the
        material x axis [m]. It winds round a twisted segment and stays on one side of
        one that only bends, so twist shows.
    """

    index: int
    rigid: bool
    radius: float
    backbone: np.ndarray
    stripe: np.ndarray


def element_poses(model, q, points: int) -> tuple[np.ndarray, np.ndarray]:
    """The material frames at ``points`` evenly spaced points of every element.

    Parameters
    ----------
    model : softcurve.Model
        Gives the pose at each material coordinate (element ``i`` covers
        ``robot.span_bounds[i : i + 2]``).
    q : array_like, shape (k, n)
        Configurations.
    points : int
        Points along each element, both ends included [count].

    Returns
    -------
    rotation : ndarray, shape (k, N, points, 3, 3)
        The material frames' axes (columns) in the world frame.
    position : ndarray, shape (k, N, points, 3)
        Their origins [m].
    """
    q = model_rows(model, q, "q")
    count = model.robot.n_segments
    local = np.linspace(0.0, 1.0, points)
    bounds = model.robot.span_bounds
    s = (bounds[:-1, None] + local[None, :] * np.diff(bounds)[:, None]).ravel()
    rotation, position = model.evaluate_along(
        "pose", np.repeat(q, s.size, axis=0), np.tile(s, q.shape[0])[:, None]
    )
    shape = (q.shape[0], count, points)
    return rotation.reshape(*shape, 3, 3), position.reshape(*shape, 3)


def element_shapes(model, q, points: int) -> tuple[ElementShape, ...]:
    """Each element's backbone and surface stripe at the configurations ``q``.

    Parameters
    ----------
    model : softcurve.Model
        Gives the pose at each material coordinate (element ``i`` covers
        ``robot.span_bounds[i : i + 2]``, :func:`element_poses`).
    q : array_like, shape (k, n)
        Configurations.
    points : int
        Points along each element, both ends included [count].

    Returns
    -------
    tuple of ElementShape
        One per element, base to tip.
    """
    rotation, position = element_poses(model, q, points)
    across = rotation[..., :, 0]  # the material x axis
    return tuple(
        ElementShape(
            index=i,
            rigid=element.kind == RIGID_KIND,
            radius=float(element.radius),
            backbone=position[:, i],
            stripe=position[:, i] + element.radius * across[:, i],
        )
        for i, element in enumerate(model.robot.segments)
    )


def chain_lines(model, q, points: int) -> tuple[np.ndarray, tuple[ElementShape, ...]]:
    """The soft elements' backbone as one line per configuration, broken where a rigid
    body lies, and the rigid bodies (each drawn as a bar, :func:`draw_rigid_body`).

    Parameters
    ----------
    model : softcurve.Model
        Gives the poses.
    q : array_like, shape (k, n)
        Configurations.
    points : int
        Points along the whole backbone of a chain without rigid bodies (evenly spaced
        in ``s``, as :func:`backbones`); along each element otherwise [count].

    Returns
    -------
    lines : ndarray, shape (k, P, 3)
        World positions [m]; NaN rows (where a line plot breaks) in place of each rigid
        body.
    rigid : tuple of ElementShape
        The rigid bodies, base to tip.
    """
    if not any(s.kind == RIGID_KIND for s in model.robot.segments):
        return backbones(model, q, points), ()
    parts = element_shapes(model, q, points)
    gap = np.full((parts[0].backbone.shape[0], 1, 3), np.nan)
    lines = np.concatenate([gap if p.rigid else p.backbone for p in parts], axis=1)
    return lines, tuple(p for p in parts if p.rigid)


def draw_rigid_body(ax, part: ElementShape, k: int, plane, scale: float, label=None) -> None:
    """Draw a rigid body at configuration ``k`` into ``ax`` as a dark grey bar of its
    diameter from its base to its tip.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    part : ElementShape
        The rigid body (``rigid`` true).
    k : int
        The configuration drawn.
    plane : tuple of int, shape (2,)
        The world axes drawn horizontally and vertically (``(0, 2)``: x-z).
    scale : float
        From metres to the axes' unit (1e3 for mm) [the axes' unit per m].
    label : str, optional
        Its legend entry.
    """
    ends = scale * part.backbone[k][[0, -1]][:, list(plane)]
    ax.fill(*bar_corners(ends, scale * part.radius).T, **RIGID_STYLE, label=label)


def bar_corners(ends, radius: float) -> np.ndarray:
    """The corners of a bar of half-width ``radius`` between two points of a view; a
    square of side ``2 radius`` round them where they coincide in it (a body seen end
    on).

    Parameters
    ----------
    ends : ndarray, shape (2, 2)
        The bar's ends in the view [the view's unit].
    radius : float
        Its half-width [the view's unit].

    Returns
    -------
    ndarray, shape (4, 2)
        The corners, in order round the bar.
    """
    along = ends[1] - ends[0]
    length = np.linalg.norm(along)
    along = along / length if length > 0 else np.array([1.0, 0.0])
    normal = radius * np.array([-along[1], along[0]])
    start, end = ends[0] - radius * along, ends[1] + radius * along
    return np.array([start + normal, end + normal, end - normal, start - normal])


def state_rows(robot) -> tuple[tuple[str, str, tuple], ...]:
    """The rows of a states figure: one per coordinate name, in the order the elements
    first name them (``l, kx, ky`` for constant curvature, then the strains).

    Parameters
    ----------
    robot : softcurve.Robot
        The robot.

    Returns
    -------
    tuple of (str, str, tuple of (int, int))
        Per row: the coordinate's name, its unit, and the ``(element, column of q)`` of
        every element that has it.
    """
    rows: dict[str, tuple[str, list]] = {}
    for i, element in enumerate(robot.segments):
        start = robot.offsets[i]
        for k, (name, unit) in enumerate(
            zip(element.coordinate_names, element.coordinate_units, strict=True)
        ):
            rows.setdefault(name, (unit, []))[1].append((i, start + k))
    return tuple((name, unit, tuple(columns)) for name, (unit, columns) in rows.items())
