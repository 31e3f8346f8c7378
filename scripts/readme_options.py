"""README.md's table of the main options of ``cuboids fit``, written from the command itself: each option's
flags, default and help text, which for the options that set FitConfig fields are the field's default and
the first paragraph of its docstring (cuboidcli/cli/options.py; ``literals`` in backticks).

    python scripts/readme_options.py           # rewrite the table in README.md
    python scripts/readme_options.py --check   # exit 1 if it is not up to date (tests/cli/test_options.py)
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
BEGIN = "<!-- options of cuboids fit, from the command: python scripts/readme_options.py -->\n"
END = "<!-- end of the options -->\n"
#: The options the table shows, in its order (`cuboids fit --help` has all).
MAIN = (
    "hypotheses",
    "max_cuboids",
    "sampler",
    "local_fraction",
    "max_batches",
    "slab_max_m",
    "align",
    "gravity_down",
    "solver",
    "theta",
    "grid_step",
    "occlusion_aware",
    "fast",
    "refine",
    "seed",
    "device",
    "glb",
    "ply",
    "overlay",
    "workers",
    "ray",
    "ray_address",
    "skip_existing",
)


def markdown_row(param) -> str:
    """``| option | default | meaning |`` of a command's option (a click parameter)."""
    from cuboidcli.cli.options import FIELDS, field_help, field_summary

    flags = "/".join(o for o in [*param.opts, *param.secondary_opts] if o.startswith("--"))
    text = param.help.replace("\\[", "[")
    if param.name in FIELDS and text.startswith(field_help(param.name)):  # the doc, with its literals
        text = field_summary(param.name).replace("``", "`") + text[len(field_help(param.name)) :]
    if isinstance(param.show_default, str):
        default = param.show_default
    elif param.is_flag and param.secondary_opts:
        default = f"`{param.opts[0] if param.default else param.secondary_opts[0]}`"
    elif param.is_flag:
        default = "on" if param.default else "off"
    else:
        default = "-" if param.default is None else str(param.default)
    cells = (f"`{flags}`", default, text.replace("<", "\\<"))
    return "| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |"


def table() -> str:
    """The table, as README.md holds it between BEGIN and END."""
    import click
    import typer

    from cuboidcli.cli.main import app

    group = typer.main.get_command(app)
    params = {p.name: p for p in group.get_command(click.Context(group), "fit").params}
    rows = ["| option | default | meaning |", "|---|---|---|", *(markdown_row(params[n]) for n in MAIN)]
    return "\n".join(rows) + "\n"


def with_table(readme: str) -> str:
    """README.md's text with the table between BEGIN and END written anew."""
    head, rest = readme.split(BEGIN, 1)
    return head + BEGIN + table() + END + rest.split(END, 1)[1]


def main(argv: list[str]) -> int:
    text = README.read_text(encoding="utf-8")
    new = with_table(text)
    if "--check" in argv:
        if new != text:
            print("README.md: the option table is out of date (run this script)", file=sys.stderr)
            return 1
        return 0
    if new != text:
        README.write_text(new, encoding="utf-8")
        print("wrote the option table of README.md")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
