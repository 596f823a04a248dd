"""The package's layers: imports only go down, no cycles, modules small enough to read.

Parses every module of ``src/softcurve`` (ast, nothing imported) and checks each import,
at module level or inside a function, against the layer order of docs/architecture.md.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

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

MAX_LINES = 400


def _module_name(path: Path) -> str:
    parts = ("softcurve", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


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


def _imports(module: str) -> set[str]:
    """softcurve modules imported anywhere in ``module`` (relative imports resolved)."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            names = [f"{base}.{a.name}" for a in node.names] + [base]
        else:
            continue
        for name in names:
            if name == "softcurve" or name.startswith("softcurve."):
                target = _resolve(name)
                if target != module:
                    found.add(target)
    return found


GRAPH = {m: _imports(m) for m in MODULES}


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


def test_no_import_cycles():
    """Tarjan's strongly connected components over module-to-module imports (a
    subpackage's ``__init__`` counts as a module)."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in GRAPH.get(v, ()):
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

    for v in GRAPH:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_modules_are_small_enough_to_read(module):
    lines = len(MODULES[module].read_text().splitlines())
    assert lines <= MAX_LINES, f"{module} has {lines} lines (> {MAX_LINES}): split it"


def test_the_checker_sees_an_upward_import(tmp_path):
    """The checks can fail: a description module importing the simulation is caught."""
    source = "from softcurve.simulation.simulate import simulate\n"
    tree = ast.parse(source)
    imported = {_resolve(f"{n.module}.{a.name}") for n in ast.walk(tree)
                if isinstance(n, ast.ImportFrom) for a in n.names}  # fmt: skip
    assert imported == {"softcurve.simulation.simulate"}
    assert _layer("softcurve.description.robot") < _layer(imported.pop())
