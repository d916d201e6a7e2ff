"""Environment variables set for a while and put back as they were (absent ones removed)."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping


def saved_environ(keys: Iterable[str]) -> dict[str, str | None]:
    """``{key: value or None}`` of ``keys`` now, for ``restore_environ``."""
    return {k: os.environ.get(k) for k in keys}


def restore_environ(saved: Mapping[str, str | None]) -> None:
    """Put each variable of ``saved`` back: its value, or removed where it was absent."""
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
