"""Text helpers shared by the skeleton file formats: bytes -> text -> numeric tables.

Every format module (``jaxproj.io.formats``) reads its file with ``read_bytes`` and ``decode``
and turns rows of tokens into float64 tables with ``to_table`` (``whitespace_table`` for the
whitespace-separated Kinect text formats); each raises ``jaxproj.errors.InputError`` with a
one-line message naming the file, the 1-based line (and column) and the problem. Text is parsed in
bulk: one vectorised float conversion for the whole file, and for ASCII text the columns per line
are counted with byte operations (no Python loop per line); a 1000-frame MSR file reads in about
10-20 ms.

``Head`` is what format detection (``jaxproj.io.registry.detect``) looks at: the start of a file
(or all of it), its name and its first non-blank line.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxproj.errors import InputError

SNIFF_BYTES = 1 << 16
"""How much of a file in a folder detection reads (its first complete lines decide)."""


def one_line(err: BaseException) -> str:
    """``"TypeName: message"`` of an exception, on one line."""
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def read_bytes(path: str | os.PathLike[str]) -> bytes:
    """The file's bytes.

    Raises:
      InputError: missing file, a directory, unreadable or empty (0 bytes).
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, "is a directory, not a file") from None
    except OSError as err:
        raise InputError(path, f"cannot read file ({one_line(err)})") from None
    if not data:
        raise InputError(path, "file is empty (0 bytes)")
    return data


def decode(path: str | os.PathLike[str], data: bytes) -> str:
    """UTF-8 text of the file (a byte-order mark is dropped).

    Raises:
      InputError: not UTF-8 (names the byte and its offset) or only whitespace.
    """
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(
            path, f"not a text file (byte 0x{data[err.start]:02x} at offset {err.start})"
        ) from None
    if not text.strip():
        raise InputError(path, "file is empty (only whitespace)")
    return text


def is_number(token: str) -> bool:
    """Can numpy convert ``token`` to a float64?"""
    try:
        np.array(token, dtype=np.float64)
    except ValueError:
        return False
    return True


def is_number_row(line: str | None, n_columns: int) -> bool:
    """Is ``line`` a row of ``n_columns`` whitespace-separated numbers? One field may be no
    number (a damaged row of a recording is still recognised: its reader names the token)."""
    if line is None or "," in line:
        return False
    fields = line.split()
    return len(fields) == n_columns and sum(not is_number(f) for f in fields) <= 1


def _first_bad_token(tokens: list[str]) -> int:
    """Index of the first token numpy cannot convert to float (searched in chunks)."""
    step = 1024
    for lo in range(0, len(tokens), step):
        try:
            np.array(tokens[lo : lo + step], dtype=np.float64)
        except ValueError:
            for i in range(lo, min(lo + step, len(tokens))):
                try:
                    np.array(tokens[i], dtype=np.float64)
                except ValueError:
                    return i
    raise AssertionError("unreachable: no bad token found")  # pragma: no cover


def to_table(
    path: str | os.PathLike[str], tokens: list[str], line_numbers: np.ndarray, n_columns: int
) -> np.ndarray:
    """``(n_rows, n_columns)`` float64 from row-major tokens of rows with ``n_columns`` each.

    Args:
      path: the file (named in errors).
      tokens: ``n_rows * n_columns`` tokens, row by row.
      line_numbers: ``(n_rows,)`` 1-based line of each row (named in errors).
      n_columns: tokens per row.

    Raises:
      InputError: a non-numeric token (names its line, column and text).
    """
    try:
        flat = np.array(tokens, dtype=np.float64)
    except ValueError:
        i = _first_bad_token(tokens)
        line, column = line_numbers[i // n_columns], i % n_columns + 1
        raise InputError(
            path, f"line {line}, column {column}: non-numeric token {tokens[i]!r}"
        ) from None
    return flat.reshape(-1, n_columns)


def check_counts(
    path: str | os.PathLike[str],
    counts: np.ndarray,
    line_numbers: np.ndarray,
    n_columns: int,
    what: str,
) -> None:
    """``InputError`` unless there is a row and every row has ``n_columns`` tokens.

    Args:
      path: the file (named in errors).
      counts: ``(n_rows,)`` tokens per row.
      line_numbers: ``(n_rows,)`` 1-based line of each row.
      n_columns: the expected count.
      what: the format's row layout, in words (e.g. ``"CSV: x,y,z for 20 joints"``).
    """
    if counts.size == 0:
        raise InputError(path, "file has no data rows")
    bad = np.flatnonzero(counts != n_columns)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            path,
            f"line {line_numbers[i]}: found {counts[i]} columns, expected {n_columns} ({what})",
        )


_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 28, 29, 30, 31, 32]] = True  # ASCII whitespace of str.split()


def whitespace_table(
    path: str | os.PathLike[str], text: str, n_columns: int, what: str
) -> tuple[np.ndarray, np.ndarray]:
    """Whitespace-separated text -> (``(n_rows, n_columns)`` float64, ``(n_rows,)`` 1-based lines).

    Blank lines are skipped. For ASCII text the columns per line are counted with vectorised byte
    operations (no Python loop per line); other text falls back to a per-line split.

    Raises:
      InputError: no rows, a row with another number of columns, a non-numeric token.
    """
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    if text.isascii():
        tokens = text.split()
        b = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
        ws = _WHITESPACE[b]
        starts = ~ws
        starts[1:] &= ws[:-1]
        line_of_byte = np.cumsum(b == 10)
        token_line = line_of_byte[starts]
        assert token_line.size == len(tokens)
        counts = np.bincount(token_line, minlength=int(line_of_byte[-1]) + 1)
        lines = np.flatnonzero(counts)
        counts, lines = counts[lines], lines + 1
    else:  # str.split() also splits at non-ASCII whitespace: split line by line
        per_line = [line.split() for line in text.split("\n")]
        lines = np.array([i for i, f in enumerate(per_line, start=1) if f], dtype=np.int64)
        counts = np.array([len(f) for f in per_line if f], dtype=np.int64)
        tokens = [t for f in per_line for t in f]
    check_counts(path, counts, lines, n_columns, what)
    return to_table(path, tokens, lines, n_columns), lines


@dataclass(frozen=True)
class Head:
    """The start of a file, as format detection sees it.

    Attributes:
      path: the file.
      data: its first bytes (``SNIFF_BYTES``), or all of them.
      complete: ``data`` is the whole file (its last line is complete). Lines are looked for in
        the first ``SNIFF_BYTES`` only, either way.
    """

    path: Path
    data: bytes
    complete: bool

    @property
    def suffix(self) -> str:
        """The file name's extension, lower case (``".csv"``; ``""`` when none)."""
        return self.path.suffix.lower()

    @functools.cached_property
    def _lines(self) -> tuple[list[str], str]:
        """(the first two non-blank complete lines, stripped; why there is none)."""
        data = self.data
        if not self.complete or len(data) > SNIFF_BYTES:  # only complete lines count
            data = data[:SNIFF_BYTES]
            cut = max(data.rfind(b"\n"), data.rfind(b"\r"))
            data = data[: cut + 1] if cut >= 0 else b""
        text = data.decode("utf-8-sig", errors="replace")
        found = []
        for line in text.splitlines():
            if line.strip():
                found.append(line.strip())
                if len(found) == 2:
                    break
        if not found:
            return [], "no text line to recognise (blank or binary)"
        if "\ufffd" in found[0]:
            return [], "not a text file"
        return found, ""

    @property
    def first_line(self) -> str | None:
        """The first non-blank line, stripped (``None``: no text line, see ``problem``)."""
        lines, _ = self._lines
        return lines[0] if lines else None

    @property
    def second_line(self) -> str | None:
        """The second non-blank line, stripped (``None`` when there is none)."""
        lines, _ = self._lines
        return lines[1] if len(lines) > 1 and "\ufffd" not in lines[1] else None

    @property
    def problem(self) -> str:
        """Why there is no ``first_line`` (``""`` when there is one)."""
        return self._lines[1]
