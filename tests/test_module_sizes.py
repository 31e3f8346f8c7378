"""Modules a newcomer can read in one sitting: no module of the package over :data:`MAX_LINES` lines, and no
module of the command line (``cuboidcli/cli``, which only parses, prints and calls the library) over
:data:`MAX_CLI_LINES`. A module that grows past its bound is split by concept, not trimmed."""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "cuboidcli"
#: Most lines of a library module.
MAX_LINES = 400
#: Most lines of a command-line module.
MAX_CLI_LINES = 300


def _lines(path: Path) -> int:
    return len(path.read_text().splitlines())


def _too_long(paths, bound: int) -> list[str]:
    return [f"{p.relative_to(PACKAGE.parent)}: {n} lines" for p in sorted(paths) if (n := _lines(p)) > bound]


def test_no_library_module_is_over_400_lines():
    modules = [p for p in PACKAGE.rglob("*.py") if "cli" not in p.relative_to(PACKAGE).parts[:1]]
    assert modules
    long = _too_long(modules, MAX_LINES)
    assert not long, f"split these modules (at most {MAX_LINES} lines):\n" + "\n".join(long)


def test_no_command_line_module_is_over_300_lines():
    modules = list((PACKAGE / "cli").rglob("*.py"))
    assert modules
    long = _too_long(modules, MAX_CLI_LINES)
    assert not long, f"split these command-line modules (at most {MAX_CLI_LINES} lines):\n" + "\n".join(long)
