"""Count the package modules a reader follows from ``cuboids fit --depth d.png``.

Starts at ``cuboidcli/cli/main.py`` and follows every ``cuboidcli`` import, at module level and inside
functions alike (read with :mod:`ast`, never executed), transitively. ``main.py`` registers its
subcommands from one module each (``from cuboidcli.cli import fit as _fit`` ... ``_fit.register(app)``;
``fit``, ``demo``, ``export``, ``evaluate``, ``synth``): only the one named by ``--command`` (default
``fit``) is followed, with the modules it imports itself (``cli/fit.py`` imports ``cli/fit_request.py`` and
``cli/fit_run.py``; ``--command demo`` follows ``cli/demo.py``, which calls ``cli/fit.py``). Groups that
``main.py`` imports by name on first use (its ``LAZY_GROUPS``: ``train``) count only for their own
command. Imports under ``if TYPE_CHECKING:`` never run and are not followed. The builders of the parts
registry (``PARTS`` in ``cuboidcli/fitting/parts.py``) are named there as ``"module:function"`` strings and
imported when a part is built: no import statement, yet the fit builds its parts, so the modules they name
(the parts' own, ``cuboidcli.solvers.numerical``) are followed too. Importing ``a.b.c`` runs
``a/__init__.py`` and ``a/b/__init__.py`` too, so those count; the second figure leaves out the
``__init__.py`` files that hold nothing but a docstring.

    python scripts/count_fit_modules.py                      # this checkout's cuboidcli/
    python scripts/count_fit_modules.py ../other/cuboidcli   # another checkout, for a before/after figure
    python scripts/count_fit_modules.py --list               # and the modules, one a line

The count is coarse: a module counts as soon as any function in it imports it, whether or not the fit
path calls that function.
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

ROOT = "cuboidcli"
MAIN = "cuboidcli.cli.main"
#: The parts registry, whose ``"module:function"`` strings name the builders a fit imports by name.
REGISTRY = "cuboidcli.fitting.parts"


def package_modules(package: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file under ``package``."""
    found = {}
    for path in sorted(package.rglob("*.py")):
        parts = [ROOT, *path.relative_to(package).with_suffix("").parts]
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            test = node.test
            if (test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)) == "TYPE_CHECKING":
                for child in node.body:
                    lines.update(range(child.lineno, (child.end_lineno or child.lineno) + 1))
    return lines


def imports_of(module: str, path: Path, known: dict[str, Path]) -> list[tuple[str, str]]:
    """(imported module, name it is bound to or "") for each ``cuboidcli`` import in a file that runs."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    skip = _type_checking_lines(tree)
    is_package = path.name == "__init__.py"
    out = []
    for node in ast.walk(tree):
        if getattr(node, "lineno", None) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [(alias.name, alias.asname or "") for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".") if is_package else module.split(".")[:-1]
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                out.append((sub if sub in known else base, alias.asname or alias.name))
    return [(name, bound) for name, bound in out if name == ROOT or name.startswith(ROOT + ".")]


def builders_of(path: Path) -> list[str]:
    """The modules the ``"cuboidcli.module:function"`` strings of a file name (the registry's builders)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    return [
        node.value.partition(":")[0]
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and node.value.startswith(ROOT + ".")
        and ":" in node.value
    ]


def _owner(name: str, known: dict[str, Path]) -> str | None:
    while name not in known and "." in name:
        name = name.rpartition(".")[0]
    return name if name in known else None


def registered_subcommands(known: dict[str, Path]) -> dict[str, str]:
    """The subcommand modules of ``main.py``: the name bound by its import -> module, for each name whose
    ``register`` it calls."""
    tree = ast.parse(known[MAIN].read_text(encoding="utf-8"))
    registers = {
        node.func.value.id
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr == "register"
        and isinstance(node.func.value, ast.Name)
    }
    return {bound: name for name, bound in imports_of(MAIN, known[MAIN], known) if bound in registers}


def lazy_groups(known: dict[str, Path]) -> dict[str, str]:
    """``main.py``'s ``LAZY_GROUPS``: subcommand groups imported by name when first used (command ->
    module); empty where the checkout has none."""
    tree = ast.parse(known[MAIN].read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        target = getattr(node, "target", None) or (getattr(node, "targets", None) or [None])[0]
        if isinstance(target, ast.Name) and target.id == "LAZY_GROUPS" and node.value is not None:
            return ast.literal_eval(node.value)
    return {}


def reached(package: Path, command: str = "fit") -> list[str]:
    """The modules imported, transitively, on the path of ``cuboids COMMAND`` (sorted); a group of
    ``LAZY_GROUPS`` counts only for its own command."""
    known = package_modules(package)
    others = {m for m in registered_subcommands(known).values() if m != f"{ROOT}.cli.{command}"}
    lazy = lazy_groups(known)
    seen: set[str] = set()
    todo = [MAIN, *([lazy[command]] if command in lazy else [])]
    while todo:
        module = todo.pop()
        if module in seen:
            continue
        seen.add(module)
        parts = module.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]  # the packages above it run first
        named = builders_of(known[module]) if module == REGISTRY else []
        for name, _ in [*imports_of(module, known[module], known), *((n, "") for n in named)]:
            target = _owner(name, known)
            if target is not None and not (module == MAIN and target in others):
                todo.append(target)
    return sorted(seen)


def docstring_only(path: Path) -> bool:
    body = ast.parse(path.read_text(encoding="utf-8")).body
    return all(isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant) for n in body)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parents[1] / ROOT
    parser.add_argument("package", nargs="?", type=Path, default=here, help="a cuboidcli/ folder")
    parser.add_argument("--command", default="fit", help="the subcommand module to follow (default fit)")
    parser.add_argument("--list", action="store_true", help="print the modules too")
    args = parser.parse_args(argv)
    known = package_modules(args.package)
    modules = reached(args.package, args.command)
    thin = [m for m in modules if known[m].name == "__init__.py" and docstring_only(known[m])]
    if args.list:
        for m in modules:
            print(f"{m}{'  (docstring only)' if m in thin else ''}")
    print(f"{len(modules)} modules ({len(modules) - len(thin)} without docstring-only __init__ files)")


if __name__ == "__main__":
    main()
