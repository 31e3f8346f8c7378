"""The ``cuboids`` console script. Each subcommand module registers itself here."""

from __future__ import annotations

import importlib
import os
import sys

import click
import typer
from typer.core import TyperGroup

from cuboidcli import __version__
from cuboidcli.cli.common import fail, quiet_libraries, report_crash

#: Set to 1 for the same effect as ``cuboids --debug``.
DEBUG_ENV = "CUBOIDS_DEBUG"


def _debug(ctx: click.Context) -> bool:
    return bool(ctx.params.get("debug")) or os.environ.get(DEBUG_ENV, "") not in ("", "0")


def _is_cli_exception(exc: BaseException) -> bool:
    """An exit or usage error of the command-line layer (click's, or the copy of click that typer vendors),
    which click turns into its own message and exit status."""
    names = {"Exit", "Abort", "ClickException"}
    return any(
        cls.__name__ in names and cls.__module__.split(".")[0] in ("click", "typer")
        for cls in type(exc).__mro__
    )


def _unwritable_message(exc: BaseException) -> str | None:
    """One line for a file the command could not write (or read) for want of space or permission."""
    from cuboidcli.io.atomic import UNWRITABLE, OutputError

    if isinstance(exc, OutputError):
        return str(exc)
    if isinstance(exc, OSError) and exc.errno in UNWRITABLE:
        return f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc)
    return None


#: Subcommand groups whose modules are imported only when the group is asked for (its commands, or the
#: list of all commands for ``cuboids --help``): the train commands take their options from the training
#: configs, and importing them for every command would load the training package for ``cuboids fit`` too.
#: Each module has ``group()``, the group as a click command.
LAZY_GROUPS = {"train": "cuboidcli.cli.train"}
#: The one-line help ``cuboids --help`` lists for each group of :data:`LAZY_GROUPS`, so that listing the
#: commands imports none of them (a test checks each line against the group's own help).
LAZY_HELP = {"train": "Train the learned components (neural solver, ...)."}


class CuboidsGroup(TyperGroup):
    """The top-level command group: quiet libraries, and one line instead of a traceback for a bug.

    Exceptions the commands raise on purpose (``typer.Exit`` after a one-line error, click's usage errors,
    Ctrl-C) pass through; a closed output pipe ends the command quietly (status 1); any other exception
    is an internal error: its traceback goes to a file
    (:func:`report_crash`) and the command exits with status 1, unless ``--debug`` asks to see it.
    The groups of :data:`LAZY_GROUPS` are built when first asked for, and every command's options are
    checked against the table of options (:func:`~cuboidcli.cli.option_table.check_options`).
    """

    #: True while ``cuboids --help`` lists the commands: a group not loaded yet is shown by its stored help.
    _listing = False

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [*super().list_commands(ctx), *(name for name in LAZY_GROUPS if name not in self.commands)]

    def format_help(self, ctx, formatter) -> None:
        self._listing = True
        try:
            super().format_help(ctx, formatter)
        finally:
            self._listing = False

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name in LAZY_GROUPS and name not in self.commands and self._listing:
            return click.Command(name, short_help=LAZY_HELP[name])
        if name in LAZY_GROUPS and name not in self.commands:
            self.add_command(importlib.import_module(LAZY_GROUPS[name]).group(), name)
        command = super().get_command(ctx, name)
        # every option checked against the one table as it is parsed, whichever module defines it; the
        # table is imported here, as ``cuboids --help`` and ``--version`` need none of it
        from cuboidcli.cli.option_table import check_options

        return None if command is None else check_options(command, name)

    def invoke(self, ctx: click.Context):
        if not _debug(ctx):
            quiet_libraries()
        try:
            return super().invoke(ctx)
        except BrokenPipeError:  # the reader went away (``cuboids fit --help | head``): nothing to report
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # the interpreter's last flush must not fail again
            raise typer.Exit(1) from None
        except Exception as exc:
            if _debug(ctx) or _is_cli_exception(exc):
                raise
            message = _unwritable_message(exc)
            if message is not None:  # a read-only or full output folder: the user's to fix, not a bug
                fail(message)
            report_crash(exc)
            raise typer.Exit(1) from None


app = typer.Typer(
    name="cuboids",
    help="Abstract 3D scenes from depth maps into a few cuboids (Kluger et al., TPAMI 2024).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=CuboidsGroup,
)


def _version(value: bool) -> None:
    if value:
        from cuboidcli.weights import describe_weights

        typer.echo(f"cuboids {__version__}")
        for line in describe_weights():
            typer.echo(line)
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(
        False,
        "--version",
        callback=_version,
        is_eager=True,
        help="Print the version, the weights folder and a short hash of each default weights file.",
    ),
    debug: bool = typer.Option(
        False,
        "--debug",
        help="Show the full traceback of an internal error and the libraries' warnings "
        f"(or set {DEBUG_ENV}=1).",
    ),
) -> None:
    """cuboids: robust cuboid fitting for 3D scene abstraction."""


# Subcommands: each module defines register(app). Keep one line per module.
from cuboidcli.cli import fit as _fit  # noqa: E402

_fit.register(app)
from cuboidcli.cli import demo as _demo  # noqa: E402

_demo.register(app)
from cuboidcli.cli import export as _export  # noqa: E402

_export.register(app)
from cuboidcli.cli import evaluate as _evaluate  # noqa: E402

_evaluate.register(app)
from cuboidcli.cli import synth as _synth  # noqa: E402

_synth.register(app)
# ``cuboids train`` is added on first use: LAZY_GROUPS.


def _exit_status(code: object) -> int:
    """The process exit status ``sys.exit(code)`` would give (printing a message code as it would)."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


def run() -> None:
    """Console entry point: the Typer app, plus a hard exit for processes started by ``torchrun``.

    A multi-process run has finished its work, written its files and torn its process group down by the
    time the command returns (the trainers end with a barrier). What is left is the interpreter's own
    shutdown, and there native thread pools of the libraries loaded (gloo's, the two OpenMP runtimes of
    torch and numba) can abort the process ("terminate called without an active exception"), which makes
    torchrun report a finished run as failed. Such a process therefore leaves with ``os._exit`` once its
    output is flushed. A single process exits normally.
    """
    try:
        app()
        code: object = 0
    except SystemExit as exc:
        code = exc.code
    # WORLD_SIZE as torchrun sets it (as distributed.launched_world_size, without importing torch).
    if int(os.environ.get("WORLD_SIZE", "1")) <= 1:
        sys.exit(code)
    status = _exit_status(code)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


if __name__ == "__main__":
    run()
