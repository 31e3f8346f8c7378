"""The ``cuboids evaluate`` command as an app of its own, for the CLI tests of this folder."""

import pytest
import typer

from cuboidcli.cli.evaluate import register


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    app = typer.Typer()

    @app.callback()
    def main() -> None:  # keeps `evaluate` a subcommand
        pass

    register(app)
    return app
