"""Helpers shared by several test modules (import them as ``from helpers import ...``)."""

from __future__ import annotations

import numpy as np

from jaxproj.human.skeleton import J

# MSR Action3D row (1-based) of each joint, copied from the dataset notes' table; deliberately not
# derived from readers.MSR_TO_SDK, so that the conversion is checked against an independent source.
MSR_ROW: dict[str, int] = {
    "ShoulderLeft": 1, "ShoulderRight": 2, "ShoulderCenter": 3, "Spine": 4, "HipLeft": 5,
    "HipRight": 6, "HipCenter": 7, "ElbowLeft": 8, "ElbowRight": 9, "WristLeft": 10,
    "WristRight": 11, "HandLeft": 12, "HandRight": 13, "KneeLeft": 14, "KneeRight": 15,
    "AnkleLeft": 16, "AnkleRight": 17, "FootLeft": 18, "FootRight": 19, "Head": 20,
}  # fmt: skip


def msr_text(sdk: np.ndarray, confidence: float | np.ndarray = 0.5, newline: str = "\n") -> str:
    """An MSR Action3D ``*_skeleton3D.txt`` file: 20 rows ``x y z c`` per frame, in MSR row order.

    Args:
      sdk: ``(T, 20, 3)`` positions in Kinect SDK joint order (``skeleton.JOINT_NAMES``).
      confidence: the fourth column, a scalar or ``(T, 20)`` in SDK order.
      newline: the line terminator (every line ends with it).

    Returns:
      The text, every value with 6 decimals as in the dataset's files.
    """
    sdk = np.asarray(sdk, dtype=np.float64)
    rows = np.zeros((len(sdk), 20, 4))
    rows[..., :3] = sdk
    rows[..., 3] = confidence
    msr = np.zeros_like(rows)
    for name, row in MSR_ROW.items():
        msr[:, row - 1] = rows[:, J[name]]
    return "".join(" ".join(f"{v:.6f}" for v in r) + newline for r in msr.reshape(-1, 4))


def small_projector():
    """A whole-body ``Projector`` on 200 distinct training descriptors of subjects 1 and 3 (seed
    0) and their IK poses, with the kernel settings the streaming and oracle tests' float32
    tolerances were measured with (the whole-body defaults; the tuned per-chain defaults, hidden
    192 and ridge 1e-4, round differently)."""
    from jaxproj.io import datasets
    from jaxproj.projection import api as engine
    from jaxproj.robots.nao_h25 import ik

    kernels = engine.BuildConfig(chains="whole", k=96, hidden=96, lam=1e-3, input_scale=0.5)
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3]))
    uniq = np.unique(train, axis=0)
    idx = np.sort(np.random.default_rng(0).choice(len(uniq), 200, replace=False))
    human = uniq[idx].astype(np.float32)
    robot_poses = np.asarray(ik.solve_driven(human), np.float32)
    return engine.build_from_landmarks(human, robot_poses, kernels)


def clip_driven_np(q: np.ndarray) -> np.ndarray:
    """``(..., 10)`` NAO driven angles clipped as the pipeline documents it, in NumPy: to the
    joint limits, then HeadPitch into the head envelope at HeadYaw (``robot.HEAD_ENVELOPE_*``)."""
    from jaxproj.robots.nao_h25 import robot

    q = np.clip(np.asarray(q, np.float64), robot.LOWER[robot.DRIVEN_INDEX],
                robot.UPPER[robot.DRIVEN_INDEX])  # fmt: skip
    env = (robot.HEAD_ENVELOPE_PITCH_MIN, robot.HEAD_ENVELOPE_PITCH_MAX)
    bounds = [np.interp(q[..., 0], robot.HEAD_ENVELOPE_YAW, b) for b in env]
    q[..., 1] = np.clip(q[..., 1], *bounds)
    return q


# A standing person in Kinect v1 camera space (metres, y up, facing the camera, the performer's
# left at smaller x), our own numbers of adult proportions: upper arm 0.27 m, forearm 0.23,
# thigh 0.42, shin 0.41, trunk (HipCenter -> ShoulderCenter) 0.50.
PERSON: dict[str, tuple[float, float, float]] = {
    "HipCenter": (0.0, 0.0, 2.5), "Spine": (0.0, 0.25, 2.5), "ShoulderCenter": (0.0, 0.5, 2.5),
    "Head": (0.0, 0.7, 2.5),
    "ShoulderLeft": (-0.18, 0.45, 2.5), "ElbowLeft": (-0.21, 0.18, 2.5),
    "WristLeft": (-0.23, -0.05, 2.48), "HandLeft": (-0.24, -0.12, 2.47),
    "ShoulderRight": (0.18, 0.45, 2.5), "ElbowRight": (0.21, 0.18, 2.5),
    "WristRight": (0.23, -0.05, 2.48), "HandRight": (0.24, -0.12, 2.47),
    "HipLeft": (-0.09, -0.05, 2.5), "KneeLeft": (-0.1, -0.47, 2.5),
    "AnkleLeft": (-0.1, -0.88, 2.52), "FootLeft": (-0.1, -0.92, 2.42),
    "HipRight": (0.09, -0.05, 2.5), "KneeRight": (0.1, -0.47, 2.5),
    "AnkleRight": (0.1, -0.88, 2.52), "FootRight": (0.1, -0.92, 2.42),
}  # fmt: skip


def person_motion(n_frames: int = 7, seed: int = 0, jitter: float = 0.02) -> np.ndarray:
    """``(T, 20, 3)`` float64 Kinect v1 positions: ``PERSON`` with each joint moved by up to
    ``jitter`` m per frame, rounded to 6 decimals (exactly representable in every format)."""
    from jaxproj.human.skeleton import JOINT_NAMES

    base = np.array([PERSON[n] for n in JOINT_NAMES])
    rng = np.random.default_rng(seed)
    return np.round(base + rng.uniform(-jitter, jitter, size=(n_frames, 20, 3)), 6)


def person_joints(skeleton: str, n_frames: int = 2, seed: int = 0) -> np.ndarray:
    """``(T, len(sensor_joints), 3)`` joints of a registered skeleton holding ``person_motion``:
    each joint Kinect v1 takes a position from sits at that position; every other joint a few
    centimetres from its parent (the skeleton's own axes are not applied: MediaPipe's y-down
    landmarks come out upside down, which changes no bone length)."""
    from jaxproj.human import skeletons

    s = skeletons.get(skeleton)
    kin = person_motion(n_frames, seed)
    out = np.full((n_frames, len(s.joints), 3), np.nan)
    for i, j in enumerate(s.kinect_v1_sources):
        if j >= 0:
            out[:, j] = kin[:, i]
    rng = np.random.default_rng(seed + 1)
    while np.isnan(out[0, :, 0]).any():
        for j in np.flatnonzero(np.isnan(out[0, :, 0])):
            p = s.parents[j]
            if p < 0:
                out[:, j] = kin[:, 0]
            elif not np.isnan(out[0, p, 0]):
                out[:, j] = out[:, p] + rng.uniform(-0.03, 0.03, size=3)
    return out[:, : len(s.sensor_joints)]
