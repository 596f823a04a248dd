"""The Sphinx extension of softcurve's documentation site.

At build time (``builder-inited``) it writes the generated pages into three folders of
the source tree, which hold nothing else (they are listed in ``.gitignore``):

- ``api/``: one page per public module (the modules that ``tests/test_docs.py`` checks),
  rendered by autodoc and numpydoc from the docstrings, and an index by layer;
- ``cli/``: one page per subcommand, the text of ``softcurve COMMAND --help``;
- ``gallery/``: one page per example script or file of ``examples/``, with its
  description, the command that runs it, its figures from ``docs/figures/`` and its
  source.

A file is rewritten only when its text changes, and a generated file that no longer
belongs (a module removed) is deleted, so a build always shows the current package.

Each object is documented once, on the page of its face: the module it is defined in
when that module is public, else the nearest public package above its private module
that exports it in ``__all__`` (``softcurve.compiled._model.Model`` is documented as
``softcurve.compiled.Model``). A package's page documents the names it is the face of and
lists, with links, the names it re-exports from other faces.

During the build (``missing-reference``) it resolves cross-references through the
names users write: ``softcurve.Model`` and ``softcurve.compiled._model.Model`` are both
sent to ``softcurve.compiled.Model``.
References to other projects (NumPy, Matplotlib, CasADi ...) are shown as plain text,
because the build is offline; a reference to a softcurve object that does not exist is
left to Sphinx, which reports it and, in strict mode, fails the build.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import importlib
import inspect
import io
import os
import pkgutil
import re
from pathlib import Path

LAYERS = (
    ("base", "validation, the result protocol, files, shared docstring texts"),
    ("description", "robots, materials, actuators, presets"),
    ("symbolic", "kinematics and the equation of motion in CasADi"),
    ("compiled", "the compiled Model, its cache, C export"),
    ("figures", "every Matplotlib figure"),
    ("analysis", "static loads, equilibria, linearization, quasi-static maps"),
    ("simulation", "simulate, batches, trajectories and their files"),
    ("control", "controllers, input allocation, MPC"),
    ("identification", "experiments and fits"),
    ("scenarios", "TOML scenario files and sweeps"),
    ("cli", "the softcurve command"),
)
"""The subpackages in the order of docs/architecture.md: ``(name, what it holds)``."""

GALLERY_FIGURES = {
    "contact_finger.py": (
        "python examples/contact_finger.py all --output {out}",
        {
            "contact_finger_force.png": "finger_force.png",
            "contact_cylinder.png": "cylinder.png",
            "contact_floor_force.png": "floor_force.png",
            "contact_floor_tip.png": "floor_tip.png",
        },
    ),
    "contact_wall.toml": (
        "softcurve simulate examples/contact_wall.toml -o {out}",
        {"contact_wall_contact.png": "contact.png", "contact_wall_tip.png": "tip.png"},
    ),
    "flick.py": (
        "python examples/flick.py --output {out}",
        {"flick.png": "flick.png"},
    ),
    "hanging.toml": (
        "softcurve simulate examples/hanging.toml -o {out}",
        {"hanging_states.png": "states.png"},
    ),
    "ifac2020.toml": (
        "softcurve simulate examples/ifac2020.toml -o {out}",
        {"paper-states.png": "states.png", "paper-tip.png": "tip.png"},
    ),
    "inverse_statics.py": (
        "python examples/inverse_statics.py --output {out}/inverse_statics.png",
        {"inverse_statics.png": "inverse_statics.png"},
    ),
    "paper_reproduction.py": (
        "python examples/paper_reproduction.py --figures {out}",
        {"paper-states-first-second.png": "paper-states-first-second.png"},
    ),
    "pneumatic.toml": (
        "softcurve equilibria examples/pneumatic.toml --inputs 2e4 0 0 --plot {out}/equilibria.png",
        {"pneumatic_equilibria.png": "equilibria.png"},
    ),
    "pneumatic_step.toml": (
        "softcurve simulate examples/pneumatic_step.toml -o {out}",
        {"pneumatic_step_states.png": "states.png"},
    ),
    "predictive_circle.py": (
        "python examples/predictive_circle.py --output {out}",
        {"predictive_circle.png": "predictive_circle.png"},
    ),
    "sweep_bending.toml": (
        "softcurve sweep examples/sweep_bending.toml -o {out} --figure",
        {"sweep_bending.png": "sweep.png"},
    ),
    "sweep_grid.toml": (
        "softcurve sweep examples/sweep_grid.toml -o {out} --figure",
        {"sweep_grid.png": "sweep.png"},
    ),
    "sweep_tendons.toml": (
        "softcurve sweep examples/sweep_tendons.toml -o {out} --figure",
        {"sweep_tendons.png": "sweep.png"},
    ),
    "tendon_reach.py": (
        "python examples/tendon_reach.py --output {out}",
        {"tendon_reach.png": "tendon_reach.png"},
    ),
    "tendon_tracking.py": (
        "python examples/tendon_tracking.py --output {out}",
        {
            "tendon_tracking_tensions.png": "tendon_tracking_tensions.png",
            "tendon_tracking_shapes.png": "tendon_tracking_shapes.png",
        },
    ),
    "tendons.toml": (
        "softcurve simulate examples/tendons.toml -o {out}",
        {"tendons_states.png": "states.png", "tendons_tip.png": "tip.png"},
    ),
    "tip_circle.py": (
        "python examples/tip_circle.py --output {out}/tip_circle.png",
        {"tip_circle.png": "tip_circle.png"},
    ),
    "train_reach.py": (
        "python examples/train_reach.py --minutes 3 --output {out}",
        {
            "train_reach_learning_curve.png": "learning_curve.png",
            "train_reach_rollout.png": "rollout.png",
        },
    ),
    "twisting_gripper.toml": (
        "softcurve simulate examples/twisting_gripper.toml -o {out}",
        {"twisting_gripper_states.png": "states.png"},
    ),
    "two-segment.toml": (
        "softcurve simulate examples/two-segment.toml -o {out}",
        {"two_segment_states.png": "states.png", "two_segment_tip.png": "tip.png"},
    ),
    "validate_joint.py": (
        "python examples/validate_joint.py --only oscillation --quick --laws tanh "
        "--figure {out}/validate_joint.png",
        {"validate_joint_oscillations.png": "validate_joint.png"},
    ),
    "validate_caasenbrood2021.py": (
        "python examples/validate_caasenbrood2021.py --figures {out}",
        {
            "validation_oscillation.png": "validation_oscillation.png",
            "validation_openloop.png": "validation_openloop.png",
            "validation_static.png": "validation_static.png",
        },
    ),
}  # fmt: skip
"""Per example of ``examples/``: the command that makes its figures (``{out}`` a folder
of its own) and, per figure of ``docs/figures/``, the file of that folder it is; the
gallery page shows them (a missing one fails the build), ``docs/gallery_figures.py``
runs the commands and copies the files."""

COMMANDS_FOR_FILES = {
    "sweep_": "softcurve sweep examples/{name} -o sweep-out --figure",
    "pneumatic.toml": "softcurve equilibria examples/{name} --inputs 2e4 0 0",
}
"""How an example TOML file is run, by the start of its name (default: ``simulate``)."""

HELP_COLUMNS = "88"
"""Terminal width for the ``--help`` texts, so that the pages do not depend on the
terminal that builds them."""

GENERATED = ("api", "cli", "gallery")


# -- writing the generated pages -------------------------------------------------------------
class Pages:
    """The generated pages of one folder: written when changed, the others deleted."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.written: set[Path] = set()
        folder.mkdir(parents=True, exist_ok=True)

    def write(self, name: str, text: str) -> None:
        path = self.folder / name
        self.written.add(path)
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
            tmp.write_text(text, encoding="utf-8")
            tmp.replace(path)

    def remove_stale(self) -> None:
        for path in self.folder.iterdir():
            if path.is_file() and path not in self.written and not path.name.startswith("."):
                path.unlink()


def public_modules() -> list[str]:
    """The public modules of softcurve (no part of the name starts with ``_``), sorted."""
    import softcurve

    return sorted(
        info.name
        for info in pkgutil.walk_packages(softcurve.__path__, "softcurve.")
        if not any(part.startswith("_") for part in info.name.split("."))
    )


# -- faces: where each object is documented --------------------------------------------------
def public_part(module: str) -> str:
    """The module's name up to its first private part: the package whose ``__init__`` is
    the face of a private implementation module (``softcurve.compiled._model`` gives
    ``softcurve.compiled``)."""
    parts = module.split(".")
    end = next((i for i, part in enumerate(parts) if part.startswith("_")), len(parts))
    return ".".join(parts[:end])


def _exports(module: str) -> tuple[str, ...]:
    return tuple(getattr(importlib.import_module(module), "__all__", ()))


def face(obj) -> str | None:
    """The documented name of a softcurve class or function: ``module.qualname`` where the
    module is public, else ``package.name`` for the nearest public package above the
    private module that exports it; None for an object that no public name shows."""
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if not module or not qualname or module.split(".")[0] != "softcurve":
        return None
    package = public_part(module)
    if package == module:
        return f"{module}.{qualname}"
    while package.count("."):  # the facade, softcurve itself, is a table of links
        namespace = importlib.import_module(package)
        for name in _exports(package):
            if getattr(namespace, name, None) is obj:
                return f"{package}.{name}"
        package = package.rpartition(".")[0]
    return None


@functools.cache
def _imports(module: str) -> dict[str, tuple[str, str]]:
    """``{bound name: (source module, its name there)}`` of the module's absolute
    ``from X import y`` statements, read from its source."""
    source = inspect.getsource(importlib.import_module(module))
    found = {}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            for alias in node.names:
                found[alias.asname or alias.name] = (node.module, alias.name)
    return found


def data_face(module: str, name: str) -> tuple[str, str, str, str]:
    """Where a module-level value (a constant, a table) that ``module`` exports is
    documented and where it is defined: ``(face, name there, definer, name there)``.
    Values carry no ``__module__``; the import statements say where they come from."""
    source, original = _imports(module).get(name, (None, None))
    if source is None or source.split(".")[0] != "softcurve":
        return module, name, module, name
    if public_part(source) == source:
        return data_face(source, original)
    package = public_part(source)
    while package.count("."):
        for exported in _exports(package):
            if _imports(package).get(exported) == (source, original):
                return package, exported, source, original
        package = package.rpartition(".")[0]
    return module, name, source, original


def _documented_name(module: str, name: str) -> str | None:
    """The documented dotted name of ``module.name``, a name the module exports."""
    obj = getattr(importlib.import_module(module), name)
    if inspect.ismodule(obj):
        return obj.__name__
    if inspect.isclass(obj) or inspect.isfunction(obj):
        return face(obj)
    where, exported, _, _ = data_face(module, name)
    return f"{where}.{exported}"


def module_page(name: str) -> str:
    """The reST page of one public module: autodoc for the names it is the face of, the
    values it exports from its private modules with their doc comments, and links to the
    names it re-exports from other faces."""
    text = heading(f"``{name}``") + f"\n.. automodule:: {name}\n"
    exports = _exports(name)
    if not exports:  # no __all__: autodoc documents what the module defines
        return text + "   :members:\n   :member-order: bysource\n"
    namespace = importlib.import_module(name)
    own, values, elsewhere = [], [], []
    for exported in exports:
        obj = getattr(namespace, exported)
        documented = _documented_name(name, exported)
        if documented != f"{name}.{exported}":
            elsewhere.append((exported, documented, obj))
        elif inspect.isclass(obj) or inspect.isfunction(obj):
            own.append(exported)
        elif data_face(name, exported)[2] == name:  # defined here: autodoc reads its comment
            own.append(exported)
        else:
            values.append(exported)
    if own:
        text += f"   :members: {', '.join(own)}\n   :member-order: bysource\n"
    text += "".join(_value_directive(name, value) for value in values)
    if elsewhere:
        text += "\n.. rubric:: Also exported here\n\n"
        for exported, documented, obj in elsewhere:
            summary = f": {_summary(obj)}" if inspect.ismodule(obj) or callable(obj) else ""
            text += f"- ``{exported}``: :py:obj:`{documented}`{summary}\n"
    return text


def _value_directive(module: str, name: str) -> str:
    """A ``py:data`` entry for a value defined in a private module, with the doc comment
    found there (autodoc reads doc comments only in the module it documents)."""
    from sphinx.pycode import ModuleAnalyzer
    from sphinx.util.inspect import object_description

    _, _, definer, original = data_face(module, name)
    comments = ModuleAnalyzer.for_module(definer).find_attr_docs().get(("", original))
    if not comments:
        return ""  # like autodoc: an undocumented value is left out
    value = object_description(getattr(importlib.import_module(module), name))
    value = value if len(value) < 80 and "\n" not in value else "..."
    body = "".join(f"   {line}".rstrip() + "\n" for line in comments)
    return f"\n.. py:data:: {name}\n   :module: {module}\n   :value: {value}\n\n{body}"


def heading(text: str, underline: str = "=") -> str:
    return f"{text}\n{underline * len(text)}\n"


def write_api(folder: Path) -> int:
    """The API reference; returns the number of module pages."""
    import softcurve

    pages = Pages(folder)
    modules = public_modules()
    for name in modules:
        pages.write(f"{name}.rst", module_page(name))
    rows = []
    for name in softcurve.__all__:
        obj = getattr(softcurve, name)
        if inspect.ismodule(obj):
            rows.append(f"   * - :mod:`{obj.__name__}`\n     - {_summary(obj)}")
        else:
            role = "class" if inspect.isclass(obj) else "func"
            rows.append(f"   * - :{role}:`~{face(obj)}`\n"
                        f"     - {_summary(obj)}")  # fmt: skip
    top = (
        heading("``softcurve``: the facade")
        + "\n.. automodule:: softcurve\n\n"
        + "What ``import softcurve as sc`` gives, each documented in the module that "
        "defines it:\n\n.. list-table::\n   :header-rows: 1\n   :widths: 30 70\n\n"
        + "   * - name\n     - what it is\n"
        + "\n".join(rows)
        + "\n"
    )
    pages.write("softcurve.rst", top)
    index = [
        heading("API reference"),
        "Generated from the docstrings at each build (numpy style, rendered by numpydoc). "
        "Start with :doc:`softcurve`, the names ``import softcurve`` gives; the package "
        "is written in layers, each a subpackage that imports only those above it in "
        "this list (:doc:`../architecture`).\n",
        ".. toctree::\n   :maxdepth: 1\n\n   softcurve\n",
    ]
    for layer, what in LAYERS:
        members = [m for m in modules if m == f"softcurve.{layer}"
                   or m.startswith(f"softcurve.{layer}.")]  # fmt: skip
        index.append(f".. toctree::\n   :maxdepth: 1\n   :caption: {layer}: {what}\n\n")
        index.append("".join(f"   {m}\n" for m in members) + "\n")
    rest = [m for m in modules if m.split(".")[1] not in dict(LAYERS)]
    if rest:
        index.append(".. toctree::\n   :maxdepth: 1\n   :caption: other modules\n\n")
        index.append("".join(f"   {m}\n" for m in rest) + "\n")
    pages.write("index.rst", "\n".join(index))
    pages.remove_stale()
    return len(modules) + 1


def _summary(obj) -> str:
    """The first sentence of a docstring, on one line."""
    doc = inspect.getdoc(obj) or ""
    first = " ".join(doc.split("\n\n")[0].split())
    return re.split(r"\.\s+(?=[A-Z(`])", first)[0].rstrip(".")


def help_text(arguments: list[str]) -> str:
    """What ``softcurve ARGUMENTS`` prints, run in this process."""
    from softcurve.cli import main

    out = io.StringIO()
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = HELP_COLUMNS
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            main(arguments)
    finally:
        if columns is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = columns
    return out.getvalue().rstrip() + "\n"


def write_cli(folder: Path) -> int:
    """One page per subcommand from its ``--help``; returns the number of pages."""
    from softcurve.cli import COMMANDS

    pages = Pages(folder)
    names = [importlib.import_module(f"softcurve.cli.{m}").COMMAND.name for m in COMMANDS]
    for name in names:
        pages.write(
            f"{name}.md",
            f"# `softcurve {name}`\n\n"
            f"The text of `softcurve {name} --help`, generated when the site is built.\n\n"
            f"```text\n{help_text([name, '--help'])}```\n",
        )
    pages.write(
        "index.md",
        "# The command line\n\n"
        "One page per command, each the text of `softcurve COMMAND --help`, generated "
        "when the site is built. Exit codes: 0 success, 1 a solver or integrator failed "
        "(the partial result is written), 2 bad input (checked before any work).\n\n"
        f"```text\n{help_text(['--help'])}```\n\n"
        "```{toctree}\n:maxdepth: 1\n\n" + "\n".join(names) + "\n```\n",
    )
    pages.remove_stale()
    return len(names)


def write_gallery(folder: Path, examples: Path) -> int:
    """One page per example; returns the number of pages."""
    pages = Pages(folder)
    names, titles = [], {}
    for path in sorted(examples.iterdir()):
        if path.suffix not in (".py", ".toml") or path.name.startswith("_"):
            continue
        names.append(path.stem)
        title, description = _describe(path)
        titles[path.stem] = title
        figures = "".join(
            f"```{{figure}} ../figures/{figure}\n:alt: {figure}\n\n{figure}\n```\n\n"
            for figure in GALLERY_FIGURES.get(path.name, ("", {}))[1]
        )
        language = "python" if path.suffix == ".py" else "toml"
        pages.write(
            f"{path.stem}.md",
            f"# {path.name}\n\n**{title}.**\n\n{description}\n\n"
            f"Run it from the repository's folder:\n\n```bash\n{_command(path)}\n```\n\n"
            + (
                f"## Figures\n\nMade by `{GALLERY_FIGURES[path.name][0].format(out='OUT')}` "
                f"(`python docs/gallery_figures.py --only {path.name}` redraws them):\n\n"
                f"{figures}"
                if figures
                else ""
            )
            + f"## Source\n\n```{{literalinclude}} ../../examples/{path.name}\n"
            f":language: {language}\n```\n",
        )
    unknown = set(GALLERY_FIGURES) - {p.name for p in examples.iterdir()}
    if unknown:
        raise RuntimeError(f"GALLERY_FIGURES names examples that do not exist: {unknown}")
    cards = "\n".join(f"- {{doc}}`{name}`: {titles[name]}" for name in names)
    pages.write(
        "index.md",
        "# Examples\n\nThe scripts and scenario files of `examples/`, each with what it "
        "shows, how to run it, the figures it makes (where the guide shows them) and its "
        f"source.\n\n{cards}\n\n"
        "```{toctree}\n:hidden:\n\n" + "\n".join(names) + "\n```\n",
    )
    pages.remove_stale()
    return len(names)


def _describe(path: Path) -> tuple[str, str]:
    """``(title, description)`` of an example from its docstring or leading comments:
    the first sentence, and the rest as Markdown (indented lines are code)."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".py":
        doc = inspect.cleandoc(_module_docstring(text))
    else:
        lines = []
        for line in text.splitlines():
            if not line.startswith("#"):
                break
            lines.append(line[2:] if line.startswith("# ") else line[1:])
        doc = "\n".join(lines).strip()
    doc = re.sub(r"::\n", ":\n", doc)  # reST's literal-block marker
    lines = doc.splitlines()
    end = next((i for i, line in enumerate(lines) if not line.strip() or line[0] == " "), None)
    paragraph = "\n".join(lines[:end])
    rest = "\n".join(lines[end:]) if end is not None else ""
    sentences = re.split(r"(?<=[.:])\s+(?=[A-Z(`])", " ".join(paragraph.split()), maxsplit=1)
    title = sentences[0].rstrip(".:") or path.name
    lead = sentences[1] if len(sentences) > 1 else ""
    return title, "\n\n".join(part for part in (lead, rest.strip()) if part)


def _module_docstring(text: str) -> str:
    import ast

    return ast.get_docstring(ast.parse(text), clean=False) or ""


def _command(path: Path) -> str:
    if path.suffix == ".py":
        return f"python examples/{path.name}"
    for start, command in COMMANDS_FOR_FILES.items():
        if path.name.startswith(start):
            return command.format(name=path.name)
    return f"softcurve simulate examples/{path.name}"


def generate(app) -> None:
    """``builder-inited``: write the generated pages into the source folder (unless
    ``softcurve_generate = False``, for a quick build of the guide alone)."""
    source = Path(app.srcdir)
    counts = {"api": 0, "cli": 0, "gallery": 0}
    if app.config.softcurve_generate:
        counts = {
            "api": write_api(source / "api"),
            "cli": write_cli(source / "cli"),
            "gallery": write_gallery(source / "gallery", source.parent / "examples"),
        }
    (Path(app.outdir) / ".pages.txt").write_text(  # read by docs/build.py's summary
        "".join(f"{k} {v}\n" for k, v in counts.items()), encoding="utf-8"
    )


# -- resolving references --------------------------------------------------------------------
def _names(path: str) -> list[str]:
    """The dotted names under which the object ``path`` names may be documented, best
    first: a module's name; a function's or class's :func:`face`; a value's face
    (:func:`data_face`); for an attribute, property, field or enum member, its name under
    its class's face, then the class."""
    parts = path.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        parent, last = None, None
        try:
            for attribute in parts[split:]:
                parent, last, obj = obj, attribute, inspect.getattr_static(obj, attribute)
        except AttributeError:
            return []
        if inspect.ismodule(obj):
            return [obj.__name__]
        if isinstance(parent, type):  # a method, property, field or member of a class
            owner = face(parent) or f"{parent.__module__}.{parent.__qualname__}"
            return [f"{owner}.{last}", owner]
        if isinstance(obj, type) or inspect.isfunction(obj):
            return [face(obj) or f"{obj.__module__}.{obj.__qualname__}"]
        if inspect.ismodule(parent):  # a value of a module
            where, exported, _, _ = data_face(parent.__name__, last)
            return [f"{where}.{exported}"]
        return []
    return []


def resolve(app, env, node, contnode):
    """``missing-reference``: facade names to where they are defined; other projects'
    names to plain text; softcurve names that do not exist are left to Sphinx."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    module, cls = node.get("py:module"), node.get("py:class")
    candidates = [target]
    if module:
        candidates += [f"{module}.{cls}.{target}"] if cls else []
        candidates += [f"{module}.{target}"]
    domain = env.get_domain("py")
    for candidate in candidates:
        if not candidate.startswith("softcurve"):
            continue
        for name in _names(candidate):
            if name == node["reftarget"]:
                continue
            found = domain.resolve_any_xref(
                env, node["refdoc"], app.builder, name, _bare(node), contnode
            )
            if found:
                return found[0][1]
    root = target.split(".")[0]
    if root != "softcurve" and not (module and _exists_in_softcurve(module, cls, target)):
        return contnode  # another project's name: plain text (the build is offline)
    return None


def _bare(node):
    """A copy of a reference node without its module and class context."""
    copy = node.deepcopy()
    for key in ("py:module", "py:class"):
        copy.attributes.pop(key, None)
    copy["refspecific"] = False
    return copy


def _exists_in_softcurve(module: str, cls: str | None, target: str) -> bool:
    """Whether a relative name in a softcurve module means a softcurve object (then a
    missing page for it is an error)."""
    if not module.startswith("softcurve"):
        return False
    first = re.split(r"[.(]", target)[0]
    try:
        namespace = vars(importlib.import_module(module))
    except ImportError:
        return False
    obj = namespace.get(first)
    return obj is not None and getattr(obj, "__module__", "").startswith("softcurve")


# -- speed -----------------------------------------------------------------------------------
def _compile_numpydoc_template_once() -> None:
    """numpydoc compiles its Jinja template for every docstring (about a third of the
    build); compile it once per template loader instead. Uses numpydoc's internals: when
    they differ, the build is left as it is, only slower."""
    try:
        from jinja2 import FileSystemLoader
        from jinja2.sandbox import SandboxedEnvironment
        from numpydoc import docscrape_sphinx as scrape
        from numpydoc import numpydoc as plugin
        from sphinx.jinja2glue import BuiltinTemplateLoader

        original = scrape.get_doc_object_orig
        classes = scrape.SphinxClassDoc, scrape.SphinxFunctionDoc, scrape.SphinxObjDoc
    except (ImportError, AttributeError):
        return
    folder = [str(Path(scrape.__file__).parent / "templates")]
    templates = {}

    def get_doc_object(obj, what=None, doc=None, config=None, builder=None):
        config = {} if config is None else config
        if id(builder) not in templates:
            if builder is None:
                loader = FileSystemLoader(folder)
            else:
                loader = BuiltinTemplateLoader()
                loader.init(builder, dirs=folder)
            environment = SandboxedEnvironment(loader=loader)
            templates[id(builder)] = environment.get_template("numpydoc_docstring.rst")
        config["template"] = templates[id(builder)]
        class_doc, func_doc, obj_doc = classes
        return original(
            obj, what=what, doc=doc, config=config,
            class_doc=class_doc, func_doc=func_doc, obj_doc=obj_doc,
        )  # fmt: skip

    plugin.get_doc_object = get_doc_object


def setup(app):
    _compile_numpydoc_template_once()
    app.add_config_value("softcurve_generate", True, "env", bool)
    app.connect("builder-inited", generate)
    app.connect("missing-reference", resolve)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
