"""The ``cuboids evaluate`` command as an app of its own, for the CLI tests of this folder, and the helpers
that run it and read its one-line errors."""

import pytest
import typer
from typer.testing import CliRunner

from cuboidcli.cli.evaluate import register


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    app = typer.Typer()

    @app.callback()
    def main() -> None:  # keeps `evaluate` a subcommand
        pass

    register(app)
    return app


def run_evaluate(app: typer.Typer, *args):
    """``cuboids evaluate ARGS`` through ``app`` (paths and numbers as text)."""
    return CliRunner().invoke(app, ["evaluate", *map(str, args)])


def one_line_error(result, code: int = 2) -> str:
    """The output of a command that ended with exit status ``code`` and one line, no traceback."""
    assert result.exit_code == code, result.output
    assert "Traceback" not in result.output and result.output.strip().count("\n") == 0, result.output
    return result.output
