"""The ``cuboids`` console script. Each subcommand module registers itself here."""

from __future__ import annotations

import typer

from cuboidcli import __version__

app = typer.Typer(
    name="cuboids",
    help="Abstract 3D scenes from depth maps into a few cuboids (Kluger et al., TPAMI 2024).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"cuboids {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version."
    ),
) -> None:
    """cuboids: robust cuboid fitting for 3D scene abstraction."""


# Subcommands: each module defines register(app). Keep one line per module.
from cuboidcli.cli import fit as _fit  # noqa: E402

_fit.register(app)
from cuboidcli.cli import export as _export  # noqa: E402

_export.register(app)
from cuboidcli.cli import evaluate as _evaluate  # noqa: E402

_evaluate.register(app)
from cuboidcli.cli import synth as _synth  # noqa: E402

_synth.register(app)
from cuboidcli.cli import train as _train  # noqa: E402

_train.register(app)

if __name__ == "__main__":
    app()
