"""Atomic file writes: write a temporary file beside the target, then ``os.replace`` it.

A write that fails half-way (full disk, an exception in the encoder, Ctrl-C) never leaves a
half-written target, nor its temporary file: the target keeps its previous content (or stays
absent).
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable
from pathlib import Path

from jaxproj.errors import InputError


def _temp_path(path: Path) -> Path:
    """Create (exclusively) and return an empty hidden file beside ``path``, same extension.

    Opened with mode 0o666 so the process umask applies (``tempfile.mkstemp`` would give 0o600,
    which ``os.replace`` would then carry over to the target).
    """
    while True:
        tmp = path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp


def atomic_write(path: str | os.PathLike[str], write: Callable[[Path], None]) -> Path:
    """Write ``path`` atomically.

    Args:
      path: the target file; its folder is created if missing.
      write: called with the path of a fresh temporary file in the same folder, with the same
        extension (encoders such as ffmpeg pick the format from it); it writes the whole content
        there (replacing the empty file).

    Returns:
      ``path`` as a ``Path``.

    Raises:
      InputError: an ``OSError`` while creating the folder, writing or renaming ("cannot write
        ..."). Any other exception of ``write`` propagates unchanged. In both cases the temporary
        file is removed and the target is left as it was.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = _temp_path(path)
    except OSError as e:
        raise InputError(path, f"cannot write: {e.strerror or e}") from None
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(e, OSError):
            raise InputError(path, f"cannot write: {e.strerror or e}") from None
        raise
    return path
