"""The same motion in every skeleton layout (``tests/data/formats/same_motion``, made by
``benchmarks/experiments/skeleton_layouts.py --write``; its ``SOURCE.md`` and the script's
``LAYOUT_MAPS`` say how each layout's joints were made from the CMU joints).

Each file reads as its layout, and the descriptor of its Kinect v1 layout (``read_skeleton``'s
positions; ``jaxproj.human.skeleton.descriptor``, all 19 bones) matches the Kinect v1 reference's
bone by bone: to the files' rounding where the layout's joints are the reference's CMU joints,
and within what the joint map's other choices allow where they are not (SMPL's head, MediaPipe's
spine and feet). One descriptor compile; no robot, no model.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from jaxproj.human import skeletons
from jaxproj.human.skeleton import descriptor
from jaxproj.human.skeletons import BONE_NAMES
from jaxproj.io.formats.bvh import CMU_SCALE, parse_bvh
from jaxproj.io.readers import read_skeleton

DATA = Path(__file__).resolve().parents[1] / "data"
FOLDER = DATA / "formats" / "same_motion"
CLIPS = {"131_01": 40, "131_03": 100}
"""Clip -> first frame of the excerpt in ``tests/data/cmu_bvh/<clip>_every6.bvh`` (20 fps)."""
STEP, FRAMES, FPS = 2, 30, 10.0
"""Every 2nd frame of the 20 fps file, 30 of them: 3 s at 10 fps."""

FILES = {
    "kinect_v1": ("csv", "csv"),
    "kinect_v2": ("skeleton", "ntu"),
    "azure_kinect": ("json", "azure_kinect"),
    "smpl": ("npz", "npz"),
    "smplx": ("npz", "npz"),
    "mediapipe_pose": ("json", "mediapipe"),
}
"""Layout -> (file suffix, the format ``read_skeleton`` detects)."""
TIMED = {"azure_kinect", "smpl", "smplx"}
"""The files that carry their rate (``timestamp_usec``, ``fps``); the others are read at 10 fps."""

TIGHT_DEG = 0.05
"""Bones made of the reference's own CMU joints. The files round positions to 10 um (5 decimals
of a metre, 0.01 mm) or store float32; on the shortest bone (the hand, 0.037 m) that moves a
direction by at most ~2 * sqrt(3) * 5e-6 / 0.037 rad = 0.027 deg."""

SMPL_HEAD_DROP_M = 0.05
"""SMPL's head joint (the skull's base): this far below CMU ``Head`` along the head's up axis
(the script's ``SMPL_MAP``)."""


def _read(clip: str, layout: str, fps: float | None = FPS):
    suffix, _ = FILES[layout]
    return read_skeleton(FOLDER / f"{clip}.{layout}.{suffix}", fps=fps)


def _bones(positions: np.ndarray) -> np.ndarray:
    """``(T, 20, 3)`` Kinect v1 positions -> ``(T, 19, 3)`` float64 unit bones, body frame."""
    d, ok = descriptor(np.asarray(positions, np.float32), "full")
    assert np.asarray(ok).all()
    return np.asarray(d, np.float64).reshape(len(positions), len(BONE_NAMES), 3)


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between unit vectors (``atan2(|a x b|, a . b)``: exact near 0)."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, -1)))


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    """Clip -> the Kinect v1 reference's bones."""
    return {c: _bones(_read(c, "kinect_v1").positions) for c in CLIPS}


@pytest.mark.parametrize("layout", list(FILES))
@pytest.mark.parametrize("clip", list(CLIPS))
def test_each_file_reads_as_its_layout(clip: str, layout: str) -> None:
    rec = _read(clip, layout, fps=None)
    assert (rec.format, rec.skeleton) == (FILES[layout][1], layout)
    assert rec.positions.shape == (FRAMES, 20, 3) and rec.valid.all()
    if layout in TIMED:  # the file's own rate
        np.testing.assert_allclose(np.diff(rec.times), 1.0 / FPS, rtol=1e-6)


def test_the_reference_is_the_bvh_readers_cmu_map(reference: dict[str, np.ndarray]) -> None:
    """The CSV is ``read_skeleton(bvh, bvh_map="cmu")`` on the same frames (other axes)."""
    for clip, first in CLIPS.items():
        bvh = read_skeleton(DATA / "cmu_bvh" / f"{clip}_every6.bvh", bvh_map="cmu")
        frames = bvh.positions[first : first + STEP * FRAMES : STEP]
        assert _angles(_bones(frames), reference[clip]).max() < TIGHT_DEG


@pytest.mark.parametrize("layout", ["kinect_v2", "azure_kinect", "smpl", "smplx"])
def test_bones_at_the_same_joints_match_the_reference(
    layout: str, reference: dict[str, np.ndarray]
) -> None:
    """Kinect v2, Azure Kinect, SMPL and SMPL-X put every bone they define (SMPL-X: no hands)
    and their body frame at the reference's CMU joints, but SMPL's neck (next test)."""
    s = skeletons.get(layout)
    same = [BONE_NAMES.index(b) for b in s.bones if not (layout.startswith("smpl") and b == "neck")]
    assert len(same) == len(s.bones) - layout.startswith("smpl")
    for clip in CLIPS:
        err = _angles(_bones(_read(clip, layout).positions), reference[clip])[:, same]
        assert err.max() < TIGHT_DEG, (clip, BONE_NAMES[same[int(err.max(0).argmax())]])


@pytest.mark.parametrize("layout", ["smpl", "smplx"])
def test_smpl_neck_ends_at_the_skulls_base(layout: str, reference: dict[str, np.ndarray]) -> None:
    """The neck bone runs to a point ``SMPL_HEAD_DROP_M`` from the reference's head end: it turns
    by at most asin(drop / neck length) (the CMU ``Neck -> Head`` offset, 0.090 m), and it does
    turn where the head tilts on the neck (median of a few degrees in these clips)."""
    clip = parse_bvh(DATA / "cmu_bvh" / "131_01_every6.bvh")
    neck_m = np.linalg.norm(clip.offsets[clip.index("Head")]) * CMU_SCALE
    bound = math.degrees(math.asin(SMPL_HEAD_DROP_M / neck_m))  # 33.6 deg
    neck = BONE_NAMES.index("neck")
    err = np.concatenate(
        [_angles(_bones(_read(c, layout).positions), reference[c])[:, neck] for c in CLIPS]
    )
    assert err.max() < bound
    assert 1.0 < np.median(err) < 10.0


def _mediapipe_choices(reference_positions: np.ndarray) -> np.ndarray:
    """The reference with MediaPipe's joint choices made from its own joints: the pelvis centre
    midway between the hip joints, the spine top midway between the shoulders, the spine middle
    midway between those (``layouts.MEDIAPIPE_POSE.derived``)."""
    k = skeletons.get("kinect_v1").index
    p = np.asarray(reference_positions, np.float64).copy()
    p[:, k["HipCenter"]] = 0.5 * (p[:, k["HipLeft"]] + p[:, k["HipRight"]])
    p[:, k["ShoulderCenter"]] = 0.5 * (p[:, k["ShoulderLeft"]] + p[:, k["ShoulderRight"]])
    p[:, k["Spine"]] = 0.5 * (p[:, k["HipCenter"]] + p[:, k["ShoulderCenter"]])
    return p


def test_mediapipe_bones_are_the_references_under_its_joint_choices() -> None:
    """MediaPipe's head centre (mid ears) is CMU ``Head`` and its hands (mid index and pinky
    knuckles) CMU ``Fingers``, the reference's joints; its pelvis centre and spine are means of
    the reference's hips and shoulders: every bone but the feet matches the reference with
    those means, to the rounding. The foot ends at the toes' tip (``Toe_End``), the reference's
    at the ball (``Toe``): the bone turns by at most asin(|Toe -> Toe_End| / |Ankle -> Toe|)
    per side (CMU offsets; ~30 deg), and does turn."""
    bvh = parse_bvh(DATA / "cmu_bvh" / "131_01_every6.bvh")
    for clip in CLIPS:
        want = _bones(_mediapipe_choices(_read(clip, "kinect_v1").positions))
        err = _angles(_bones(_read(clip, "mediapipe_pose").positions), want)
        for i, b in enumerate(BONE_NAMES):
            if not b.startswith("foot"):
                assert err[:, i].max() < TIGHT_DEG, (clip, b)
                continue
            side = "Left" if b.endswith("left") else "Right"
            toe = np.linalg.norm(bvh.offsets[bvh.index(f"{side}Toe")])
            tip = np.linalg.norm(bvh.offsets[bvh.index(f"{side}Toe_End")])
            assert err[:, i].max() < math.degrees(math.asin(tip / toe)), (clip, b)
            assert np.median(err[:, i]) > 1.0, (clip, b)


def test_mediapipe_differs_from_the_reference_through_its_spine(
    reference: dict[str, np.ndarray],
) -> None:
    """Against the reference itself MediaPipe's body frame is tilted (its up axis from the hips'
    midpoint, ~0.09 m below CMU ``Hips``): its pelvis bones run along the hip line (~55 deg from
    the reference's, which drop from ``Hips`` to the hip joints) and every other bone turns by the
    tilt, a few degrees (the measured table: ``docs/results.md``)."""
    err = np.concatenate(
        [_angles(_bones(_read(c, "mediapipe_pose").positions), reference[c]) for c in CLIPS]
    )
    med = dict(zip(BONE_NAMES, np.median(err, axis=0), strict=True))
    assert 45.0 < med["pelvis_left"] < 65.0 and 45.0 < med["pelvis_right"] < 65.0
    assert all(1.0 < med[b] < 15.0 for b in BONE_NAMES if not b.startswith("pelvis"))
