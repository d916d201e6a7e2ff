import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import (
    BONE_NAMES,
    BONE_TILT_REFERENCES,
    BONES,
    FULL_BODY,
    JOINT_NAMES,
    UPPER_BODY,
    J,
    body_frame,
    descriptor,
    level_body,
    world_up,
)
from jaxproj.io import datasets


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    """(N, 20, 3) valid real frames from several bundled sequences."""
    seqs = datasets.msr_action3d(subjects=[1, 2], actions=[1, 5, 10, 19])
    return np.concatenate([s.positions[s.valid] for s in seqs])


def _rot_y(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=np.float64)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def test_tree_is_the_kinect_v1_tree():
    assert len(BONES) == 19 and len(BONE_NAMES) == 19
    children = [c for _, c in BONES]
    # every joint but the root is the child of exactly one bone
    assert sorted(children) == sorted(n for n in JOINT_NAMES if n != "HipCenter")


@pytest.mark.parametrize("bones", ["upper", "full"])
def test_unit_norm_on_real_frames(frames, bones):
    d, ok = descriptor(frames, bones=bones)
    d, ok = np.asarray(d), np.asarray(ok)
    assert ok.all()
    n_b = len(UPPER_BODY) if bones == "upper" else len(FULL_BODY)
    norms = np.linalg.norm(d.reshape(len(d), n_b, 3), axis=-1)
    np.testing.assert_allclose(norms, 1.0, atol=1e-5)


def test_invariant_to_translation_vertical_rotation_and_scale(frames):
    rng = np.random.default_rng(0)
    d0, _ = descriptor(frames, bones="full")
    for _ in range(5):
        rot = _rot_y(rng.uniform(-np.pi, np.pi))  # Kinect camera y is vertical
        moved = (frames.astype(np.float64) @ rot.T) * rng.uniform(0.5, 2.0)
        moved = moved + rng.normal(size=3) * 2.0
        d1, ok = descriptor(moved.astype(np.float32), bones="full")
        assert np.asarray(ok).all()
        np.testing.assert_allclose(np.asarray(d1), np.asarray(d0), atol=2e-5)
    # the frame is built from the skeleton, so any rotation leaves the descriptor unchanged
    rot = _random_rotation(rng)
    d2, _ = descriptor((frames.astype(np.float64) @ rot.T).astype(np.float32), bones="full")
    np.testing.assert_allclose(np.asarray(d2), np.asarray(d0), atol=2e-5)


def test_body_frame_is_right_handed_and_forward_faces_the_camera(frames):
    rot, ok = body_frame(frames)
    rot = np.asarray(rot)
    assert np.asarray(ok).all()
    np.testing.assert_allclose(
        rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-5
    )
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-5)
    # MSR Action3D: the sensor looks along +z at people facing it -> forward has negative z
    assert np.mean(rot[:, 0, 2] < 0) > 0.95


def test_arms_hang_down_in_a_rest_frame(frames):
    d, _ = descriptor(frames[:1], bones="upper")
    v = np.asarray(d)[0].reshape(5, 3)
    assert v[0, 2] > 0.8  # neck points up
    assert v[1, 2] < -0.5 and v[3, 2] < -0.5  # upper arms point down (first frame = rest)


def test_zero_length_bone_or_nonfinite_frame_is_invalid_never_nan(frames):
    bad = np.repeat(frames[:1], 5, axis=0).copy()
    bad[0, J["ElbowLeft"]] = bad[0, J["ShoulderLeft"]]  # zero-length upper arm
    bad[1, J["WristRight"], 0] = np.nan
    bad[2, J["Head"], 1] = np.inf
    bad[3] = 0.0  # lost tracking
    d, ok = descriptor(bad)
    d, ok = np.asarray(d), np.asarray(ok)
    assert ok.tolist() == [False, False, False, False, True]
    assert np.isfinite(d).all()
    assert (d[:4] == 0).all()
    # a zero-length bone outside the chosen subset does not invalidate the frame
    legs = frames[:1].copy()
    legs[0, J["FootLeft"]] = legs[0, J["AnkleLeft"]]
    assert bool(np.asarray(descriptor(legs, bones="upper")[1])[0])
    assert not bool(np.asarray(descriptor(legs, bones="full")[1])[0])


def test_mirror_equals_descriptor_of_the_reflected_skeleton(frames):
    # Reflect the skeleton through a plane (camera x -> -x) and swap left/right joint labels:
    # that is the mirror image of the person; its direct descriptor must equal `mirror=True`.
    swap = [
        J[n.replace("Left", "_").replace("Right", "Left").replace("_", "Right")]
        for n in JOINT_NAMES
    ]
    reflected = frames[:, swap] * np.array([-1.0, 1.0, 1.0], dtype=np.float32)
    dm, _ = descriptor(frames, bones="full", mirror=True)
    dr, _ = descriptor(reflected, bones="full")
    np.testing.assert_allclose(np.asarray(dm), np.asarray(dr), atol=2e-5)
    assert not np.allclose(np.asarray(dm), np.asarray(descriptor(frames, bones="full")[0]))


def test_bad_subset_is_a_config_error():
    with pytest.raises(ConfigError, match="unknown bone"):
        descriptor(np.zeros((1, 20, 3), np.float32), bones="arms")
    with pytest.raises(ConfigError, match="unknown bone"):
        descriptor(np.zeros((1, 20, 3), np.float32), bones=("neck", "tail"))


def _tilted(d: np.ndarray, angle: float) -> np.ndarray:
    """Every bone of ``(T, 57)`` descriptors turned by ``angle`` about the body's left axis (a
    tracker that puts the trunk axis ``angle`` further back against the limbs)."""
    v = d.reshape(len(d), -1, 3)
    c, s = np.cos(angle), np.sin(angle)
    out = np.stack([c * v[..., 0] + s * v[..., 2], v[..., 1], c * v[..., 2] - s * v[..., 0]], -1)
    return out.reshape(d.shape).astype(np.float32)


def test_level_body_takes_out_a_trackers_trunk_tilt_and_keeps_the_motion(frames):
    """``level_body``: the median shin straight down and each calibrated bone at its
    reference; the same output whatever constant tilt the tracker put between trunk and limbs;
    a frame's deviation from the median kept; upper-body descriptors as they were."""
    d, ok = (np.asarray(a) for a in descriptor(frames, bones="full"))
    out = np.asarray(level_body(d, ok, "full"))
    v = out.reshape(len(out), -1, 3)
    shins = -np.concatenate([v[:, BONE_NAMES.index(f"shin_{s}")] for s in ("left", "right")])
    assert abs(np.degrees(np.median(np.arctan2(shins[:, 0], shins[:, 2])))) < 0.5
    for bone, ref in BONE_TILT_REFERENCES.items():
        b = v[ok, BONE_NAMES.index(bone)]
        assert abs(np.median(np.arctan2(b[:, 0], b[:, 2])) - ref) < 5e-3  # rad
    for angle in (np.radians(17.0), np.radians(-18.0)):
        again = np.asarray(level_body(_tilted(d, angle), ok, "full"))
        assert np.abs(again - out).max() < 2e-3  # a constant tilt is taken out
    assert np.allclose(np.linalg.norm(v, axis=-1), 1.0, atol=1e-5)  # lengths kept
    # legs=False (a whole-body motion): no turn; the calibrated bones still at their references
    kept = np.asarray(level_body(d, ok, "full", legs=False)).reshape(len(d), -1, 3)
    calibrated = [BONE_NAMES.index(b) for b in BONE_TILT_REFERENCES]
    rest = [i for i in range(len(BONE_NAMES)) if i not in calibrated]
    assert np.array_equal(kept[:, rest], d.reshape(len(d), -1, 3)[:, rest])
    for bone, ref in BONE_TILT_REFERENCES.items():
        b = kept[ok, BONE_NAMES.index(bone)]
        assert abs(np.median(np.arctan2(b[:, 0], b[:, 2])) - ref) < 5e-3  # rad
    upper, ok_u = descriptor(frames, bones="upper")
    assert np.array_equal(np.asarray(level_body(upper, ok_u, "upper")), np.asarray(upper))


def test_level_body_with_up_levels_the_feet_against_the_floor(frames):
    """``level_body(up=)``: a person leaning 10 deg further forward in the world (each frame
    turned about its own body-left axis) has the same body-frame descriptors, so against the
    body the levelled feet are the same; against the floor (``world_up``) the feet, flat on it,
    turn 10 deg towards the toes-up side of the body frame; no other bone moves."""
    d, ok = (np.asarray(a) for a in descriptor(frames, bones="full"))
    rot = np.asarray(body_frame(frames)[0], np.float64)  # rows: forward, left, up
    k = rot[:, 1]  # each frame's left axis, camera coordinates
    a = np.radians(10.0)  # forward: up towards forward, a right-hand turn about left
    kx = np.zeros((len(k), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx -= kx.transpose(0, 2, 1)
    turn = np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * kx @ kx  # Rodrigues, per frame
    centre = frames.mean(axis=1, keepdims=True)
    leaning = (np.einsum("tij,tnj->tni", turn, frames - centre) + centre).astype(np.float32)
    d2, ok2 = (np.asarray(x) for x in descriptor(leaning, bones="full"))
    np.testing.assert_allclose(d2, d, atol=2e-5)  # the body frame leans with the person
    up, up2 = np.asarray(world_up(frames)), np.asarray(world_up(leaning))
    tilt = lambda u: np.degrees(np.arctan2(u[..., 0], u[..., 2]))  # noqa: E731
    assert abs(np.median(tilt(up) - tilt(up2)) - 10.0) < 0.1  # up tilts back in the body
    body = np.asarray(level_body(d, ok, "full")).reshape(len(d), -1, 3)
    flat, flat2 = (np.asarray(level_body(d, ok, "full", up=u)).reshape(len(d), -1, 3)
                   for u in (up, up2))  # fmt: skip
    feet = [BONE_NAMES.index(f"foot_{side}") for side in ("left", "right")]
    others = [i for i in range(len(BONE_NAMES)) if i not in feet]
    np.testing.assert_allclose(flat[:, others], body[:, others], atol=1e-6)
    np.testing.assert_allclose(flat2[:, others], body[:, others], atol=1e-6)
    for i in feet:
        change = tilt(flat2[ok, i]) - tilt(flat[ok, i])
        assert np.allclose(change, -10.0, atol=0.1)  # the foot stays flat on the tilted floor
