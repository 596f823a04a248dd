"""Docs that cannot rot: every public parameter is documented, with its unit or shape.

Which objects are checked (the public API):

- every name in ``softcurve.__all__``: functions; classes with their constructor (the
  signature of the class, documented in the class docstring or in ``__init__``'s) and
  their public methods (names not starting with ``_``, static and class methods included,
  inherited ones where a softcurve class defines them; properties take no parameters
  and are skipped); modules (``presets``) with their public functions;
- the public functions of every public module of the package (no part of the dotted
  name starts with ``_``): the names not starting with ``_`` that the module defines
  itself (imports excluded) and, for a package, the functions of its private modules
  that it exports in ``__all__``.

What each one must satisfy, from its numpy-style docstring parsed by numpydoc:

1. every parameter of its signature appears in ``Parameters`` (or ``Other
   Parameters``), except ``self`` and ``cls``; ``*columns`` and ``**options`` are written
   with or without their stars; ``a, b : float`` documents both;
2. every documented parameter exists in the signature;
3. every documented parameter has a type line (``name : type``), except ``*columns``
   and ``**options``, which may leave it out;
4. a numeric parameter, one whose type line says float, complex, scalar, number,
   array_like or ndarray, says what its numbers are in one of three ways:

   - a shape in the type line: ``array_like, shape (n,)`` or ``ndarray (3, 3)``;
   - a unit in square brackets in the type line or description: ``[m]``, ``[N m/rad]``,
     ``[1/s]``, ``[s]``, or ``[-]`` for a dimensionless number (a bracket right after a
     name, ``q[0]``, is indexing and does not count);
   - a description that names its kind of number: dimensionless, unitless, count,
     number of, tolerance, ratio, fraction, probability or index.

   Integers are counts or indices by nature and need none of these.

A result class that is a dataclass (``Equilibrium``, ``Trajectory``, ``FitReport`` ...)
is built by the library, not by its users, and numpy convention documents its fields
under ``Attributes``; for a dataclass, rules 1 to 4 therefore accept a constructor
parameter documented in either ``Parameters`` or ``Attributes``, and an entry found in
``Attributes`` must satisfy rules 2 to 4 like one in ``Parameters``. A field computed at
construction (``field(init=False)``, e.g. ``Capsule.axis``) is no parameter: documented
under ``Attributes``, it must satisfy rules 3 and 4.

Run ``python -m pytest -q tests/test_docs.py``; a failure lists every offender as
``module.qualname: parameter 'x' ...``, so all can be fixed in one pass.
"""

from __future__ import annotations

import dataclasses
import enum
import importlib
import inspect
import pkgutil
import re
import warnings

from numpydoc.docscrape import NumpyDocString

import softcurve

NUMERIC_TYPE = re.compile(r"\b(float|complex|scalar|number|array_like|array-like|ndarray)s?\b")
SHAPE = re.compile(r"\bshape\b|\([^()]*,[^()]*\)")
UNIT = re.compile(r"(?<![\w\])`'\"])\[[^\[\]]+\]")
DIMENSIONLESS = re.compile(
    r"\b(dimensionless|unitless|counts?|number of|tolerances?|ratios?|fractions?|"
    r"probabilit(y|ies)|index|indices)\b",
    re.IGNORECASE,
)


# -- the checker -------------------------------------------------------------------------
PARAMETER_SECTIONS = ("Parameters", "Other Parameters")
DATACLASS_SECTIONS = (*PARAMETER_SECTIONS, "Attributes")


def _documented(
    *docstrings: str | None, sections: tuple[str, ...] = PARAMETER_SECTIONS
) -> dict[str, tuple[str, str]]:
    """``{name without stars: (type line, description)}`` over the docstrings' ``sections``."""
    documented = {}
    for docstring in docstrings:
        if not docstring:
            continue
        with warnings.catch_warnings():  # unknown sections are no concern of this test
            warnings.simplefilter("ignore")
            parsed = NumpyDocString(inspect.cleandoc(docstring))
        for section in sections:
            for parameter in parsed[section]:
                for name in parameter.name.split(","):
                    documented[name.strip().lstrip("*")] = (
                        parameter.type,
                        " ".join(parameter.desc),
                    )
    return documented


def _signature_names(signature: inspect.Signature) -> list[str]:
    names = list(signature.parameters)
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return names


def _unit_problem(type_line: str, description: str) -> str | None:
    """Why a documented parameter breaks rules 3 and 4, or None."""
    if not type_line.strip():
        return "has no type line ('name : type')"
    if not NUMERIC_TYPE.search(type_line):
        return None
    if SHAPE.search(type_line) or UNIT.search(type_line) or UNIT.search(description):
        return None
    if DIMENSIONLESS.search(description):
        return None
    return (
        f"is numeric ({type_line.strip()}) but gives no unit in [brackets], no shape "
        "and does not say it is dimensionless (a count, tolerance, ratio, index ...)"
    )


def parameter_offenses(
    label: str,
    signature: inspect.Signature,
    *docstrings,
    sections: tuple[str, ...] = PARAMETER_SECTIONS,
    derived: tuple[str, ...] = (),
) -> list[str]:
    """Every broken rule of one callable, as ``label: parameter 'x' ...`` lines, reading
    the parameters from the docstrings' ``sections``; ``derived`` names documented
    attributes that are no parameter (a dataclass's fields computed at construction)."""
    names = _signature_names(signature)
    documented = _documented(*docstrings, sections=sections)
    stars = {inspect.Parameter.VAR_POSITIONAL: "*", inspect.Parameter.VAR_KEYWORD: "**"}
    found = []
    for name in names:
        if name not in documented:
            star = stars.get(signature.parameters[name].kind, "")
            found.append(f"{label}: parameter '{star}{name}' is not documented")
    for name, (type_line, description) in documented.items():
        if name in derived:
            problem = _unit_problem(type_line, description)
            if problem:
                found.append(f"{label}: attribute '{name}' {problem}")
            continue
        if name not in names:
            found.append(f"{label}: parameter '{name}' is documented but not in the signature")
            continue
        variadic = signature.parameters[name].kind in stars
        problem = None if variadic and not type_line else _unit_problem(type_line, description)
        if problem:
            found.append(f"{label}: parameter '{name}' {problem}")
    return found


def _label(obj) -> str:
    return f"{obj.__module__}.{obj.__qualname__}"


def function_offenses(function, docstring=None) -> list[str]:
    """The broken rules of a function or method (``self``/``cls`` skipped); ``docstring``
    defaults to the function's own."""
    docstring = function.__doc__ if docstring is None else docstring
    return parameter_offenses(_label(function), inspect.signature(function), docstring)


def _own_classes(cls) -> list[type]:
    """``cls`` and its bases that softcurve defines (not object, Enum, Exception ...)."""
    return [k for k in cls.__mro__ if k is cls or k.__module__.split(".")[0] == "softcurve"]


def _public_methods(cls):
    seen = set()
    for klass in _own_classes(cls):
        for name, attribute in vars(klass).items():
            if name.startswith("_") or name in seen:
                continue
            seen.add(name)
            if isinstance(attribute, staticmethod | classmethod):
                attribute = attribute.__func__
            if inspect.isfunction(attribute) or hasattr(attribute, "__wrapped__"):
                yield name, attribute


def class_offenses(cls) -> list[str]:
    """The broken rules of a class's constructor and public methods; a dataclass may
    document its fields under ``Attributes`` instead of ``Parameters``."""
    found = []
    defines_init = any("__init__" in vars(k) for k in _own_classes(cls))
    if defines_init and not issubclass(cls, enum.Enum):
        init = cls.__init__
        own_init_doc = init.__doc__ if "__init__" in vars(cls) and init.__doc__ else None
        is_dataclass = dataclasses.is_dataclass(cls)
        sections = DATACLASS_SECTIONS if is_dataclass else PARAMETER_SECTIONS
        derived = (
            tuple(f.name for f in dataclasses.fields(cls) if not f.init) if is_dataclass else ()
        )
        found += parameter_offenses(
            _label(cls),
            inspect.signature(cls),
            cls.__doc__,
            own_init_doc,
            sections=sections,
            derived=derived,
        )
    for name, method in _public_methods(cls):
        # an implementation of a documented interface method inherits its docstring, as
        # in help(): inspect.getdoc looks it up along the method resolution order
        found += function_offenses(method, inspect.getdoc(getattr(cls, name)))
    return found


# -- the public API ----------------------------------------------------------------------
def public_modules() -> list:
    """Every module of the package with no part of its name starting with ``_``."""
    modules = []
    for info in pkgutil.walk_packages(softcurve.__path__, "softcurve."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            modules.append(importlib.import_module(info.name))
    return modules


def _module_functions(module) -> list:
    """The public functions a module defines, and for a package the functions of its
    private implementation modules that it exports in ``__all__`` (it is their face)."""
    exported = [getattr(module, name) for name in getattr(module, "__all__", ())]
    faced = [
        obj
        for obj in exported
        if inspect.isfunction(obj) and obj.__module__.startswith(f"{module.__name__}._")
    ]
    return faced + [
        obj
        for name, obj in vars(module).items()
        if not name.startswith("_")
        and inspect.isfunction(obj)
        and obj.__module__ == module.__name__
    ]


def public_api() -> list:
    """The classes and functions checked, each once, in a stable order."""
    objects = []
    for name in softcurve.__all__:
        obj = getattr(softcurve, name)
        if inspect.ismodule(obj):
            objects += _module_functions(obj)
        elif callable(obj):  # constants (softcurve.STRAINS) have no parameters
            objects.append(obj)
    for module in public_modules():
        objects += _module_functions(module)
    unique = {id(obj): obj for obj in objects}
    return sorted(unique.values(), key=_label)


def api_offenses() -> list[str]:
    found = []
    for obj in public_api():
        found += class_offenses(obj) if inspect.isclass(obj) else function_offenses(obj)
    return sorted(set(found))


# -- the tests ---------------------------------------------------------------------------
def test_public_api_documents_every_parameter_with_unit_or_shape():
    offenses = api_offenses()
    assert not offenses, (
        f"{len(offenses)} documentation problems (rules in tests/test_docs.py's docstring):\n"
        + "\n".join(offenses)
    )


def test_the_walk_reaches_the_entry_points():
    labels = {_label(obj) for obj in public_api()}
    for expected in (
        "softcurve.compiled._model.Model",
        "softcurve.description.presets.ifac2020",
        "softcurve.simulation._simulate.simulate",
        "softcurve.simulation.solvers._policy.cvodes_options",  # through its face's __all__
        "softcurve.description.robot.Robot",
    ):
        assert expected in labels
    methods = {_label(m) for _, m in _public_methods(softcurve.Model)}
    assert "softcurve.compiled._model.Model.forward_dynamics" in methods


def _badly_documented(q, speed, length, count: int, *columns, **options):
    """A deliberately bad example.

    Parameters
    ----------
    q : array_like
        Coordinates.
    speed : float
        How fast it goes.
    length
        No type line.
    ghost : float
        Not a parameter [m].
    """


def _well_documented(q, speed, tolerance, count: int, *columns, **options):
    """A good example.

    Parameters
    ----------
    q : array_like, shape (n,)
        Coordinates.
    speed : float
        How fast it goes [m/s].
    tolerance : float
        Relative tolerance of the solve.
    count : int
        How many.
    *columns : ndarray (T, k)
        Inputs.
    **options
        Passed on.
    """


class _BadlyDocumentedClass:
    """Constructor parameters belong here.

    Parameters
    ----------
    mass : float
        The mass.
    """

    def __init__(self, mass, radius):
        pass

    def scaled(self, factor):
        """No parameter section."""


def test_the_checker_catches_a_badly_documented_function():
    label = f"{__name__}._badly_documented"
    offenses = function_offenses(_badly_documented)
    assert sorted(offenses) == sorted(
        [
            f"{label}: parameter 'count' is not documented",
            f"{label}: parameter '*columns' is not documented",
            f"{label}: parameter '**options' is not documented",
            f"{label}: parameter 'ghost' is documented but not in the signature",
            f"{label}: parameter 'length' has no type line ('name : type')",
            f"{label}: parameter 'q' is numeric (array_like) but gives no unit in [brackets], "
            "no shape and does not say it is dimensionless (a count, tolerance, ratio, index ...)",
            f"{label}: parameter 'speed' is numeric (float) but gives no unit in [brackets], "
            "no shape and does not say it is dimensionless (a count, tolerance, ratio, index ...)",
        ]
    )
    assert function_offenses(_well_documented) == []


@dataclasses.dataclass(frozen=True)
class _ResultDataclass:
    """A result built by the library: fields under Attributes.

    Attributes
    ----------
    q : ndarray, shape (n,)
        Coordinates [m, 1/m, 1/m].
    speed : float
        How fast it went.
    ghost : float
        Not a field [m].
    """

    q: object
    speed: float
    count: int


class _PlainClassWithAttributes:
    """Not a dataclass: Attributes do not document the constructor.

    Attributes
    ----------
    mass : float
        The mass [kg].
    """

    def __init__(self, mass):
        pass


def test_a_dataclass_may_document_its_fields_under_attributes():
    cls = f"{__name__}._ResultDataclass"
    offenses = class_offenses(_ResultDataclass)
    assert sorted(offenses) == sorted(
        [
            f"{cls}: parameter 'count' is not documented",
            f"{cls}: parameter 'ghost' is documented but not in the signature",
            f"{cls}: parameter 'speed' is numeric (float) but gives no unit in [brackets], "
            "no shape and does not say it is dimensionless (a count, tolerance, ratio, index ...)",
        ]
    )
    plain = f"{__name__}._PlainClassWithAttributes"
    assert class_offenses(_PlainClassWithAttributes) == [
        f"{plain}: parameter 'mass' is not documented"
    ]


def test_the_checker_catches_a_badly_documented_class():
    cls = f"{__name__}._BadlyDocumentedClass"
    offenses = class_offenses(_BadlyDocumentedClass)
    assert f"{cls}: parameter 'radius' is not documented" in offenses
    assert any(o.startswith(f"{cls}: parameter 'mass' is numeric") for o in offenses)
    assert f"{cls}.scaled: parameter 'factor' is not documented" in offenses
    assert len(offenses) == 3


def test_indexing_is_not_a_unit():
    assert _unit_problem("float", "The entry q[0] of the state.") is not None
    assert _unit_problem("float", "Length [m] of the segment.") is None
    assert _unit_problem("float", "Material coordinate in [0, 1].") is None
