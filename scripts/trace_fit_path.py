"""Follow ``cuboids fit`` as it runs: the package files whose functions execute, and the calls that cross
from one unit of the package to another.

Runs the command in this process under :func:`sys.setprofile` and records every Python call into a
``cuboidcli`` file (module and class bodies run by ``import`` are left out: the figure is about the functions
control passes through, not about what gets imported). A call is attributed to the nearest ``cuboidcli`` frame
above it, so a network's ``forward`` reached through ``torch.nn.Module.__call__`` counts as a call from the
code that called the network. Units are the first component below ``cuboidcli`` (``fitting``, ``cli``,
``weights``), as in ``tests/test_layers.py``; a crossing is a distinct (caller unit -> callee unit) pair,
and it is upward where the callee's layer is above the caller's in that test's table (units the table does
not know, in older checkouts, are reported as such). An upward call is a callback when the caller's file
imports nothing of the callee's unit (a function handed down, like the command's progress printer), and an
upward dependency when it does. The builders of the parts registry (``PARTS`` in
``cuboidcli/fitting/parts.py``), imported by name when a part is built, live in the parts' own modules, so
building a part is a call down (``fitting -> solvers``); in older checkouts they were in
``cuboidcli/factories.py`` and that call shows as an upward callback (``fitting -> factories``).

    python scripts/trace_fit_path.py --depth D.png --camera nyu [fit options]     # this checkout
    python scripts/trace_fit_path.py --package ../old --depth D.png --camera nyu  # another checkout's code
    python scripts/trace_fit_path.py --list --depth D.png --camera nyu  # and the files, as first reached

A module "entered again from below" is one control comes back into from a module it had called down into
(``job.py -> api.py -> job.py``), listed with ``--list`` as "back into M from N": a progress callback the
command hands down shows so, and nothing else should. A module of the layers from the API up (``cli``,
``job``, ``api``, ``load``, ``result``, ...) "entered more than once" is called into from another package
more than once while it was not running (listed as "entries into M"; a constructor and then a method of
what it built count as two).

Every argument but ``--package`` and ``--list`` goes to ``cuboids fit`` as it is: a checkout from before
``--camera`` (0.1.0) takes ``--preset nyu`` instead. The embedded sample frame is
``--depth cuboidcli/data/sample/sample_depth.png -K cuboidcli/data/sample/camera.json``.

The fit's outputs go to a temporary folder. Profiling slows the fit down; its timings mean nothing.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import inspect
import sys
import tempfile
from collections import Counter
from functools import cache
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def unit_of(module_file: str, package: Path) -> str:
    """The unit of a file below ``package`` (``fitting/pipeline.py`` -> ``fitting``; ``api.py`` -> ``api``;
    ``__init__.py`` -> ``cuboidcli``)."""
    rel = Path(module_file).resolve().relative_to(package)
    first = rel.parts[0]
    if len(rel.parts) == 1:
        return "cuboidcli" if first == "__init__.py" else rel.stem
    return first


@cache
def imported_units(module_file: str) -> frozenset[str]:
    """The package units a file imports anywhere in it (module level or in functions); read once a file."""
    tree = ast.parse(Path(module_file).read_text(encoding="utf-8"))
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and not n.level]
    units = {name.split(".")[1] for name in names if name.startswith("cuboidcli.")}
    return frozenset(units | ({"cuboidcli"} if "cuboidcli" in names else set()))


def trace(package: Path, argv: list[str]) -> tuple[Counter, Counter, set, Counter, Counter]:
    """Run ``cuboids fit ARGV`` from ``package``'s checkout: (calls per file, calls per unit crossing, the
    crossings whose caller file imports the callee's unit, re-entries per (file, caller file): calls into a
    file from another file while the first is still running further up the stack: control climbing back
    into a module it had gone down from), and entries per file: calls into it from another file while it
    is not running (a property read excepted))."""
    sys.path.insert(0, str(package.parent))
    prefix = str(package) + "/"
    files: Counter = Counter()
    crossings: Counter = Counter()
    by_import: set = set()
    reentries: Counter = Counter()
    entries: Counter = Counter()

    def profile(frame, event, arg):
        if event != "call":
            return
        path = frame.f_code.co_filename
        if not path.startswith(prefix) or not frame.f_code.co_flags & inspect.CO_OPTIMIZED:
            return  # not ours, or a module or class body run by an import
        files[path] += 1
        caller = frame.f_back
        while caller is not None and not caller.f_code.co_filename.startswith(prefix):
            caller = caller.f_back
        if caller is not None and caller.f_code.co_filename != path:
            above = caller.f_back
            while above is not None:
                if above.f_code.co_filename == path:
                    reentries[(path, caller.f_code.co_filename)] += 1
                    break
                above = above.f_back
            else:  # a call down into the module from another package; reading a property is no entry
                owner = frame.f_locals.get("self")
                other = unit_of(caller.f_code.co_filename, package) != unit_of(path, package)
                if other and not isinstance(getattr(type(owner), frame.f_code.co_name, None), property):
                    entries[path] += 1
        if caller is not None and caller.f_code.co_name != "<module>":
            a, b = unit_of(caller.f_code.co_filename, package), unit_of(path, package)
            if a != b:
                crossings[(a, b)] += 1
                if b in imported_units(caller.f_code.co_filename):
                    by_import.add((a, b))

    main = importlib.import_module("cuboidcli.cli.main")
    assert Path(main.__file__).resolve().is_relative_to(package), f"imported {main.__file__}, not {package}"
    with tempfile.TemporaryDirectory() as out:
        sys.argv = ["cuboids", "fit", *argv, "-o", str(Path(out) / "fit.json")]
        sys.setprofile(profile)
        try:
            main.run()
        except SystemExit as e:
            if e.code not in (0, None):
                raise
        finally:
            sys.setprofile(None)
    return files, crossings, by_import, reentries, entries


def layer_ranks() -> dict[str, int]:
    """Unit -> rank, from the table of ``tests/test_layers.py`` in this checkout."""
    sys.path.insert(0, str(REPO))
    from tests.test_layers import LAYERS

    return {unit: rank for rank, units in enumerate(LAYERS) for unit in units}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--package", type=Path, default=REPO, help="the checkout whose code runs")
    parser.add_argument("--list", action="store_true", help="print the files and crossings too")
    args, fit_args = parser.parse_known_args(argv)
    ranks = layer_ranks()
    package = args.package.resolve() / "cuboidcli"
    files, crossings, by_import, reentries, entries = trace(package, fit_args)
    upper = {u for u, r in ranks.items() if r >= ranks.get("api", 99)}
    repeated = {p: n for p, n in entries.items() if n > 1 and unit_of(p, package) in upper}
    upward = [(a, b) for a, b in crossings if a in ranks and b in ranks and ranks[b] > ranks[a]]
    callbacks = [pair for pair in upward if pair not in by_import]
    unknown = sorted({u for pair in crossings for u in pair if u not in ranks})
    if args.list:
        for path, calls in files.items():  # in the order control first reaches them
            print(f"{calls:8d}  {Path(path).relative_to(package)}")
        for (a, b), calls in sorted(crossings.items()):
            mark = ("  upward callback" if (a, b) in callbacks else "  UPWARD") if (a, b) in upward else ""
            print(f"{calls:8d}  {a} -> {b}{mark}")
        for (path, caller), calls in sorted(reentries.items()):
            into, came = Path(path).relative_to(package), Path(caller).relative_to(package)
            print(f"{calls:8d}  back into {into} from {came}")
        for path, calls in repeated.items():
            print(f"{calls:8d}  entries into {Path(path).relative_to(package)}")
    print(
        f"{len(files)} files run, {len(crossings)} unit crossings ({len(upward) - len(callbacks)} upward "
        f"dependencies, {len(callbacks)} upward callbacks), {len(reentries)} modules entered again from "
        f"below, {len(repeated)} modules above the estimator entered more than once"
        + (f"; units not in the layer table: {', '.join(unknown)}" if unknown else "")
    )


if __name__ == "__main__":
    main()
