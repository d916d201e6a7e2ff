"""Atomic file writes: write a temporary file beside the target, then ``os.replace`` it.

A write that fails half-way (full disk, an exception in the encoder, Ctrl-C) never leaves a
half-written target, nor its temporary file: the target keeps its previous content (or stays
absent).

No writer creates a folder: a target whose folder is missing (or is not a folder) is a
``ConfigError`` naming the path and the folder (``missing_folder``), the same rule and wording
as the CLI's output options (``jaxproj.cli.options.output_path``): a typo such as
``/nope/x.json`` must not create ``/nope``.

No writer replaces a file it was told not to (``check_output``): every writer of the Python API
takes ``overwrite`` (default ``True``, as numpy's savers; the CLI passes ``--force``, default
off), and an output that is one of the writer's inputs (same file by ``os.path.samefile``, or the
same resolved path) is refused whatever ``overwrite`` says.

``write_npz`` is the package's one NPZ writer (model files, motion files, the bundled datasets):
atomic, and deterministic — the same arrays give the same bytes (fixed zip timestamps and
permissions, no pickles).
"""

from __future__ import annotations

import contextlib
import io
import os
import secrets
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from jaxproj.errors import ConfigError, InputError


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


FOLDER_RULE = "jaxproj creates no folder for an output file: create it first"
"""Why a missing folder is an error, in the words of every such message."""


def missing_folder(path: str | os.PathLike[str]) -> str | None:
    """What is wrong with the folder of the output file ``path`` (``"folder F does not exist
    (...)"``, ``"F is not a folder"``), or ``None`` when it is an existing folder."""
    folder = Path(path).parent
    if folder.is_dir():
        return None
    if folder.exists():
        return f"{folder} is not a folder"
    return f"folder {folder} does not exist ({FOLDER_RULE})"


def check_folder(path: str | os.PathLike[str]) -> Path:
    """``path`` as a ``Path`` if its folder exists, else ``ConfigError`` naming both."""
    problem = missing_folder(path)
    if problem is not None:
        raise ConfigError(f"{path}: {problem}")
    return Path(path)


OVERWRITE_FIX = "pass overwrite=True (Python) / --force (CLI) to replace it"
"""What to do about an existing output, in the words of every refusal."""


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether ``a`` and ``b`` name one file: ``os.path.samefile`` where both exist (hard and
    symbolic links included), else the same resolved path (two outputs not written yet)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
        return Path(a).resolve() == Path(b).resolve()
    except (OSError, RuntimeError):  # unreadable, or a symlink loop: not provably the same
        return False


def output_problem(
    path: str | os.PathLike[str],
    overwrite: bool,
    inputs: Mapping[str, str | os.PathLike[str] | None] | None = None,
    fix: str = OVERWRITE_FIX,
) -> str | None:
    """What forbids writing the output file ``path``, or ``None``: a missing folder
    (``missing_folder``), one of ``inputs`` (what -> path, e.g. ``{"the recording": p}``;
    ``None`` entries skipped; refused even with ``overwrite``), an existing folder, or an
    existing file when ``overwrite`` is false (``"exists; " + fix``)."""
    problem = missing_folder(path)
    if problem is not None:
        return problem
    for what, other in (inputs or {}).items():
        if other is not None and same_file(path, other):
            return (
                f"is {what} too: write the output to another file (an input is never "
                "replaced, not even with overwrite=True / --force)"
            )
    if os.path.isdir(path):
        return "is a folder: name an output file"
    if not overwrite and os.path.lexists(path):
        return f"exists; {fix}"
    return None


def check_output(
    path: str | os.PathLike[str],
    *,
    overwrite: bool = True,
    inputs: Mapping[str, str | os.PathLike[str] | None] | None = None,
) -> Path:
    """``path`` as a ``Path`` if a writer may write it (``output_problem``), else
    ``ConfigError`` naming it: ``"P: exists; pass overwrite=True (Python) / --force (CLI) to
    replace it"``, ``"P: is the recording too: ..."``, a missing folder. Writers call it before
    any work."""
    problem = output_problem(path, overwrite, inputs)
    if problem is not None:
        raise ConfigError(f"{path}: {problem}")
    return Path(path)


def atomic_write(
    path: str | os.PathLike[str], write: Callable[[Path], None], *, overwrite: bool = True
) -> Path:
    """Write ``path`` atomically.

    Args:
      path: the target file; its folder must exist (``check_folder``: none is created).
      write: called with the path of a fresh temporary file in the same folder, with the same
        extension (encoders such as ffmpeg pick the format from it); it writes the whole content
        there (replacing the empty file).
      overwrite: replace an existing ``path`` (default); ``False``: ``ConfigError`` if it
        exists (``check_output``, checked again here, after ``write``'s caller did its work).

    Returns:
      ``path`` as a ``Path``.

    Raises:
      ConfigError: the folder of ``path`` does not exist or is not a folder (nothing is
        created); ``path`` exists and ``overwrite`` is false.
      InputError: an ``OSError`` while writing or renaming ("cannot write ..."). Any other
        exception of ``write`` propagates unchanged. In both cases the temporary file is
        removed and the target is left as it was.
    """
    path = check_output(path, overwrite=overwrite)
    try:
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


ZIP_DATE = (1980, 1, 1, 0, 0, 0)
"""Timestamp of every member of an NPZ written by ``write_npz`` (the zip format's earliest)."""


def _npz_member(key: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(f"{key}.npy", date_time=ZIP_DATE)
    info.external_attr = 0o644 << 16
    return info


def _write_npz_file(path: Path, arrays: Mapping[str, np.ndarray], compress: bool) -> None:
    if not compress:
        with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for key, value in arrays.items():
                with zf.open(_npz_member(key), "w", force_zip64=True) as fh:
                    np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)
        return
    with zipfile.ZipFile(path, "w") as zf:
        for key, value in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(value), allow_pickle=False)
            info = _npz_member(key)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, buf.getvalue(), compresslevel=9)


def write_npz(
    path: str | os.PathLike[str],
    arrays: Mapping[str, np.ndarray],
    *,
    compress: bool = False,
    overwrite: bool = True,
) -> Path:
    """Write ``arrays`` as an NPZ archive (``np.load`` reads it), atomically and deterministically.

    Args:
      path: the target file (``atomic_write``: its folder must exist).
      arrays: member name (without ``.npy``) -> array, written in this order; no object arrays.
      compress: deflate each member (level 9) like ``np.savez_compressed``; default stored, like
        ``np.savez``.
      overwrite: replace an existing file (default), else ``ConfigError`` (``atomic_write``).

    Returns:
      ``path`` as a ``Path``.

    Raises:
      ConfigError: the folder of ``path`` does not exist, or ``path`` exists and ``overwrite``
        is false (``atomic_write``).
      InputError: the file cannot be written (``atomic_write``).
    """
    return atomic_write(
        path, lambda tmp: _write_npz_file(tmp, arrays, compress), overwrite=overwrite
    )
