"""Options whose spelling changed: the old spelling keeps working, hidden from ``--help``, with a one-line
warning that names the new one.

    camera: str = typer.Option(None, "--camera", help="..."),
    preset: str = renamed_option("--preset", "--camera"),
    ...
    camera = prefer_new(camera, preset, "--preset", "--camera")
"""

from __future__ import annotations

from typing import Any

import typer

from cuboidcli.cli.common import console, fail


def renamed_option(old: str, new: str, *aliases: str) -> Any:
    """A hidden option that accepts the ``old`` spelling of ``new`` (value None when not given)."""
    return typer.Option(None, old, *aliases, hidden=True, help=f"Deprecated spelling of {new}.")


def prefer_new(new_value: Any, old_value: Any, old: str, new: str) -> Any:
    """The value to use: ``new_value`` if given, else ``old_value`` with a warning that ``old`` is now
    spelled ``new``. Giving both is an error (exit 2)."""
    if old_value is None:
        return new_value
    if new_value is not None:
        fail(f"{old} and {new} are the same option; give only {new}")
    console.print(f"[yellow]warning:[/] {old} is deprecated; use {new}", highlight=False, soft_wrap=True)
    return old_value


def renamed_value(value, default, old_value, old: str, new: str):
    """The value of an option that has a default and an old spelling (:func:`renamed_option`): ``value``,
    or the old spelling's with a one-line warning when only that was given; both given (``value`` other
    than ``default``) is an error, as :func:`prefer_new` makes it."""
    chosen = prefer_new(None if value == default else value, old_value, old, new)
    return default if chosen is None else chosen
