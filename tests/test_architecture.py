"""The package's shape: imports only go down, no cycles, private means private, C in C.

Parses every module of ``src/softcurve`` (ast, nothing imported) and checks each import,
at module level or inside a function, against the layer order of docs/architecture.md,
and every attribute read and string literal against the rules there.
"""

from __future__ import annotations

import ast
import warnings
from pathlib import Path

import pytest

from .conftest import FIXED_STRIDE_PROPERTY, LONG_MODULE_PROPERTY

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "softcurve"

LAYERS = (
    ("softcurve._version", "softcurve.base"),
    ("softcurve.description",),
    ("softcurve.symbolic",),
    ("softcurve.compiled",),
    ("softcurve.figures",),
    ("softcurve.analysis",),
    ("softcurve.simulation",),
    ("softcurve.control",),
    ("softcurve.identification",),
    ("softcurve.scenarios",),
    ("softcurve.envs",),
    ("softcurve.cli", "softcurve.__main__"),
)
"""Bottom to top; a module may import its own layer and the layers below it."""

LONG_MODULE = 1000
"""Lines of code above which a module is reported (in the run's summary, not a failure):
a long module that is one concept is better than slices of it, but worth a second look."""

C_LINE_ENDINGS = (";", "{", "}")
"""A multi-line string whose lines mostly end in these is C (see :func:`_looks_like_c`)."""


def _module_name(path: Path) -> str:
    parts = ("softcurve", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
TREES = {m: ast.parse(p.read_text(), str(p)) for m, p in MODULES.items()}


def _package(module: str) -> str:
    """The package a module sits in (a package's ``__init__`` is its own)."""
    return module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]


def _layer(module: str) -> int | None:
    for i, prefixes in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return i
    return None


def _resolve(name: str) -> str:
    """The softcurve module an imported dotted name lives in (a module or its attribute)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name


def _absolute(module: str, node: ast.ImportFrom) -> str:
    base = node.module or ""
    if node.level:
        package = _package(module).split(".")
        anchor = package[: len(package) - node.level + 1]
        base = ".".join([*anchor, base] if base else anchor)
    return base


def _imports(module: str, tree: ast.AST) -> set[str]:
    """softcurve modules imported anywhere in ``module`` (relative imports resolved); a
    ``from package import submodule`` counts as an import of the submodule alone."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(module, node)
            names = [f"{base}.{a.name}" for a in node.names]
            if not all(name in MODULES for name in names):
                names.append(base)
        else:
            continue
        for name in names:
            if name == "softcurve" or name.startswith("softcurve."):
                target = _resolve(name)
                if target != module:
                    found.add(target)
    return found


GRAPH = {m: _imports(m, TREES[m]) for m in MODULES}


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _private_module_owner(module: str) -> str | None:
    """The package behind whose ``__init__`` a private module sits (None if public)."""
    parts = module.split(".")
    for i, part in enumerate(parts):
        if _is_private(part):
            return ".".join(parts[:i])
    return None


def _may_import(importer: str, target: str) -> bool:
    """A private module is read by modules of its own package (and its subpackages)."""
    owner = _private_module_owner(target)
    package = _package(importer)
    return owner is None or package == owner or package.startswith(owner + ".")


def _defined_private_names(tree: ast.AST) -> set[str]:
    """Private names a module defines: functions, classes, assigned names and attributes
    (``self._x = ...``), keyword fields of its classes."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, (ast.Store, ast.Del)):
            names.add(node.attr)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            names.add(node.value)  # __slots__, ctypes _fields_, setattr targets
    return {n for n in names if _is_private(n)}


def _on_own_instance(node: ast.Attribute) -> bool:
    """``self._x``, ``cls._x`` or ``super()._x``: a class and its subclasses' protocol."""
    value = node.value
    if isinstance(value, ast.Name):
        return value.id in ("self", "cls")
    return isinstance(value, ast.Call) and getattr(value.func, "id", None) == "super"


def private_reads(module: str, tree: ast.AST) -> list[str]:
    """Where ``module`` reads another module's private names: imports of a private name or
    of a private module it is not behind, and reads of a private attribute it does not
    define itself (other than on ``self``, ``cls`` or ``super()``)."""
    own = _defined_private_names(tree)
    others = {  # other projects' modules: their documented names are theirs (os._exit)
        alias.asname or alias.name
        for node in ast.walk(tree) if isinstance(node, ast.Import)
        for alias in node.names if not alias.name.startswith("softcurve")
    }  # fmt: skip
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = _absolute(module, node)
            if not base.startswith("softcurve"):
                continue
            for alias in node.names:
                full = f"{base}.{alias.name}"
                if full in MODULES:
                    if not _may_import(module, full):
                        found.append(f"line {node.lineno}: imports private module {full}")
                elif _is_private(alias.name):
                    found.append(f"line {node.lineno}: imports {alias.name} from {base}")
                elif not _may_import(module, base):
                    found.append(f"line {node.lineno}: imports from private module {base}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("softcurve") and not _may_import(module, alias.name):
                    found.append(f"line {node.lineno}: imports private module {alias.name}")
        elif (
            isinstance(node, ast.Attribute) and _is_private(node.attr)
            and node.attr not in own and not _on_own_instance(node)
            and getattr(node.value, "id", None) not in others
        ):  # fmt: skip
            found.append(f"line {node.lineno}: reads .{node.attr}")
    return found


def _looks_like_c(text: str) -> bool:
    """More than three lines, most ending like statements or blocks of C."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if len(lines) <= 3:
        return False
    return sum(line.endswith(C_LINE_ENDINGS) for line in lines) > len(lines) / 2


def c_strings(tree: ast.AST) -> list[int]:
    """Lines where a string literal holds C."""
    return [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str)
        and _looks_like_c(node.value)
    ]  # fmt: skip


CURVATURE_KIND = "softcurve.description.curvature"
"""The constant-curvature kind's module: its three coordinates ``(l, kx, ky)`` are its own;
everywhere else a coordinate is found through the robot's offsets and its kinds."""


def _three(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and node.value == 3


def _times_three(node: ast.AST) -> ast.AST | None:
    """The other factor of a product ``3 * x`` or ``x * 3`` (``x`` not a constant)."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        for a, b in ((node.left, node.right), (node.right, node.left)):
            if _three(a) and not isinstance(b, ast.Constant):
                return b
    return None


def _names(node: ast.AST) -> set[str]:
    return {n.id if isinstance(n, ast.Name) else n.attr
            for n in ast.walk(node) if isinstance(n, ast.Name | ast.Attribute)}  # fmt: skip


def _stride_lines(tree: ast.AST) -> set[int]:
    """Lines that hard-wire three coordinates per element: an index or slice of three
    times a variable (``q[3 * i]``, ``q[3 * i : 3 * i + 3]``) or of step 3 (``q[1::3]``),
    a range of step 3 (``range(1, n, 3)``, ``np.arange(1, n, 3)``), three times a count of
    segments (``3 * n_segments``)."""
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript):
            for part in ast.walk(node.slice):
                if (isinstance(part, ast.Slice) and part.step is not None and _three(part.step)
                        or _times_three(part) is not None):  # fmt: skip
                    lines.add(part.lineno)
        elif isinstance(node, ast.Call):
            name = (
                node.func.id if isinstance(node.func, ast.Name) else getattr(node.func, "attr", "")
            )
            step = node.args[2] if len(node.args) == 3 else None
            step = next((k.value for k in node.keywords if k.arg == "step"), step)
            if name in ("range", "arange") and step is not None and _three(step):
                lines.add(node.lineno)
        else:
            other = _times_three(node)
            if other is not None and any("segment" in n for n in _names(other)):
                lines.add(node.lineno)
    return lines


def strides(tree: ast.AST) -> dict[str, list[int]]:
    """The places of :func:`_stride_lines`, by their enclosing function's qualified name
    (``"Robot.check_configuration"``; ``"<module>"`` at module level), each with its
    lines."""
    lines = _stride_lines(tree)
    found: dict[str, list[int]] = {}

    def visit(node: ast.AST, scope: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                inner = child.name if scope == "<module>" else f"{scope}.{child.name}"
                visit(child, inner)
                continue
            line = getattr(child, "lineno", None)
            if line in lines:
                found.setdefault(scope, [])
                if line not in found[scope]:
                    found[scope].append(line)
            visit(child, scope)

    visit(tree, "<module>")
    return found


def constant_curvature_only() -> dict[tuple[str, str], str]:
    """The places outside the constant-curvature kind allowed to stride by three, as
    ``(module, function) -> why``: genuinely constant-curvature-only, or not yet written
    per kind. A place fixed is reported (:func:`test_the_list_of_strides_shrinks`), so that
    its entry is removed; a new place fails :func:`test_no_new_hard_wired_stride`."""
    robot = "softcurve.description.robot"
    without_elements = (
        "an actuator built without elements=robot drives constant-curvature segments, whose "
        "coordinates lie at 3 i (check_robot refuses it on a robot of other kinds)"
    )
    until_maps = "constant curvature only until the identification's maps are written per kind"
    return {
        (robot, "in_domain"): "the public rule of constant-curvature robots (every kind: "
        "Robot.inside)",
        (robot, "domain_problem"): "the public message of constant-curvature robots (every "
        "kind: Robot.domain_problem)",
        (robot, "Robot.check_configuration"): "the fast path of plain floats, behind "
        "robot.constant_curvature",
        ("softcurve.analysis.statics", "_curvature_pairs"): "rotate_about_axis without a "
        "robot, whose default is a robot of constant-curvature segments",
        ("softcurve.description.actuator", "Actuator._init_parts"): without_elements,
        ("softcurve.description.fibers", "_place"): without_elements,
        ("softcurve.scenarios.actuation", "from_mapping"): without_elements,
        ("softcurve.identification.maps._outputs", "_curvature_start"): "a map built "
        "without model= reads constant-curvature coordinates; the fits refuse it on other "
        "robots (OutputMap.robot_problem)",
        ("softcurve.identification.maps._inputs", "_count"): until_maps,
        ("softcurve.control.references", "tip_circle"): "a reference in (l, kx, ky), "
        "flagged constant_curvature: a controller refuses it on a robot of other elements",
    }


def _stride_places() -> dict[tuple[str, str], list[int]]:
    return {
        (module, scope): lines
        for module in sorted(MODULES)
        if module != CURVATURE_KIND
        for scope, lines in strides(TREES[module]).items()
    }


def test_no_new_hard_wired_stride():
    """Three coordinates per element is the constant-curvature kind's own layout; other
    code finds an element's coordinates through ``robot.offsets`` and ``robot.sizes``, or
    asks its kind (``description/elements.py`` and the kinds' modules)."""
    allowed = constant_curvature_only()
    new = [f"{module}, {scope} (lines {lines})"
           for (module, scope), lines in _stride_places().items()
           if (module, scope) not in allowed]  # fmt: skip
    assert not new, (
        "a stride of three coordinates per element outside the constant-curvature kind: "
        "index through robot.offsets and robot.sizes, or ask the element's kind (or, if "
        "the place is constant-curvature only, list it with its reason in "
        "constant_curvature_only()):\n" + "\n".join(new)
    )


def test_the_list_of_strides_shrinks(record_property):
    """An allowed place that strides no more is named in the run's summary (its entry is to
    be removed); not a failure, since its owner fixes it on another branch."""
    places = _stride_places()
    for (module, scope), why in constant_curvature_only().items():
        assert module in MODULES, f"{module} is not a module"
        if (module, scope) not in places:
            record_property(FIXED_STRIDE_PROPERTY, f"{module}, {scope}: no stride any more "
                            f"(remove it from constant_curvature_only: {why})")  # fmt: skip


def test_the_stride_check_sees_the_forms_of_a_stride():
    text = (
        "def f(q, i, robot):\n"
        "    a = q[3 * i + 1]\n"
        "    b = q[1::3]\n"
        "    c = q[i * 3 : i * 3 + 3]\n"
        "    d = np.arange(0, robot.n, 3)\n"
        "    e = np.zeros(3 * robot.n_segments)\n"
        "    f = np.zeros(3 * n)  # a vector per point: not a stride\n"
        "    g = q[robot.offsets[i] : robot.offsets[i] + robot.sizes[i]]\n"
    )
    assert strides(ast.parse(text)) == {"f": [2, 3, 4, 5, 6]}


def test_every_module_belongs_to_a_layer():
    unplaced = [m for m in MODULES if m != "softcurve" and _layer(m) is None]
    assert not unplaced, f"modules in no layer (add them to LAYERS): {unplaced}"


def test_imports_only_go_down():
    upward = [
        f"{m} (layer {_layer(m)}) imports {t} (layer {_layer(t)})"
        for m, targets in GRAPH.items()
        if m != "softcurve"
        for t in sorted(targets)
        if t == "softcurve" or _layer(t) > _layer(m)
    ]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one node."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return cycles


def test_no_import_cycles():
    """No cycle among modules (a subpackage's ``__init__`` counts as a module)."""
    cycles = _cycles(GRAPH)
    assert not cycles, f"import cycles: {cycles}"


def _below_its_subpackages(module: str) -> bool:
    """Whether a package's own private module imports none of that package's
    subpackages (``simulation/_settings.py``): its subpackages may then use it."""
    owner = _private_module_owner(module)
    if owner is None:  # the parent's face imports its subpackages
        return False
    return not any(
        (_private_module_owner(t) or _package(t)).startswith(owner + ".") for t in GRAPH[module]
    )


def test_no_cycles_between_packages():
    """Subpackages import each other one way (a private module counts as its package):
    each ``__init__`` can then import its own modules eagerly. A subpackage may use a
    private module of its parent only where that module sits below the subpackages."""
    graph: dict[str, set[str]] = {}
    for m, targets in GRAPH.items():
        source = _private_module_owner(m) or _package(m)
        for t in targets:
            target = _private_module_owner(t) or _package(t)
            upward = source.startswith(target + ".")
            if target != source and not (upward and _below_its_subpackages(t)):
                graph.setdefault(source, set()).add(target)
    cycles = _cycles(graph)
    assert not cycles, f"package cycles: {cycles}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_module_reads_another_modules_private_names(module):
    found = private_reads(module, TREES[module])
    assert not found, f"{module} reads private names of other modules:\n" + "\n".join(found)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_c_in_python_strings(module):
    found = c_strings(TREES[module])
    assert not found, f"{module} holds C in strings at lines {found}: move it to a .c/.h file"


def test_the_package_check_sees_a_subpackage_using_its_parents_top(monkeypatch):
    """A subpackage importing its parent's module that imports the subpackages (the
    stepper once took ``initial_state`` from ``simulation/_simulate.py``) is a cycle."""
    stepper = "softcurve.simulation.stepper._stepper"
    monkeypatch.setitem(GRAPH, stepper, GRAPH[stepper] | {"softcurve.simulation._simulate"})
    with pytest.raises(AssertionError, match="package cycles"):
        test_no_cycles_between_packages()


def report_long_modules(record, limit: int = LONG_MODULE) -> None:
    """``record(LONG_MODULE_PROPERTY, "<module> has <n> lines (> limit)")`` for each module
    longer than ``limit`` lines."""
    for module, path in MODULES.items():
        lines = len(path.read_text().splitlines())
        if lines > limit:
            record(LONG_MODULE_PROPERTY, f"{module} has {lines} lines (> {limit})")


def test_long_modules_are_reported(record_property):
    """Long modules are worth a look, not an error: each is named in the summary of the run
    (tests/conftest.py), and the test passes."""
    report_long_modules(record_property)


def test_a_long_module_is_reported_without_failing():
    """With every warning an error (pyproject.toml's filterwarnings), a long module is
    still recorded and nothing raises (before, the check warned, which pytest turned into
    a failure)."""
    recorded = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        report_long_modules(lambda name, value: recorded.append((name, value)), limit=100)
    assert recorded and all(name == LONG_MODULE_PROPERTY for name, _ in recorded)
    assert any(value.startswith("softcurve.compiled._model has ") for _, value in recorded)


def test_the_checker_sees_an_upward_import():
    """The checks can fail: a description module importing the simulation is caught."""
    tree = ast.parse("from softcurve.simulation._simulate import simulate\n")
    imported = _imports("softcurve.description.robot", tree)
    assert imported == {"softcurve.simulation._simulate"}
    assert _layer("softcurve.description.robot") < _layer(imported.pop())


def test_the_checker_sees_private_reads():
    """A private module read from outside its package, a private name imported and a
    private attribute read are each caught; a module's own private attribute is not."""
    source = (
        "from softcurve.simulation.solvers._driver import integrate\n"
        "from softcurve.compiled import _build\n"
        "from softcurve.description.robot import _checked\n"
        "def f(model):\n"
        "    return model._native\n"
        "class A:\n"
        "    def __init__(self):\n"
        "        self._own = 1\n"
        "    def g(self, other):\n"
        "        return other._own\n"
    )
    found = private_reads("softcurve.control.mpc", ast.parse(source))
    assert len(found) == 4, found
    assert not private_reads(
        "softcurve.simulation.solvers._cvodes", ast.parse(source.splitlines()[0])
    )


def test_the_checker_sees_c_in_a_string():
    source = 'CODE = """\n#include <math.h>\nint f(int x) {\n    x += 1;\n    return x;\n}\n"""\n'
    assert c_strings(ast.parse(source)) == [1]
    assert not c_strings(
        ast.parse('TEXT = """A docstring.\n\nWith lines; a few.\nAnd more.\n"""\n')
    )
