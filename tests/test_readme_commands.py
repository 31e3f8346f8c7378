"""Every ``cuboids ...`` command line that README.md and docs/*.md show uses a command that exists and only
options that command shows in its help (not a deprecated spelling), so that a renamed or removed option
cannot stay in the documentation."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
import typer

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])


def command_lines(text: str) -> list[str]:
    """The ``cuboids ...`` commands of the fenced code blocks (continuation lines joined, comments dropped)
    and of inline code; a line of several commands (``a; b``, ``a && b``) gives each."""
    snippets = []
    for block in re.findall(r"^```[a-z]*\n(.*?)^```", text, flags=re.S | re.M):
        snippets += [line.split(" # ")[0] for line in block.replace("\\\n", " ").splitlines()]
    inline = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    snippets += re.findall(r"`(cuboids [^`]+)`", inline)
    parts = (part.strip() for snippet in snippets for part in re.split(r";|&&|\bdo\b", snippet))
    return [" ".join(part.split()) for part in parts if part.startswith("cuboids ")]


def root_group():
    from cuboidcli.cli.main import app

    return typer.main.get_command(app)


def resolve(words: list[str]) -> list[tuple[object, list[str]]]:
    """(command, the words after its name) for ``cuboids WORDS``; a word ``a|b`` names several commands."""
    found = [(root_group(), words)]
    while True:
        deeper = []
        for cmd, rest in found:
            if hasattr(cmd, "get_command") and rest and not rest[0].startswith("-"):
                for name in rest[0].split("|"):
                    sub = cmd.get_command(cmd.context_class(cmd), name)
                    assert sub is not None, f"no command {name!r} under {cmd.name!r}"
                    deeper.append((sub, rest[1:]))
            else:
                deeper.append((cmd, rest))
        if deeper == found:
            return found
        found = deeper


def flags_of(words: list[str]) -> list[str]:
    return [w.strip("[]").split("=")[0] for w in words if re.fullmatch(r"\[?--?[A-Za-z][\w-]*(=.*)?\]?", w)]


def examples() -> list[tuple[str, str]]:
    return [
        (str(page.relative_to(ROOT)), line)
        for page in PAGES
        for line in command_lines(page.read_text(encoding="utf-8"))
    ]


def test_the_documentation_shows_commands():
    assert len(examples()) >= 60


@pytest.mark.parametrize("page", [p for p in PAGES], ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shown_option_exists(page):
    wrong = []
    for line in command_lines(page.read_text(encoding="utf-8")):
        words = shlex.split(line.replace("'", ""), posix=True)[1:]
        words = [w for w in words if w != "..."]
        for cmd, rest in resolve(words):
            # a hidden option is a deprecated spelling: the documentation shows the current one
            shown = [p for p in cmd.params if not getattr(p, "hidden", False)]
            known = {opt for p in shown for opt in [*p.opts, *p.secondary_opts]} | {"--help"}
            wrong += [f"{line!r}: {flag}" for flag in flags_of(rest) if flag not in known]
    assert not wrong, "options no command has: " + "; ".join(wrong)
