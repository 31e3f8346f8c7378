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

#: Every old spelling that still works, with the commands that take it and its new spelling: the one list
#: of them (docs/development.md, "Options and settings are defined once").
RENAMED: tuple[tuple[tuple[str, ...], str, str], ...] = (
    (("fit", "synth"), "--preset", "--camera"),
    (("train solver", "train sampler", "train seed", "train depth", "depth_evaluate"), "--out", "--output"),
    (("train solver", "train sampler", "train seed"), "--width", "--channels"),
)


def new_spelling(old: str) -> str:
    """The new spelling of the old option ``old`` (:data:`RENAMED`); KeyError for an option never renamed."""
    for _, was, now in RENAMED:
        if was == old:
            return now
    raise KeyError(f"{old} is not a renamed option; add it to RENAMED")


def renamed_option(old: str, new: str | None = None, *aliases: str) -> Any:
    """A hidden option that accepts the ``old`` spelling (value None when not given); its new spelling is
    the one :data:`RENAMED` gives (``new``, when passed, must agree)."""
    now = new_spelling(old)
    if new is not None and new != now:
        raise ValueError(f"{old} is renamed to {now} in RENAMED, not {new}")
    return typer.Option(None, old, *aliases, hidden=True, help=f"Deprecated spelling of {now}.")


def prefer_new(new_value: Any, old_value: Any, old: str, new: str, warn: bool = True) -> Any:
    """The value to use: ``new_value`` if given, else ``old_value`` with a warning that ``old`` is now
    spelled ``new`` (with ``warn`` False, the caller warns once the command line is checked:
    :func:`warn_renamed`). Giving both is an error (exit 2)."""
    if old_value is None:
        return new_value
    if new_value is not None:
        fail(f"{old} and {new} are the same option; give only {new}")
    if warn:
        warn_renamed(old, new)
    return old_value


def warn_renamed(old: str, new: str) -> None:
    """The one-line warning that ``old`` is now spelled ``new``."""
    console.print(f"[yellow]warning:[/] {old} is deprecated; use {new}", highlight=False, soft_wrap=True)


def renamed_value(value, default, old_value, old: str, new: str, warn: bool = True):
    """The value of an option that has a default and an old spelling (:func:`renamed_option`): ``value``,
    or the old spelling's with a one-line warning when only that was given (``warn``, as
    :func:`prefer_new` takes it); both given (``value`` other than ``default``) is an error."""
    chosen = prefer_new(None if value == default else value, old_value, old, new, warn)
    return default if chosen is None else chosen
