"""The ``Skeleton`` spec and registry (``jaxproj.human.skeletons``), and the descriptor computed
from a skeleton's joints: Kinect v1 bit-identical to the hard-coded Kinect implementation it
replaced, another joint order giving the same canonical layout, clear errors."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.human import skeleton, skeletons
from jaxproj.human.skeletons import (
    BONE_MEANINGS,
    BONE_NAMES,
    KINECT_V1,
    MIRROR_BONE,
    BodyFrame,
    Skeleton,
)
from jaxproj.io import datasets

# ---- the hard-coded Kinect v1 implementation before the Skeleton spec (frozen copy) ----------

OLD_JOINTS = (
    "HipCenter", "Spine", "ShoulderCenter", "Head",
    "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft",
    "ShoulderRight", "ElbowRight", "WristRight", "HandRight",
    "HipLeft", "KneeLeft", "AnkleLeft", "FootLeft",
    "HipRight", "KneeRight", "AnkleRight", "FootRight",
)  # fmt: skip
OLD_J = {n: i for i, n in enumerate(OLD_JOINTS)}
OLD_BONES = (
    ("HipCenter", "Spine"), ("Spine", "ShoulderCenter"), ("ShoulderCenter", "Head"),
    ("ShoulderCenter", "ShoulderLeft"), ("ShoulderLeft", "ElbowLeft"),
    ("ElbowLeft", "WristLeft"), ("WristLeft", "HandLeft"),
    ("ShoulderCenter", "ShoulderRight"), ("ShoulderRight", "ElbowRight"),
    ("ElbowRight", "WristRight"), ("WristRight", "HandRight"),
    ("HipCenter", "HipLeft"), ("HipLeft", "KneeLeft"), ("KneeLeft", "AnkleLeft"),
    ("AnkleLeft", "FootLeft"),
    ("HipCenter", "HipRight"), ("HipRight", "KneeRight"), ("KneeRight", "AnkleRight"),
    ("AnkleRight", "FootRight"),
)  # fmt: skip
OLD_BONE_NAMES = (
    "spine_lower", "spine_upper", "neck",
    "clavicle_left", "upper_arm_left", "forearm_left", "hand_left",
    "clavicle_right", "upper_arm_right", "forearm_right", "hand_right",
    "pelvis_left", "thigh_left", "shin_left", "foot_left",
    "pelvis_right", "thigh_right", "shin_right", "foot_right",
)  # fmt: skip


def _old_unit(v):
    n = jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True))
    ok = (n >= 1e-3) & jnp.isfinite(n)
    safe = jnp.where(ok, n, 1.0)
    return jnp.where(ok, v / safe, 0.0), ok[..., 0]


def _old_body_frame(p):
    up_raw = p[..., OLD_J["ShoulderCenter"], :] - p[..., OLD_J["HipCenter"], :]
    left_raw = p[..., OLD_J["ShoulderLeft"], :] - p[..., OLD_J["ShoulderRight"], :]
    up, ok_up = _old_unit(up_raw)
    left_orth = left_raw - jnp.sum(left_raw * up, axis=-1, keepdims=True) * up
    left, ok_left = _old_unit(left_orth)
    forward = jnp.cross(left, up)
    rot = jnp.stack([forward, left, up], axis=-2)
    ok = ok_up & ok_left & jnp.all(jnp.isfinite(p), axis=(-2, -1))
    eye = jnp.broadcast_to(jnp.eye(3, dtype=rot.dtype), rot.shape)
    return jnp.where(ok[..., None, None], rot, eye), ok


def _old_descriptor(positions, index, mirror):
    parents = np.array([OLD_J[OLD_BONES[i][0]] for i in index])
    children = np.array([OLD_J[OLD_BONES[i][1]] for i in index])
    p = jnp.asarray(positions, dtype=jnp.float32)
    finite = jnp.all(jnp.isfinite(p), axis=(-2, -1))
    p = jnp.where(finite[..., None, None], p, 0.0)
    rot, ok_frame = _old_body_frame(p)
    unit, ok_bone = _old_unit(p[..., children, :] - p[..., parents, :])
    local = jnp.einsum("...ij,...bj->...bi", rot, unit)
    if mirror:
        local = local.at[..., 1].multiply(-1.0)
    valid = ok_frame & finite & jnp.all(ok_bone, axis=-1)
    local = jnp.where(valid[..., None, None], local, 0.0)
    return local.reshape(*local.shape[:-2], 3 * len(index)), valid


_old_descriptor_jit = jax.jit(_old_descriptor, static_argnames=("index", "mirror"))
_old_body_frame_jit = jax.jit(_old_body_frame)


@pytest.fixture(scope="module")
def frames() -> jax.Array:
    """(N, 20, 3) bundled frames, valid and not, plus a zero-length bone, a NaN and a lost one."""
    seqs = datasets.msr_action3d(subjects=[1], actions=[1, 10])
    p = np.concatenate([s.positions for s in seqs]).astype(np.float32)
    bad = p[:3].copy()
    bad[0, OLD_J["ElbowLeft"]] = bad[0, OLD_J["ShoulderLeft"]]
    bad[1, OLD_J["WristLeft"], 0] = np.nan
    bad[2] = 0.0
    return jnp.asarray(np.concatenate([p, bad]))


def test_kinect_v1_descriptor_is_bit_identical_to_the_hard_coded_one(frames):
    some = ("neck", "pelvis_left", "foot_right", "clavicle_left")
    for bones, mirror in [("full", False), (some, True)]:
        names = skeleton.resolve_bones(bones)
        if mirror:  # the old swap
            names = tuple(
                n.replace("_left", "_T").replace("_right", "_left").replace("_T", "_right")
                for n in names
            )
        index = tuple(OLD_BONE_NAMES.index(n) for n in names)
        d0, ok0 = _old_descriptor_jit(frames, index=index, mirror=mirror)
        for kw in ({}, {"skeleton": "kinect_v1"}, {"skeleton": KINECT_V1}):  # one compile
            d, ok = skeleton.descriptor(frames, bones, mirror, **kw)
            np.testing.assert_array_equal(np.asarray(d), np.asarray(d0))
            np.testing.assert_array_equal(np.asarray(ok), np.asarray(ok0))
    rot0, ok0 = _old_body_frame_jit(frames)
    rot, ok = jax.jit(skeleton.body_frame)(frames)
    np.testing.assert_array_equal(np.asarray(rot), np.asarray(rot0))
    np.testing.assert_array_equal(np.asarray(ok), np.asarray(ok0))


def test_kinect_v1_module_values_are_the_old_constants():
    assert skeleton.JOINT_NAMES == OLD_JOINTS and skeleton.J == OLD_J
    assert skeleton.N_JOINTS == 20 and skeleton.BONES == OLD_BONES
    assert skeleton.BONE_NAMES == OLD_BONE_NAMES == BONE_NAMES
    assert skeleton.FULL_BODY == OLD_BONE_NAMES
    assert skeleton.UPPER_BODY == (
        "neck", "upper_arm_left", "forearm_left", "upper_arm_right", "forearm_right"
    )  # fmt: skip
    # every Kinect bone is an edge parent -> child of its joint tree
    for a, b in KINECT_V1.bones.values():
        assert KINECT_V1.parents[KINECT_V1.index[b]] == KINECT_V1.index[a]
    assert tuple(KINECT_V1.bones) == BONE_NAMES  # stored in canonical order
    assert set(BONE_MEANINGS) == set(BONE_NAMES)
    assert all(MIRROR_BONE[MIRROR_BONE[b]] == b for b in BONE_NAMES)


def test_registry():
    assert "kinect_v1" in skeletons.names()
    assert skeletons.get() is KINECT_V1 and skeletons.get("kinect_v1") is KINECT_V1
    assert skeletons.get(KINECT_V1) is KINECT_V1
    with pytest.raises(ConfigError, match=r"unknown skeleton 'kinect_v9'; registered: .*kinect_v1"):
        skeletons.get("kinect_v9")
    assert skeletons.register(KINECT_V1) is KINECT_V1  # the same spec again: a no-op
    other = _reordered(name="kinect_v1")
    with pytest.raises(ConfigError, match="a different skeleton is registered as 'kinect_v1'"):
        skeletons.register(other)
    assert skeletons.get("kinect_v1") is KINECT_V1
    with pytest.raises(ConfigError, match="register takes a Skeleton"):
        skeletons.register("kinect_v1")  # type: ignore[arg-type]


def test_register_and_use_a_new_skeleton(monkeypatch):
    monkeypatch.setattr(skeletons, "_REGISTRY", dict(skeletons._REGISTRY))
    s = skeletons.register(_reordered())
    assert skeletons.names()[-1] == "kinect_reordered" and skeletons.get("kinect_reordered") is s
    replacement = _reordered(description="other")  # description is not part of the spec
    assert replacement == s and hash(replacement) == hash(s)
    skeletons.register(replacement)


def _reordered(name: str = "kinect_reordered", hands: bool = True, **kw) -> Skeleton:
    """Kinect v1 with its joints reversed and renamed (``k_<name>``); hands optional."""
    order = OLD_JOINTS[::-1]
    up = {n: KINECT_V1.parents[OLD_J[n]] for n in order}
    parents = tuple(-1 if up[n] < 0 else order.index(OLD_JOINTS[up[n]]) for n in order)
    bones = {
        b: (f"k_{a}", f"k_{c}")
        for b, (a, c) in KINECT_V1.bones.items()
        if hands or not b.startswith("hand")
    }
    frame = (("k_HipCenter", "k_ShoulderCenter"), ("k_ShoulderRight", "k_ShoulderLeft"))
    return Skeleton(name, tuple(f"k_{n}" for n in order), parents, bones, frame, **kw)


def test_another_joint_order_gives_the_same_canonical_descriptor(frames):
    s = _reordered(hands=False)
    p = np.asarray(frames)[:, ::-1]  # the reversed joint order
    assert s.frame == BodyFrame(("k_HipCenter", "k_ShoulderCenter"), s.frame.left)
    bones = tuple(b for b in BONE_NAMES if not b.startswith("hand"))
    d0, ok0 = skeleton.descriptor(frames, bones, True)  # mirrored: the twins swap too
    d1, ok1 = skeleton.descriptor(jnp.asarray(p), bones, True, skeleton=s)  # not registered
    np.testing.assert_allclose(np.asarray(d1), np.asarray(d0), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(ok1), np.asarray(ok0))
    kept = datasets.valid_descriptors(p, bones=bones, mirror=True, skeleton=s)
    np.testing.assert_allclose(kept, np.asarray(d0)[np.asarray(ok0)], rtol=0, atol=1e-6)
    with pytest.raises(ConfigError, match=r"\(T, 20, 3\) positions"):
        datasets.valid_descriptors(p[:, :19], skeleton=s)
    rot0, _ = jax.jit(skeleton.body_frame)(frames)
    rot1, _ = jax.jit(lambda x: skeleton.body_frame(x, skeleton=s))(jnp.asarray(p))
    np.testing.assert_allclose(np.asarray(rot1), np.asarray(rot0), rtol=0, atol=1e-6)
    # a bone this skeleton lacks: named with the skeleton, before anything is traced
    with pytest.raises(ConfigError, match="'kinect_reordered' has no bone.*hand_left, hand_right"):
        skeleton.descriptor(p, "full", skeleton=s)
    with pytest.raises(ConfigError, match=r"\(\.\.\., 20, 3\) \(kinect_reordered joints\)"):
        skeleton.descriptor(p[:, :19], "upper", skeleton=s)
    with pytest.raises(ConfigError, match=r"\(\.\.\., 20, 3\)"):
        skeleton.body_frame(jnp.asarray(p[:, :19]), skeleton=s)
    d = np.zeros((4, 54), np.float32)
    with pytest.raises(ConfigError, match="has no bone"):
        skeleton.level_neck(d, 0.0, "full", skeleton=s)
    with pytest.raises(ConfigError, match="no neck bone"):
        skeleton.neck_tilt(d[:, :6], ("thigh_left", "thigh_right"), skeleton=s)
    assert skeleton.neck_tilt(d, bones, skeleton=s).shape == (4,)
    assert skeleton.level_neck(d, 0.1, bones, skeleton=s).shape == d.shape


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"name": "Kinect"}, "lower case"),
        ({"name": "kinect v1"}, "letters, digits and _"),
        ({"joints": ("a", "a")}, "repeat"),
        ({"parents": (-1, 0)}, "2 parents for 20 joints"),
        ({"parents": (-1,) * 20}, "one root joint"),
        ({"parents": (1, 0) + (0,) * 18}, "no valid parent|one root"),
        ({"parents": (-1, 2, 1) + (0,) * 17}, "form a cycle"),
        ({"parents": (-1, 20) + (0,) * 18}, "no valid parent"),
        ({"bones": {"neck": ("ShoulderCenter", "Head"), "tail": ("Spine", "Head")}}, "tail"),
        ({"bones": {"thigh_left": ("HipLeft", "KneeLeft")}}, "without their other side"),
        ({"bones": {"neck": ("ShoulderCenter", "Nose")}}, "unknown joint"),
        ({"bones": {"neck": ("Head", "Head")}}, "to itself"),
        ({"bones": {"neck": "Head"}}, r"\(from, to\) pair"),
        ({"bones": {}}, "mapping canonical bone"),
        ({"frame": (("HipCenter", "Neck"), ("ShoulderRight", "ShoulderLeft"))}, "frame up"),
        ({"frame": {"up": ("HipCenter", "Head")}}, "BodyFrame"),
    ],
)
def test_bad_specs_are_config_errors(change, match):
    spec = {
        "name": "k",
        "joints": KINECT_V1.joints,
        "parents": KINECT_V1.parents,
        "bones": dict(KINECT_V1.bones),
        "frame": KINECT_V1.frame,
    }
    spec.update(change)
    with pytest.raises(ConfigError, match=match):
        Skeleton(**spec)


def test_frame_as_a_dict_and_bones_as_a_read_only_mapping():
    s = Skeleton(
        "k", KINECT_V1.joints, KINECT_V1.parents, dict(KINECT_V1.bones),
        {"up": ("HipCenter", "ShoulderCenter"), "left": ("ShoulderRight", "ShoulderLeft")},
    )  # fmt: skip
    assert s == KINECT_V1.__class__(**{**_fields(KINECT_V1), "name": "k"})
    assert s.bones == dict(KINECT_V1.bones) and s.bones["neck"] == ("ShoulderCenter", "Head")
    with pytest.raises(TypeError):
        s.bones["neck"] = ("Spine", "Head")  # type: ignore[index]
    assert s.missing("full") == () and s.bone_joints(("neck",)) == ((2, 3),)


def _fields(s: Skeleton) -> dict:
    return {k: getattr(s, k) for k in ("name", "joints", "parents", "bones", "frame")}
