"""docs/options.md: every option of every command that takes a value, with its type and the values it
allows, written from the table the commands check their options against (cuboidcli/cli/option_table.py).

    python scripts/option_table.py           # rewrite docs/options.md
    python scripts/option_table.py --check   # exit 1 if it is not up to date (tests/cli/test_option_table.py)
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "options.md"
KINDS = {"int": "whole number", "float": "number", "choice": "name", "text": "text", "path": "path"}
HEADER = """# Options and the values they allow

Every option of every command that takes a value, with the values it allows. A value outside them (NaN,
inf, out of range, a huge count, empty text, a word where a number belongs) ends the command with one line
naming the option and what it allows, exit status 2, before anything is read or written. The Python API
refuses the same values of the same settings with the same words (a ValueError). Switches (`--glb`,
`--refine/--no-refine`) take no value and are not listed. Written by `python scripts/option_table.py` from
`cuboidcli/cli/option_table.py`.
"""


def commands():
    """(name, click command) of every command, ``cuboids ...`` first, then the module entry points."""
    import typer

    from cuboidcli.cli import depth_evaluate
    from cuboidcli.cli.main import app
    from cuboidcli.cli.option_table import check_options

    def walk(group, path=()):
        for name in group.list_commands(None):
            cmd = group.get_command(None, name)
            if hasattr(cmd, "commands"):
                yield from walk(cmd, (*path, name))
            else:
                yield " ".join((*path, name)), cmd

    yield from walk(typer.main.get_command(app))
    one = typer.Typer(add_completion=False)
    one.command()(depth_evaluate.evaluate_depth_cmd)
    yield "depth_evaluate", check_options(typer.main.get_command(one), "depth_evaluate")


def page() -> str:
    from cuboidcli.cli.option_table import rows

    parts = [HEADER]
    for name, cmd in commands():
        title = f"python -m cuboidcli.cli.{name}" if name == "depth_evaluate" else f"cuboids {name}"
        parts.append(f"\n## `{title}`\n\n| option | type | allowed | default |\n|---|---|---|---|\n")
        for flag, kind, allowed, default in rows(name, cmd.params):
            cells = (f"`{flag}`", KINDS[kind], allowed.replace("|", "\\|"), f"`{default}`" if default else "")
            parts.append("| " + " | ".join(cells) + " |\n")
    return "".join(parts)


def main(argv: list[str]) -> int:
    text = page()
    if "--check" in argv:
        current = PAGE.read_text() if PAGE.is_file() else ""
        if current != text:
            print(f"{PAGE.relative_to(ROOT)} is out of date: python scripts/option_table.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text)
    print(f"wrote {PAGE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
