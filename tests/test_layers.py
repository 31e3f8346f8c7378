"""The package's layers: imports point down only, and no modules import each other in a circle.

Every ``import`` and ``from ... import`` of ``cuboidcli`` in the package is read with :mod:`ast`, at module
level and inside functions alike (a lazy import is still a dependency). So is every string constant that
names a module of the package, ``"cuboidcli.export.html"`` or ``"cuboidcli.solvers.numerical:build"``: the
parts registry's builders, the export tables, ``importlib.import_module`` arguments and the package root's
lazy exports are imports made by name, and they count as imports by the module holding the string.
Docstrings (a bare string statement: a module's, class's, function's or attribute's) only mention modules
and are not read; neither is prose that merely contains a module path. Each module belongs to the unit
named by its first component below ``cuboidcli`` (``cuboidcli.fitting.pipeline`` -> ``fitting``,
``cuboidcli.weights`` -> ``weights``); the units are ordered in :data:`LAYERS`, lowest first:

====  =====================================  ===============================================================
rank  units                                  what they hold
====  =====================================  ===============================================================
0     cuboidcli (root), geometry             ``__version__``; torch and numba kernels, rotations, gravity
1     camera, cuboid                         intrinsics; the oriented box
2     io                                     readers and writers: depth maps, results, datasets, weights files
3     nets                                   the networks a user runs (sampler, solver, depth), one format
4     solvers, sampling, depth               the parts of a fit: cuboid solvers, samplers, depth from RGB;
                                             each takes a loaded net or a weights file
5     fitting                                the estimator: config, pipeline, scoring, winner, assignment;
                                             it takes built parts (protocols), no factories, no weights
6     weights                                the weights registry: names, shipped bundles, defaults, hashes
7     export, synth                          GLB / PLY / OBJ / PNG outputs; synthetic scenes and datasets
8     factories, frame, scene, api,          parts built by name with their weights; frame loading; whole
      scaleout, folder, room_folder, load,   rooms; the Python API; many frames on workers or Ray; folders of
      result, job                            frames and rooms; loading inputs; a fit's result; a fit job
9     evaluation                             metrics, datasets, runs
10    learn                                  training: trainers, losses, data (training only)
11    cli                                    the ``cuboids`` command: parses, prints, calls the library
====  =====================================  ===============================================================

A module may import its own unit, units of its rank and units of lower ranks. Within that, the module
graph must have no cycle, and neither may the graph of units of one rank (``solvers`` <-> ``sampling``).
Imports under ``if TYPE_CHECKING:`` never run, yet they tie two modules together as much as any other
import: they must point down and they count as cycles too. A string that names a module is held to the
same two rules, except for the few listed with their reason in :data:`STRING_ALLOWANCES` (the package
root's lazy exports, ``cuboidcli.fit`` and friends, name the API above it on purpose).

docs/development.md's "Package layout" section shows the same table (:func:`test_docs_show_the_layers`).

More rules: inference never imports training code (only ``learn`` and ``cli`` import ``cuboidcli.learn``);
the library outside ``cuboidcli/cli`` never imports the command-line packages (typer, rich, click); the
parts and the estimator never look weights up (no module of :data:`NO_WEIGHTS` imports
``cuboidcli.weights``), and the estimator knows the parts by their protocols alone: ``fitting`` imports no
concrete solver, sampler, depth estimator or network (:data:`FACTORY_ONLY`), and of the parts' units only
their protocol modules (:data:`ESTIMATOR_MAY_IMPORT`), in functions too: a part compiles its own kernels
(``warm_up``), the estimator calls no kernel of a part. The parts registry (:data:`REGISTRY`) alone names
the parts' builders, by string. And a string that names a module names one that exists.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "cuboidcli"

#: Units, lowest layer first; units in one tuple share a rank (see the module docstring).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("cuboidcli", "geometry"),
    ("camera", "cuboid"),
    ("io",),
    ("nets",),
    ("solvers", "sampling", "depth"),
    ("fitting",),
    ("weights",),
    ("export", "synth"),
    ("factories", "load", "result", "api", "scaleout", "job"),
    ("evaluation",),
    ("learn",),
    ("cli",),
)
RANK = {unit: rank for rank, units in enumerate(LAYERS) for unit in units}

#: Training code: imported only by the units in TRAINING_USERS (and by itself).
TRAINING = ("cuboidcli.learn",)
TRAINING_USERS = ("learn", "cli")
#: Command-line packages the library (everything but cuboidcli.cli) never imports.
CLI_PACKAGES = ("typer", "rich", "click")
#: Units that take a loaded network or a weights file and never ask the weights registry which one.
NO_WEIGHTS = ("nets", "solvers", "sampling", "depth", "fitting")
#: Modules only the factories build from (and training and the tests use directly); the estimator
#: (``fitting``) receives what they make through the CuboidSolver and Sampler protocols.
FACTORY_ONLY = (
    "cuboidcli.solvers.numerical",
    "cuboidcli.solvers.neural",
    "cuboidcli.solvers.onnx",
    "cuboidcli.solvers.onnx_export",
    "cuboidcli.sampling.learned",
    "cuboidcli.depth",
    "cuboidcli.nets",
)
#: The units of the parts a fit is given (lower than ``fitting``) ...
PART_UNITS = ("solvers", "sampling", "depth", "nets")
#: ... and the only modules of them the estimator imports: the protocols and what they hand over (the
#: solver's protocol and ``solve_upright``; the sampler's protocol, ``SamplingContext``, ``SpaceCells`` and
#: ``draw_hypotheses``, re-exported by the package).
ESTIMATOR_MAY_IMPORT = ("cuboidcli.solvers.base", "cuboidcli.sampling")
#: The parts registry: it names every part's builder ("cuboidcli.solvers.numerical:build") so that the
#: settings, the factories and the command line know the parts, and imports the builder only when a part is
#: built by name (``Part.build``, called by the factories). Its strings are held to the layer and cycle rules
#: (the builders lie below ``fitting``), not to the estimator's rules above: naming a part is what it is for.
REGISTRY = "cuboidcli.fitting.parts"

#: A string constant that names a module of the package, alone or with a name in it (``module:name``).
MODULE_STRING = re.compile(r"cuboidcli(?:\.[A-Za-z_]\w*)+(?::[A-Za-z_]\w*)?")
#: Strings that may name a module above, or in a circle with, the module holding them: (holding module,
#: named module, or "*" for any) -> why. They are still held to the other rules (training code, weights).
STRING_ALLOWANCES: dict[tuple[str, str], str] = {
    ("cuboidcli", "*"): "the package root's lazy exports (``cb.fit``, ``cb.Camera``, ...): a facade that "
    "resolves the public names on first use; the root stays at rank 0 because every module may import "
    "``__version__`` from it, which would otherwise close a circle with everything it exports",
    ("cuboidcli.synth.dataset", "cuboidcli.synth"): "the ``generator`` label a synthetic dataset and its "
    "ground truth are tagged with: it names the producer in the files written, and is never imported",
}


@dataclass(frozen=True)
class Import:
    source: str
    """The importing module (``cuboidcli.fitting.pipeline``)."""
    target: str
    """The imported module, or for a name imported from a module, that module."""
    line: int
    type_only: bool
    """Under ``if TYPE_CHECKING:``."""
    by_name: bool = False
    """Named in a string constant (``"cuboidcli.solvers.numerical:build"``), not an import statement."""

    @property
    def allowance(self) -> str | None:
        """Why this string may point up or close a circle (:data:`STRING_ALLOWANCES`); None for the rest."""
        if not self.by_name:
            return None
        return STRING_ALLOWANCES.get((self.source, self.target)) or STRING_ALLOWANCES.get((self.source, "*"))

    def __str__(self) -> str:
        if self.by_name:
            return f"{self.source} (line {self.line}) names {self.target} in a string"
        return f"{self.source} (line {self.line}) imports {self.target}"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def unit(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def _type_checking_lines(tree: ast.AST) -> set[int]:
    """Line numbers of the statements inside ``if TYPE_CHECKING:`` blocks."""
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            test = node.test
            name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
            if name == "TYPE_CHECKING":
                for child in node.body:
                    lines.update(range(child.lineno, (child.end_lineno or child.lineno) + 1))
    return lines


def _absolute(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _owner(name: str) -> str:
    """The package module that defines ``name`` (a module, or a name inside one)."""
    known = modules()
    while name not in known and "." in name:
        name = name.rpartition(".")[0]
    return name


def imported_names(path: Path) -> list[tuple[str, int, bool]]:
    """(dotted module name, line, type-only) for every import statement in a file, at any depth: for
    ``from m import x`` both ``m.x`` and ``m`` are candidates, resolved by the caller."""
    tree = ast.parse(path.read_text(), str(path))
    module, is_package = module_name(path), path.name == "__init__.py"
    type_only = _type_checking_lines(tree)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, node.lineno, node.lineno in type_only) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(module, is_package, node)
            out += [(f"{base}.{alias.name}", node.lineno, node.lineno in type_only) for alias in node.names]
    return out


def module_strings(text: str) -> list[tuple[str, int]]:
    """(string, line) for every string constant in source ``text`` that names a package module
    (:data:`MODULE_STRING`), in order; docstrings (bare string statements) are left out."""
    tree = ast.parse(text)
    docs = {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(getattr(node.value, "value", None), str)
    }
    found = [
        (node.value, node.lineno)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and id(node) not in docs
        and MODULE_STRING.fullmatch(node.value)
    ]
    return sorted(found, key=lambda found: found[1])


@cache
def package_imports() -> tuple[Import, ...]:
    """Every import of a cuboidcli module by a cuboidcli module (not of itself): the import statements, then
    the modules named in strings (``by_name``)."""
    found = []
    for source, path in modules().items():
        for name, line, type_only in imported_names(path):
            if name == "cuboidcli" or name.startswith("cuboidcli."):
                target = _owner(name)
                if target != source:
                    found.append(Import(source, target, line, type_only))
        for string, line in module_strings(path.read_text()):
            target = _owner(string.partition(":")[0])
            if target != source:
                found.append(Import(source, target, line, False, by_name=True))
    return tuple(found)


def ranked_imports() -> list[Import]:
    """The imports the layer and cycle rules judge: all but the strings :data:`STRING_ALLOWANCES` lets be."""
    return [imp for imp in package_imports() if imp.allowance is None]


def estimator_imports() -> list[Import]:
    """The imports the estimator's rules judge: all but the parts registry's strings (:data:`REGISTRY`)."""
    return [imp for imp in package_imports() if not (imp.by_name and imp.source == REGISTRY)]


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
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
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_every_unit_has_a_layer():
    units = {unit(m) for m in modules()}
    assert not units - set(RANK), f"add these packages or modules to LAYERS: {sorted(units - set(RANK))}"
    assert len(RANK) == sum(len(units) for units in LAYERS), "a unit is listed twice in LAYERS"


def test_imports_point_down():
    upward = [
        f"{imp}: {unit(imp.source)} (rank {RANK[unit(imp.source)]}) may not import {unit(imp.target)} "
        f"(rank {RANK[unit(imp.target)]})"
        for imp in ranked_imports()
        if RANK[unit(imp.target)] > RANK[unit(imp.source)]
    ]
    assert not upward, "imports that point up:\n" + "\n".join(upward)


def test_no_module_cycles():
    """Type-only imports count: a module that names another's types for the checker depends on it. So do
    modules named in strings: the module that imports a builder by name depends on it when it runs."""
    edges: dict[str, set[str]] = {}
    for imp in ranked_imports():
        edges.setdefault(imp.source, set()).add(imp.target)
    found = "\n".join(" <-> ".join(c) for c in cycles(edges))
    assert not found, "modules that import each other in a circle:\n" + found


def test_no_cycles_between_units_of_one_rank():
    edges: dict[str, set[str]] = {}
    for imp in ranked_imports():
        a, b = unit(imp.source), unit(imp.target)
        if a != b:
            edges.setdefault(a, set()).add(b)
    found = "\n".join(" <-> ".join(c) for c in cycles(edges))
    assert not found, "units that import each other in a circle:\n" + found


def test_inference_never_imports_training_code():
    def is_training(module: str) -> bool:
        return any(module == t or module.startswith(t + ".") for t in TRAINING)

    wrong = [
        str(imp)
        for imp in package_imports()
        if is_training(imp.target) and not is_training(imp.source) and unit(imp.source) not in TRAINING_USERS
    ]
    assert not wrong, "training code imported outside learn/ and cli/:\n" + "\n".join(wrong)


def test_the_library_never_imports_the_command_line_packages():
    wrong = [
        f"{module} (line {line}) imports {name}"
        for module, path in modules().items()
        if unit(module) != "cli"
        for name, line, _ in imported_names(path)
        if name.split(".")[0] in CLI_PACKAGES
    ]
    assert not wrong, "the library imports command-line packages:\n" + "\n".join(wrong)


def test_the_parts_and_the_estimator_never_look_weights_up():
    assert all(RANK[u] < RANK["weights"] for u in NO_WEIGHTS)  # an import would point up, too
    wrong = [
        str(imp)
        for imp in package_imports()
        if imp.target == "cuboidcli.weights" and unit(imp.source) in NO_WEIGHTS
    ]
    assert not wrong, "the weights registry imported below it:\n" + "\n".join(wrong)


def test_the_estimator_builds_no_parts():
    def built_by_factories(module: str) -> bool:
        return any(module == m or module.startswith(m + ".") for m in FACTORY_ONLY)

    wrong = [
        str(imp)
        for imp in estimator_imports()
        if unit(imp.source) == "fitting" and built_by_factories(imp.target)
    ]
    assert not wrong, "fitting builds a part itself (that is cuboidcli.factories' work):\n" + "\n".join(wrong)


def test_the_estimator_imports_only_the_protocols_of_the_parts():
    """``fitting`` reaches the solvers, samplers, depth estimators and networks through their protocol
    modules alone, at module level and inside functions: no kernel of a part is imported (a part warms up
    its own, ``warm_up``)."""
    assert all(unit(m) in PART_UNITS and m in modules() for m in ESTIMATOR_MAY_IMPORT)
    wrong = [
        str(imp)
        for imp in estimator_imports()
        if unit(imp.source) == "fitting"
        and unit(imp.target) in PART_UNITS
        and imp.target not in ESTIMATOR_MAY_IMPORT
    ]
    assert not wrong, "fitting imports a part beyond its protocol:\n" + "\n".join(wrong)


def test_the_walk_sees_lazy_and_type_only_imports():
    """The checks above are only as good as the walk: it finds imports inside functions (the minimal-set
    proposals are imported when a batch is drawn, the learned sampler when a factory builds it) and marks
    those under TYPE_CHECKING."""
    found = {(imp.source, imp.target): imp for imp in package_imports() if not imp.by_name}
    assert not found[("cuboidcli.sampling", "cuboidcli.sampling.proposals")].type_only
    assert not found[("cuboidcli.factories", "cuboidcli.sampling.learned")].type_only
    assert found[("cuboidcli.sampling.learned", "cuboidcli.sampling")].type_only
    assert found[("cuboidcli.evaluation.outputs", "cuboidcli.evaluation.runner")].type_only
    assert ("cuboidcli.fitting.pipeline", "cuboidcli.sampling") in found
    assert ("cuboidcli.io.result", "cuboidcli") in found  # from cuboidcli import __version__


def test_the_walk_sees_modules_named_in_strings():
    """The parts registry's builders and the package root's lazy exports are imports by name: the walk
    finds them, judges the registry's by the layers and lets the root's be, for the reason it gives."""
    named = [imp for imp in package_imports() if imp.by_name]
    registry = {imp.target for imp in named if imp.source == REGISTRY}
    assert "cuboidcli.solvers.numerical" in registry and "cuboidcli.sampling.learned" in registry
    assert all(imp.allowance is None for imp in named if imp.source == REGISTRY)
    root = [imp for imp in named if imp.source == "cuboidcli"]
    assert root and all(imp.allowance for imp in root)
    assert all(reason.strip() for reason in STRING_ALLOWANCES.values())
    used = {(imp.source, "*") for imp in named} | {(imp.source, imp.target) for imp in named}
    assert not set(STRING_ALLOWANCES) - used, "allowances no string needs any more: drop them"


def test_only_strings_that_are_not_docstrings_name_modules():
    source = '''"""cuboidcli.api"""
import importlib
EXPORTS = {"fit": "cuboidcli.api"}
def load():
    """cuboidcli.cli"""
    return importlib.import_module("cuboidcli.learn.trainer")
class Part:
    """cuboidcli.cli.main"""
    builder: str = "cuboidcli.solvers.numerical:build"
    """cuboidcli.evaluation"""
PROSE = "see cuboidcli.api for the rest"
SPELLED = f"cuboidcli.{EXPORTS}"
'''
    assert module_strings(source) == [
        ("cuboidcli.api", 3), ("cuboidcli.learn.trainer", 6), ("cuboidcli.solvers.numerical:build", 9),
    ]  # fmt: skip


def _defines(module: str, name: str) -> bool:
    """Whether ``module`` binds ``name`` at its top level (a def, a class, an assignment or an import)."""
    bound = set()
    for node in ast.parse(modules()[module].read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            bound.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            bound.update(n.id for target in targets for n in ast.walk(target) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            bound.update((alias.asname or alias.name).split(".")[0] for alias in node.names)
    return name in bound


def test_strings_name_modules_that_exist():
    """A module named by a string is imported only when used, so a stale name fails late, at a user's; the
    walk resolves every one now: the module exists and, for ``module:name``, binds that name."""
    wrong = []
    for source, path in modules().items():
        for string, line in module_strings(path.read_text()):
            module, _, name = string.partition(":")
            owner = _owner(module)
            if owner == "cuboidcli" or (name and (owner != module or not _defines(owner, name))):
                wrong.append(f"{source} (line {line}): {string!r}")
    assert not wrong, "strings that name no module of the package (or no name in it):\n" + "\n".join(wrong)


def test_docs_show_the_layers():
    """docs/development.md's "Package layout" table lists the units of LAYERS at their ranks."""
    guide = PACKAGE.parent / "docs" / "development.md"
    if not guide.is_file():
        pytest.skip("docs/development.md (the developers' guide with the layer table) is not here yet")
    text = guide.read_text()
    assert "## Package layout" in text, "docs/development.md has no '## Package layout' section"
    section = text.split("## Package layout", 1)[1].split("\n## ", 1)[0]
    shown = {}
    for row in section.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0].isdigit():
            for name in cells[1].split(","):
                shown[name.strip().strip("`").removesuffix("/").removesuffix(".py")] = int(cells[0])
    assert shown == {u: r for u, r in RANK.items() if u != "cuboidcli"}
