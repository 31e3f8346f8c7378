"""What a setting allows, in one form for every setting: :class:`Check`, its constructors (:func:`whole`,
:func:`number`, :func:`choice`, :func:`text`, :func:`path`) and the checks of the settings that say how an
input is read (:data:`LOAD_CHECKS`).

A value that is not allowed gets one line naming the setting and what it allows: ``hypotheses must be a
whole number from 1 to 100000 (got nan)``. The estimator's settings are checked by
:data:`cuboidcli.fitting.config.CHECKS`; the Python API and the command line (with the flag as the name,
``cuboidcli/cli/option_table.py``) give the same words.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from numbers import Integral, Real

import numpy as np

from cuboidcli.camera import PRESETS as CAMERAS
from cuboidcli.fitting.parts import or_list
from cuboidcli.io.scan import UNITS

#: Kinds of value a check allows.
KINDS = ("int", "float", "bool", "choice", "text", "path", "vector")


@dataclass(frozen=True)
class Check:
    """What one setting allows, and the one-line message when a value is not allowed.

    The message's ``{name}`` is the setting, or the flag that set it; ``{value}`` the value (text quoted);
    ``{range}`` the allowed values in words; ``{choices}`` the names allowed as "a, b or c", ``{listed}``
    as "a, b, c". ``kind`` is what the value must be (:data:`KINDS`): a whole number (no bool, no
    fraction), a number (finite: NaN and inf are never a setting), a switch, one of ``choices``, text or a
    path (never empty) or a vector; ``low``/``high`` bound a number (``open_low``/``open_high``: the bound
    itself excluded) and ``ok`` says whatever else the value must satisfy."""

    message: str
    choices: tuple[str, ...] = ()
    ok: Callable[[object], bool] | None = None
    kind: str = "choice"
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    range: str = ""
    """The allowed values in words (``a whole number from 1 to 100000``), for the message and the table
    of options."""

    def allows(self, value, choices: tuple[str, ...] | None = None) -> bool:
        """Whether ``value`` is allowed (None, a setting's "not set", always is). ``choices`` narrows the
        names allowed (a command that offers fewer parts)."""
        if value is None:
            return True
        if self.kind == "choice":
            return value in (self.choices if choices is None else choices)
        if self.kind == "bool":
            return isinstance(value, bool | np.bool_)
        if self.kind in ("int", "float"):
            return self._in_range(value)
        if self.kind in ("text", "path") and not str(value).strip():
            return False
        try:
            return bool(self.ok is None or self.ok(value))
        except (TypeError, ValueError, ArithmeticError):
            return False

    def _in_range(self, value) -> bool:
        whole = self.kind == "int"
        if isinstance(value, bool | np.bool_) or not isinstance(value, Integral if whole else Real):
            return False
        if not whole and not math.isfinite(value):
            return False
        if self.low is not None and (value <= self.low if self.open_low else value < self.low):
            return False
        if self.high is not None and (value >= self.high if self.open_high else value > self.high):
            return False
        return self.ok is None or bool(self.ok(value))

    def error(self, name: str, value, choices: tuple[str, ...] | None = None) -> str | None:
        """The message for ``value``, or None when it is allowed (:meth:`allows`)."""
        if self.allows(value, choices):
            return None
        allowed = self.choices if choices is None else choices
        shown = repr(value) if isinstance(value, str) and not _is_number(value) else value
        return self.message.format(
            name=name, value=shown, range=self.range, choices=or_list(allowed), listed=", ".join(allowed)
        )


RANGE_MESSAGE = "{name} must be {range} (got {value})"


def _is_number(text: str) -> bool:
    """Whether ``text`` reads as a number (shown as it is in a message; other text is quoted)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def whole(low: int, high: int, *, ok: Callable[[object], bool] | None = None, also: str = "") -> Check:
    """A whole number from ``low`` to ``high`` (and that ``ok`` accepts, ``also`` saying how): every count
    has a bound, so that a huge value is refused before it runs out of memory or time."""
    words = f"a whole number from {low} to {high}" + (f", {also}" if also else "")
    return Check(RANGE_MESSAGE, kind="int", low=low, high=high, ok=ok, range=words)


def number(
    low: float | None = None,
    high: float | None = None,
    *,
    open_low: bool = False,
    open_high: bool = False,
    unit: str = "",
    ok: Callable[[object], bool] | None = None,
) -> Check:
    """A finite number within the bounds given (``open_*``: the bound excluded), in ``unit`` ("m")."""
    bounds = []
    if low is not None and high is not None and not open_low and not open_high:
        bounds.append(f"from {low:g} to {high:g}")
    else:
        if low is not None:
            bounds.append(f"{'>' if open_low else '>='} {low:g}")
        if high is not None:
            bounds.append(f"{'<' if open_high else '<='} {high:g}")
    words = f"a number {' and '.join(bounds)}" if bounds else "a finite number"
    return Check(
        RANGE_MESSAGE, kind="float", low=low, high=high, open_low=open_low, open_high=open_high,
        range=f"{words} {unit}".strip(), ok=ok,
    )  # fmt: skip


def choice(names, message: str = "{name} {value}: choose {choices}") -> Check:
    """One of ``names``."""
    names = tuple(names)
    return Check(message, names, kind="choice", range=f"one of {', '.join(names)}")


def text(words: str, ok: Callable[[object], bool] | None = None) -> Check:
    """Text (never empty) that ``ok`` accepts; ``words`` says what it must be."""
    return Check(RANGE_MESSAGE, kind="text", ok=ok, range=words)


def path(words: str = "a path (not empty)") -> Check:
    """A path: never empty (an empty path is the current folder, never what was meant)."""
    return Check(RANGE_MESSAGE, kind="path", range=words)


def vector(words: str, ok: Callable[[object], bool]) -> Check:
    """A tuple of numbers that ``ok`` accepts."""
    return Check(RANGE_MESSAGE, kind="vector", ok=ok, range=words)


def switch() -> Check:
    """True or False (not a truthy string)."""
    return Check(RANGE_MESSAGE, kind="bool", range="True or False")


def check_all(checks: dict[str, Check], values: dict) -> None:
    """Raise a one-line ValueError for the first of ``values`` (by name) its check in ``checks`` refuses."""
    for name, value in values.items():
        check = checks.get(name)
        error = None if check is None else check.error(name, value)
        if error is not None:
            raise ValueError(error)


#: Where a network runs, as every command's ``--device`` and the Python API's ``device=`` take it.
DEVICE = choice(("auto", "cpu", "cuda"))
#: A file or folder given by name.
PATH = path()

#: Largest depth-PNG unit in metres (a metre per unit: nothing finer could be stored in it).
MAX_DEPTH_SCALE = 1.0
#: Largest relative-depth scale and shift, and camera height (metres): far beyond any indoor scene.
MAX_METRES = 1000.0

#: How an input is read (the fields of :class:`cuboidcli.load.LoadOptions` and of a depth model's
#: :class:`cuboidcli.factories.DepthModelOptions`): the checks the Python API runs on them, and the
#: command line on the options that set them.
LOAD_CHECKS: dict[str, Check] = {
    "camera": choice(CAMERAS),
    "depth_scale": number(0, MAX_DEPTH_SCALE, open_low=True, unit="m per unit"),
    "unit": choice(UNITS),
    "every": whole(1, 100_000),
    "scale": number(0, MAX_METRES, open_low=True),
    "shift": number(-MAX_METRES, MAX_METRES),
    "camera_height_m": number(0, 100, open_low=True, unit="m"),
    "kind": choice(("metric", "relative", "relative-inverse")),
}
