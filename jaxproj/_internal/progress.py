"""Progress bars for long work (build, evaluate, demo, rollout): one ``tqdm`` bar, on stderr.

A bar shows only where asked for (``enabled``) and only when stderr is a terminal (tqdm's
``disable=None``): logs, pipes and tests stay quiet.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TypeVar

from tqdm import tqdm

T = TypeVar("T")


def bar(
    items: Iterable[T], desc: str, *, enabled: bool = True, total: int | None = None
) -> Iterator[T]:
    """Iterate ``items`` behind a progress bar labelled ``desc`` (see the module doc)."""
    return iter(tqdm(items, desc=desc, total=total, disable=None if enabled else True, leave=False))
