"""Execute the notebooks top to bottom and store their outputs.

    python notebooks/execute.py [--fast] [--out DIR] [--timeout S] [NAME ...]

Without ``--fast`` (the full settings) each notebook is executed in a fresh kernel of this Python
and written back in place with its outputs: the committed notebooks come from this command. With
``--fast`` (``JAXPROJ_FAST=1``, the tests' settings) the executed copies go to ``--out`` (default:
a new temporary folder) and the notebooks themselves are left as they are. ``NAME`` selects
notebooks by file name or prefix (``01``, ``02_paper_experiments``); default: all of them.

Each executed notebook records in its metadata (``metadata.jaxproj``) the run mode, the wall
time, the ``jaxproj`` version it ran and a hash of its code cells (``source_sha256``);
``tests/integration/test_notebooks.py`` uses the hash to tell whether the code was edited after
the run and the version to tell whether the outputs belong to the current release. Running this
script in full mode is part of cutting a release (``docs/development.md``), not of every commit.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NOTEBOOKS = sorted(HERE.glob("[0-9][0-9]_*.ipynb"))
"""The notebooks, in order."""

KERNEL = "python3"
"""The kernel: jupyter_client starts kernel specs whose command is ``python`` with this very
interpreter (``sys.executable``), so the notebooks run in the environment that runs this script."""


def source_sha256(nb) -> str:
    """SHA-256 of the notebook's code cells (their sources, in order)."""
    h = hashlib.sha256()
    for cell in nb.cells:
        if cell.cell_type == "code":
            src = cell.source if isinstance(cell.source, str) else "".join(cell.source)
            h.update(src.encode() + b"\0")
    return h.hexdigest()


def execute(path: Path, *, fast: bool, timeout: int = 1200, env: dict[str, str] | None = None):
    """Run ``path`` top to bottom in a fresh kernel; returns the executed notebook (nbformat).

    The kernel runs in the notebook's folder with this process's environment, ``JAXPROJ_FAST``
    set to ``1`` (``fast``) or removed, plus ``env``. A cell that raises stops the run with
    ``nbclient.exceptions.CellExecutionError`` (its traceback in the message).
    """
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    saved = {k: os.environ.get(k) for k in ("JAXPROJ_FAST", *(env or {}))}
    os.environ.pop("JAXPROJ_FAST", None)
    if fast:
        os.environ["JAXPROJ_FAST"] = "1"
    os.environ.update(env or {})
    t0 = time.perf_counter()
    try:
        client = NotebookClient(
            nb,
            kernel_name=KERNEL,
            timeout=timeout,
            resources={"metadata": {"path": str(path.parent)}},
            record_timing=False,  # no timestamps in the stored cells: smaller, quieter diffs
            # the kernel's own log (e.g. that it talks to us over local TCP) is not the notebook's
            extra_arguments=["--IPKernelApp.log_level=ERROR"],
        )
        client.execute()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    import jaxproj

    nb.metadata["jaxproj"] = {
        "mode": "fast" if fast else "full",
        "version": jaxproj.__version__,
        "wall_s": round(time.perf_counter() - t0, 1),
        "source_sha256": source_sha256(nb),
    }
    return nb


def select(names: list[str]) -> list[Path]:
    """The notebooks whose file names start with one of ``names`` (all for none)."""
    if not names:
        return list(NOTEBOOKS)
    chosen = [p for p in NOTEBOOKS if any(p.name.startswith(n) for n in names)]
    missing = [n for n in names if not any(p.name.startswith(n) for p in NOTEBOOKS)]
    if missing:
        raise SystemExit(f"execute.py: no notebook matches {missing}; have "
                         f"{[p.name for p in NOTEBOOKS]}")  # fmt: skip
    return chosen


def main(argv: list[str] | None = None) -> int:
    import nbformat

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help="notebook names or prefixes (default: all)")
    ap.add_argument("--fast", action="store_true", help="JAXPROJ_FAST=1; do not write in place")
    ap.add_argument("--out", type=Path, help="write the executed notebooks here instead")
    ap.add_argument("--timeout", type=int, default=1200, help="seconds per cell (default 1200)")
    args = ap.parse_args(argv)
    out = args.out
    if out is None and args.fast:
        out = Path(tempfile.mkdtemp(prefix="jaxproj-notebooks-"))
    total = time.perf_counter()
    for path in select(args.names):
        print(f"{path.name}: executing ({'fast' if args.fast else 'full'} mode) ...", flush=True)
        nb = execute(path, fast=args.fast, timeout=args.timeout)
        dest = path if out is None else out / path.name
        dest.parent.mkdir(parents=True, exist_ok=True)
        nbformat.write(nb, dest)
        size = dest.stat().st_size / 1e6
        print(f"{path.name}: {nb.metadata['jaxproj']['wall_s']:.0f} s, {size:.2f} MB -> {dest}",
              flush=True)  # fmt: skip
    print(f"all done in {time.perf_counter() - total:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
