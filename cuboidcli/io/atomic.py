"""Atomic file writes: write to a temporary file in the target folder, then rename over the target."""

from __future__ import annotations

import errno
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

#: What a full disk, a quota or a folder the user may not write to looks like: the user's to fix, not a bug.
UNWRITABLE = {
    errno.ENOSPC: "no space left on the device (free some space or write elsewhere)",
    errno.EDQUOT: "the disk quota is exceeded (free some space or write elsewhere)",
    errno.EFBIG: "the file is too large for this file system (write elsewhere)",
    errno.EROFS: "the file system is read-only (write elsewhere)",
    errno.EACCES: "permission denied (write elsewhere, or make the folder writable)",
    errno.EPERM: "permission denied (write elsewhere, or make the folder writable)",
}


class OutputError(OSError):
    """An output file could not be written because of where it goes: a read-only or full folder. The
    message is one line that names the file and what to do."""

    def __init__(self, message: str, code: int | None = None) -> None:
        super().__init__(message)
        self.errno = code


def unwritable(path: str | os.PathLike, error: OSError) -> OutputError | None:
    """The :class:`OutputError` for ``error`` raised while writing ``path``, or None for another error."""
    if isinstance(error, OutputError):
        return error
    reason = UNWRITABLE.get(error.errno)
    return None if reason is None else OutputError(f"cannot write {path}: {reason}", error.errno)


def atomic_write(path: str | os.PathLike, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp_path)`` and move the result to ``path`` atomically. Returns ``path``.

    The temporary file keeps the target's suffix so that writers which infer the format from the file
    name (OpenCV, trimesh, open3d) still work. A folder that cannot be written to (read-only, full) raises
    :class:`OutputError` and leaves ``path`` as it was.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    except OSError as e:
        error = unwritable(path, e)
        if error is None:
            raise
        raise error from e
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        write(tmp_path)
        os.chmod(tmp_path, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp_path, path)
    except OSError as e:
        tmp_path.unlink(missing_ok=True)
        error = unwritable(path, e)
        if error is None:
            raise
        raise error from e
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    return atomic_write(path, lambda p: p.write_bytes(data))


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    return atomic_write(path, lambda p: p.write_text(text, encoding="utf-8"))


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    return atomic_write_text(path, json.dumps(obj, indent=2) + "\n")


def atomic_torch_save(obj, path: str | os.PathLike) -> Path:
    """``torch.save`` through a temporary file, so an interrupted run never leaves a truncated checkpoint."""
    import torch

    return atomic_write(path, lambda tmp: torch.save(obj, tmp))
