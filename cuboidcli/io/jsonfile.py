"""Reading a JSON file, with errors that name the file, and warnings about the keys a reader does not
know (a misspelled optional key would otherwise be dropped without a word)."""

from __future__ import annotations

import difflib
import json
import warnings
from pathlib import Path


def read_json(
    path: Path,
    error: type[Exception],
    invalid: str,
    missing: str | None = None,
    missing_error: type[Exception] | None = None,
):
    """The parsed contents of the JSON file ``path``.

    Text that is not JSON raises ``error`` with the message ``invalid``, a format string over ``path`` and
    the decoder's error ``e`` (``{e.msg}``, ``{e.lineno}``...); so does a file that is not UTF-8 text (a
    binary file), with ``e.msg`` saying so and ``e.lineno`` the line of the first bad byte. With
    ``missing`` given, a missing file raises ``missing_error`` (default: ``error``) with that message, a
    format string over ``path``.
    """
    if missing is not None and not path.is_file():
        raise (missing_error or error)(missing.format(path=path))
    raw = path.read_bytes()
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as u:
        before = raw[: u.start].decode("utf-8", errors="replace")
        e = json.JSONDecodeError(f"not UTF-8 text (byte 0x{raw[u.start]:02x})", before, len(before))
        raise error(invalid.format(path=path, e=e)) from u
    except json.JSONDecodeError as e:
        raise error(invalid.format(path=path, e=e)) from e


def unknown_keys(d: dict, known) -> list[str]:
    """A line for each key of ``d`` that is not one of ``known`` (nor a "_comment"), naming the known key
    it is probably a misspelling of."""
    lines = []
    for key in d:
        if key in known or str(key).startswith("_"):
            continue
        close = difflib.get_close_matches(str(key), [k for k in known if k not in d], 1, 0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        lines.append(f"unknown key {key!r}{hint}; ignored")
    return lines


def misspelled(key: str, d: dict) -> str:
    """``; found 'centre', a misspelling?`` when ``d`` has a key close to the missing ``key``."""
    close = difflib.get_close_matches(key, [str(k) for k in d], 1, 0.6)
    return f"; found {close[0]!r}, a misspelling?" if close else ""


_WARNED: set[tuple[str, str]] = set()


def warn_once(path: Path, lines, category: type[Warning]) -> None:
    """Warn (``category``) each of ``lines`` about the file ``path`` once per process: a folder's frames
    read the same intrinsics file, each a result's keys."""
    for line in lines:
        if (str(path), line) not in _WARNED:
            _WARNED.add((str(path), line))
            warnings.warn(f"{path}: {line}", category, stacklevel=3)
