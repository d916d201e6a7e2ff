"""``Format``: what a skeleton file format module registers (``jaxproj.io.formats.FORMATS``).

A format is a name, a one-line description, the file-name suffixes that say it, a ``sniff`` that
recognises a file from its start (``jaxproj.io.text.Head``) and a ``read`` that turns the file's
bytes into a ``Recording``. Adding an input format is one module under ``jaxproj/io/formats/``
that defines such a record, and one line in the ``FORMATS`` table.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from jaxproj.io.recording import Recording
from jaxproj.io.text import Head


class ReadFn(Protocol):
    """``read(path, data, fps, **options) -> Recording``.

    ``data`` is the whole file, ``fps`` the caller's rate (already checked, or ``None``);
    ``options`` are the keyword options of ``read_skeleton`` (``bvh_map``, ``scale``, ``body``),
    each format using its own and ignoring the others. Raises ``InputError`` for a bad file.
    """

    def __call__(
        self, path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any
    ) -> Recording: ...


@dataclass(frozen=True)
class Format:
    """One skeleton file format.

    Attributes:
      name: the ``format=`` / ``--format`` value (``"msr"``).
      description: one line, for help texts and errors.
      suffixes: lower-case file-name suffixes that name the format (``(".csv",)``; ``()``: the
        name says nothing, e.g. ``.txt``). A file with such a name that ``sniff`` does not
        recognise is still read as this format when it is named on its own (its reader then
        says what is wrong); in a folder it is skipped.
      sniff: ``sniff(head) -> (recognised, why_not)``; ``why_not`` is ``""`` or, when the file
        nearly is one (its suffix or its first line says so), what is wrong, in words.
      read: the reader (``ReadFn``).
      first_line: ``(phrase, unit)`` describing this format's first line in the message for a
        text file that no format recognises (``("4 (MSR Action3D)", "numbers")``; phrases of one
        unit are joined with ``or``); ``None`` for binary formats.
    """

    name: str
    description: str
    suffixes: tuple[str, ...]
    sniff: Callable[[Head], tuple[bool, str]]
    read: ReadFn
    first_line: tuple[str, str] | None = None
