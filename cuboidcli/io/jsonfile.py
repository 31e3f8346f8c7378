"""Reading a JSON file, with errors that name the file."""

from __future__ import annotations

import json
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
