"""The README stays short and its examples run as written.

The Python example is the README's one fenced ``python`` block: read a recording, build a small
projector, retarget, save a motion. It runs as written, in a temporary folder, and the motion
file it writes must load with one ``(26,)`` pose per recorded frame. The command-line example
(the fenced ``bash`` block that runs ``jaxproj retarget``) then runs there line by line, each
line through ``jaxproj.cli.main`` (the ``jaxproj`` console script's entry point, in this process
so that it compiles no program twice), on the ``recording.npz`` the Python block wrote.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import jaxproj
from jaxproj.cli import main
from jaxproj.io import datasets
from jaxproj.robots.nao_h25 import robot

README = Path(__file__).resolve().parents[2] / "README.md"
MAX_LINES = 150
"""The README's length limit (issue 28): what, install, the two commands, the example, links."""

FENCE = re.compile(r"^```python\n(.*?)^```$", re.DOTALL | re.MULTILINE)
BASH_FENCE = re.compile(r"^```bash\n(.*?)^```$", re.DOTALL | re.MULTILINE)


def python_blocks(text: str) -> list[str]:
    """The sources of the fenced ``python`` blocks of a Markdown text, in order."""
    return FENCE.findall(text)


def cli_commands(text: str) -> list[list[str]]:
    """The README's command-line example: the argument lists of the ``bash`` block that runs
    ``jaxproj retarget``, one per line, comments dropped."""
    (block,) = [b for b in BASH_FENCE.findall(text) if "jaxproj retarget" in b]
    return [shlex.split(line, comments=True) for line in block.splitlines() if line.strip()]


def test_readme_is_short() -> None:
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, f"README.md has {n} lines (at most {MAX_LINES}: move detail to docs/)"


def test_readme_has_one_short_python_example() -> None:
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) == 1, f"README.md should hold one python block, found {len(blocks)}"
    code_lines = [line for line in blocks[0].splitlines() if line.strip()]
    assert len(code_lines) <= 10, f"the example has {len(code_lines)} lines (at most 10)"


@pytest.fixture(scope="module")
def readme_folder(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A folder where the README's Python block ran, as written (and the current folder while
    the module's tests run)."""
    (code,) = python_blocks(README.read_text(encoding="utf-8"))
    folder = tmp_path_factory.mktemp("readme")
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(folder)
        exec(compile(code, "README.md", "exec"), {"__name__": "readme_example"})
        yield folder


def test_readme_example_runs(readme_folder: Path) -> None:
    # the example retargets the first bundled take of subject 2, action 1, and saves it
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    n_frames = seq.positions.shape[0]
    path = readme_folder / "motion.npz"
    assert path.is_file()
    motion = jaxproj.load_motion(path)
    assert motion.angles.shape == (n_frames, 26)
    assert motion.angles.dtype == np.float32
    assert motion.times.shape == (n_frames,)
    np.testing.assert_allclose(np.diff(motion.times), 1 / 15, rtol=1e-5)  # MSR Action3D's rate
    np.testing.assert_array_equal(motion.valid, seq.valid)
    # angles are real robot poses: finite and within the joint limits
    lower, upper = robot.LOWER, robot.UPPER
    assert np.all(np.isfinite(motion.angles))
    assert np.all((motion.angles >= lower) & (motion.angles <= upper))
    # and they moved: the recorded arm motion is not a held pose
    assert np.ptp(motion.angles[motion.valid], axis=0).max() > 0.1


def test_readme_cli_example_runs(readme_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    commands = cli_commands(README.read_text(encoding="utf-8"))
    assert 0 < len(commands) <= 6, "keep the README's command-line example short"
    for argv in commands:
        assert argv[0] == "jaxproj", f"the command-line example runs jaxproj only, not {argv[0]}"
        assert main(argv[1:]) == 0, f"README.md: `{shlex.join(argv)}` failed"
    out = capsys.readouterr().out

    n_frames = datasets.msr_action3d(subjects=[2], actions=[1])[0].positions.shape[0]
    assert f"recording.npz: {n_frames} frames ({n_frames} valid" in out
    # the small model's confidence is on its own scale: a held-out person's recording reads as
    # like the people it was built from, not as 100 % low-confidence (its cut-off is its own)
    low = [line for line in out.splitlines() if "low-confidence frames" in line]
    assert low and all("this recording is like the people the model was built from" in x
                       for x in low), low  # fmt: skip
    # the NPZ motion carries the human, so the video draws the human and the NAO side by side
    with np.load(readme_folder / "nao.npz") as f:
        assert f["angles"].shape == (n_frames, 26) and f["positions"].shape == (n_frames, 20, 3)
    with Image.open(readme_folder / "nao.gif") as gif:
        two_panels = gif.size
    assert jaxproj.load_motion(readme_folder / "nao.json").angles.shape == (n_frames, 26)
    # what the README says of a JSON motion: no human in it, so one panel, the NAO's
    assert main(["render", "nao.json", "--out", "nao_alone.gif", "--stride", str(n_frames)]) == 0
    with Image.open(readme_folder / "nao_alone.gif") as gif:
        one_panel = gif.size
    assert two_panels == (2 * one_panel[0], one_panel[1])
