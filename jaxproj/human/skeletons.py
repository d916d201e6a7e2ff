"""Human skeletons as data: the ``Skeleton`` spec, the canonical bones and a registry by name.

A capture format (Kinect v1, BVH through a joint map, later other sensors and body models) gives
joint positions in its own order. A ``Skeleton`` says what those joints are (``joints``, their
tree ``parents``), which of its joints each **canonical bone** runs between (``bones``) and which
joints span the **body frame** (``frame``). The descriptor (``jaxproj.human.skeleton.descriptor``)
of any registered skeleton's positions is laid out the same way, canonical bone after canonical
bone (``BONE_NAMES`` order), so a model trained on one skeleton's descriptors reads another's.

The canonical vocabulary (``BONE_NAMES``, with ``BONE_MEANINGS``) is fixed: its order is the
descriptor layout every model file depends on. A skeleton defines the bones it can (a format
without hands leaves ``hand_left`` / ``hand_right`` out) and asking it for one it lacks is a
``ConfigError`` naming the skeleton and the missing bones. ``KINECT_V1`` (registered as
``"kinect_v1"``) is the first instance and the default everywhere.

Adding a skeleton: build a ``Skeleton`` with the format's joint names in its array order, pick for
each canonical bone the two joints whose meaning ``BONE_MEANINGS`` gives, name the body frame's
joints (up: pelvis centre -> spine top; left: right shoulder -> left shoulder), and ``register``
it. Construction checks the data and raises ``ConfigError`` on anything inconsistent. The
skeletons of today's capture formats (Kinect v2, Azure Kinect, SMPL, SMPL-X, MediaPipe Pose) are
in ``jaxproj.human.layouts``, registered when ``jaxproj.human`` is imported.

Size: the spec, its checks, the registry and the Kinect v1 layout of any skeleton
(``to_kinect_v1``) are one vocabulary read together; the checks are most of it.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from jaxproj.errors import ConfigError

BONE_NAMES: tuple[str, ...] = (
    "spine_lower", "spine_upper", "neck",
    "clavicle_left", "upper_arm_left", "forearm_left", "hand_left",
    "clavicle_right", "upper_arm_right", "forearm_right", "hand_right",
    "pelvis_left", "thigh_left", "shin_left", "foot_left",
    "pelvis_right", "thigh_right", "shin_right", "foot_right",
)  # fmt: skip
"""The 19 canonical bones, in descriptor order (bone ``i`` fills descriptor numbers ``3i..3i+2``
of a ``"full"`` descriptor). Fixed: model files depend on this order."""

BONE_MEANINGS: dict[str, str] = {
    "spine_lower": "pelvis centre (midway between the hip joints) -> middle of the spine",
    "spine_upper": "middle of the spine -> spine top (base of the neck, between the shoulders)",
    "neck": "spine top -> head (centre of the head)",
    "clavicle_left": "spine top -> left shoulder joint (half the shoulder line)",
    "upper_arm_left": "left shoulder joint -> left elbow",
    "forearm_left": "left elbow -> left wrist",
    "hand_left": "left wrist -> left hand (middle of the hand or the knuckles)",
    "clavicle_right": "spine top -> right shoulder joint (half the shoulder line)",
    "upper_arm_right": "right shoulder joint -> right elbow",
    "forearm_right": "right elbow -> right wrist",
    "hand_right": "right wrist -> right hand (middle of the hand or the knuckles)",
    "pelvis_left": "pelvis centre -> left hip joint (half the hip line)",
    "thigh_left": "left hip joint -> left knee",
    "shin_left": "left knee -> left ankle",
    "foot_left": "left ankle -> left foot (ball of the foot or the toes)",
    "pelvis_right": "pelvis centre -> right hip joint (half the hip line)",
    "thigh_right": "right hip joint -> right knee",
    "shin_right": "right knee -> right ankle",
    "foot_right": "right ankle -> right foot (ball of the foot or the toes)",
}
"""What each canonical bone is, anatomically: which of a new skeleton's joints to pick. Left and
right are the performer's own. Every bone points away from the body's centre."""

BONE_LINES: dict[str, tuple[str, str]] = {
    "shoulder_line": ("clavicle_left", "clavicle_right"),
    "hip_line": ("pelvis_left", "pelvis_right"),
}
"""The two body lines, each read from two canonical bones as ``unit(a - b)`` of their unit
vectors: the direction from the right shoulder (hip) joint to the left one when the two halves
are of equal length (a robot's correspondence can read the hip line this way, ``BonePair.minus``
in ``jaxproj.robots.generic_ik``). No skeleton names them: they follow from the bones."""

MIRROR_BONE: dict[str, str] = {
    n: n.replace("_left", "_TMP").replace("_right", "_left").replace("_TMP", "_right")
    for n in BONE_NAMES
}
"""Canonical bone -> its left / right twin (itself for the spine and neck): mirror imitation."""

UPPER_BODY: tuple[str, ...] = (
    "neck", "upper_arm_left", "forearm_left", "upper_arm_right", "forearm_right",
)  # fmt: skip
"""Default bone subset: what the default robot's head and arms (up to the elbow) can
follow. 15 numbers."""

FULL_BODY: tuple[str, ...] = BONE_NAMES
"""All 19 bones: 57 numbers."""

BONE_SUBSETS: dict[str, tuple[str, ...]] = {"upper": UPPER_BODY, "full": FULL_BODY}
"""Subset name -> canonical bone names (the ``bones=`` argument of the descriptor)."""


def resolve_bones(bones: str | Iterable[str]) -> tuple[str, ...]:
    """Turn a subset name (``"upper"``, ``"full"``) or bone names into canonical bone names.

    Raises:
      ConfigError: an unknown subset, an unknown bone name or no bone.
    """
    if isinstance(bones, str):
        if bones not in BONE_SUBSETS:
            raise ConfigError(f"unknown bone subset {bones!r}; use one of {sorted(BONE_SUBSETS)}")
        return BONE_SUBSETS[bones]
    bones = tuple(bones)
    unknown = [b for b in bones if b not in BONE_NAMES]
    if unknown or not bones:
        raise ConfigError(f"unknown bone names {unknown}; valid names are {BONE_NAMES}")
    return bones


class FrozenMap(Mapping[str, tuple[str, str]]):
    """A read-only, hashable mapping (``Skeleton.bones``): the skeleton stays a static argument."""

    __slots__ = ("_items",)

    def __init__(self, items: Iterable[tuple[str, tuple[str, str]]]) -> None:
        self._items = tuple(items)

    def __getitem__(self, key: str) -> tuple[str, str]:
        for k, v in self._items:
            if k == key:
                return v
        raise KeyError(key)

    def __iter__(self) -> Iterator[str]:
        return (k for k, _ in self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __hash__(self) -> int:
        return hash(self._items)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, FrozenMap):
            return self._items == other._items
        return isinstance(other, Mapping) and dict(self._items) == dict(other)

    def __repr__(self) -> str:
        return f"{{{', '.join(f'{k!r}: {v!r}' for k, v in self._items)}}}"


class BodyFrame(NamedTuple):
    """The joints that span a skeleton's body frame (``skeleton.body_frame``).

    Attributes:
      up: ``(from, to)`` joints: the up axis, pelvis centre -> spine top.
      left: ``(from, to)`` joints: the left axis (made orthogonal to ``up``), right shoulder ->
        left shoulder. Forward is ``left x up``, out of the chest.
    """

    up: tuple[str, str]
    left: tuple[str, str]


@dataclass(frozen=True)
class Skeleton:
    """A human skeleton format: its joints, their tree, its canonical bones and its body frame.

    Frozen and hashable (a static argument of the compiled descriptor). The constructor checks
    everything and raises ``ConfigError``; ``bones`` and ``frame`` may be given as plain dicts /
    tuples (``{"neck": ("ShoulderCenter", "Head"), ...}``, ``(("A", "B"), ("C", "D"))``).

    Attributes:
      name: registry name (``"kinect_v1"``): lower case letters, digits, ``_``.
      joints: joint names in the format's array order (positions are ``(..., len(joints), 3)``).
      parents: per joint, its parent's index in ``joints`` or -1 for the root (exactly one).
      bones: canonical bone name (``BONE_NAMES``) -> ``(from joint, to joint)``, for the bones
        this skeleton defines (stored in ``BONE_NAMES`` order). A left bone comes with its right
        twin (mirroring swaps them). The two joints need not be parent and child.
      frame: the joints of the body frame (``BodyFrame``).
      description: one line for people (where the format comes from).
      derived: joints the format does not record but the bones need (MediaPipe Pose has no
        spine or head centre): ``((name, (joint, joint, ...)), ...)``, each the mean of earlier
        joints. They are the last ``len(derived)`` names of ``joints``, in this order; a reader
        computes them with ``complete`` from the format's own ``sensor_joints``.
    """

    name: str
    joints: tuple[str, ...]
    parents: tuple[int, ...]
    bones: Mapping[str, tuple[str, str]]
    frame: BodyFrame
    description: str = field(default="", compare=False)
    derived: tuple[tuple[str, tuple[str, ...]], ...] = ()

    def __post_init__(self) -> None:
        name = self.name
        if not (isinstance(name, str) and name and name.replace("_", "a").isalnum()):
            raise ConfigError(f"skeleton name must be letters, digits and _, got {name!r}")
        if name != name.lower():
            raise ConfigError(f"skeleton name must be lower case, got {name!r}")
        joints = tuple(self.joints) if not isinstance(self.joints, str) else ()
        if not joints or not all(isinstance(j, str) and j for j in joints):
            raise ConfigError(f"skeleton {name!r}: joints must be non-empty names")
        dup = sorted({j for j in joints if joints.count(j) > 1})
        if dup:
            raise ConfigError(f"skeleton {name!r}: joint names repeat: {dup}")
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "parents", _check_parents(name, joints, self.parents))
        object.__setattr__(self, "bones", _check_bones(name, joints, self.bones))
        object.__setattr__(self, "frame", _check_frame(name, joints, self.frame))
        object.__setattr__(self, "derived", _check_derived(name, joints, self.derived))

    def __hash__(self) -> int:  # computed once: the skeleton is a static argument of every call
        return self._hash

    @functools.cached_property
    def _hash(self) -> int:
        return hash((self.name, self.joints, self.parents, self.bones, self.frame, self.derived))

    @property
    def n_joints(self) -> int:
        """``len(joints)``: positions are ``(..., n_joints, 3)``."""
        return len(self.joints)

    @property
    def sensor_joints(self) -> tuple[str, ...]:
        """The joints a file of this format records: ``joints`` without the ``derived`` ones."""
        return self.joints[: len(self.joints) - len(self.derived)]

    def complete(self, positions: np.ndarray) -> np.ndarray:
        """The format's recorded joints ``(..., len(sensor_joints), 3)`` -> ``(..., n_joints, 3)``
        with the ``derived`` joints appended (each the mean of its joints); float32."""
        pos = np.asarray(positions, np.float32)
        n = len(self.sensor_joints)
        if pos.ndim < 2 or pos.shape[-2:] != (n, 3):
            raise ConfigError(
                f"skeleton {self.name!r} records {n} joints: positions must be (..., {n}, 3), "
                f"got {pos.shape}"
            )
        out = [pos]
        for _, parts in self.derived:
            idx = [self.index[j] for j in parts]
            full = np.concatenate(out, axis=-2)
            out.append(full[..., idx, :].mean(axis=-2, keepdims=True))
        return np.concatenate(out, axis=-2)

    @functools.cached_property
    def kinect_v1_sources(self) -> tuple[int, ...]:
        """Per Kinect v1 joint (``KINECT_V1.joints`` order), the index of this skeleton's joint
        at the same place of the canonical bones, or -1 where this skeleton lacks the bone that
        ends there (``to_kinect_v1`` fills those). Computed from ``bones``: the Kinect v1 bone
        ``b`` runs ``(a, c)``, this skeleton's ``(a', c')``, so ``a -> a'`` and ``c -> c'``.

        Raises:
          ConfigError: the bones put two of this skeleton's joints at one Kinect joint (e.g. the
            neck starting elsewhere than the clavicles), the body frame is not spanned by the
            same joints as Kinect v1's (pelvis centre -> spine top, right -> left shoulder), or
            a bone other than a hand or a foot is missing.
        """
        return _kinect_v1_sources(self)

    @functools.cached_property
    def index(self) -> dict[str, int]:
        """Joint name -> index in ``joints``."""
        return {j: i for i, j in enumerate(self.joints)}

    def missing(self, bones: str | Iterable[str]) -> tuple[str, ...]:
        """The canonical bones of ``bones`` (names or a subset name) this skeleton lacks."""
        return tuple(b for b in resolve_bones(bones) if b not in self.bones)

    def require(self, bones: str | Iterable[str]) -> tuple[str, ...]:
        """``resolve_bones(bones)``, checked to be bones of this skeleton.

        Raises:
          ConfigError: an unknown bone name, or bones this skeleton does not define (named).
        """
        names = resolve_bones(bones)
        lacking = self.missing(names)
        if lacking:
            raise ConfigError(
                f"skeleton {self.name!r} has no bone(s) {', '.join(lacking)}; it defines "
                f"{', '.join(self.bones)}"
            )
        return names

    def bone_joints(self, bones: str | Iterable[str]) -> tuple[tuple[int, int], ...]:
        """``(from, to)`` joint indices of each of ``bones`` (checked by ``require``)."""
        return tuple(
            (self.index[self.bones[b][0]], self.index[self.bones[b][1]])
            for b in self.require(bones)
        )


SkeletonLike = Skeleton | str
"""A ``Skeleton`` or the name it is registered under (``get``)."""


def _check_parents(name: str, joints: tuple[str, ...], parents: Any) -> tuple[int, ...]:
    try:
        out = tuple(int(p) for p in parents)
    except (TypeError, ValueError):
        raise ConfigError(f"skeleton {name!r}: parents must be joint indices or -1") from None
    if len(out) != len(joints):
        raise ConfigError(
            f"skeleton {name!r}: {len(out)} parents for {len(joints)} joints (one each)"
        )
    bad = [joints[i] for i, p in enumerate(out) if p < -1 or p >= len(joints) or p == i]
    if bad:
        raise ConfigError(f"skeleton {name!r}: joints {bad} have no valid parent index")
    roots = [joints[i] for i, p in enumerate(out) if p == -1]
    if len(roots) != 1:
        raise ConfigError(f"skeleton {name!r}: one root joint (parent -1) needed, got {roots}")
    for i in range(len(out)):  # every joint reaches the root in fewer than n steps: no cycle
        j, steps = i, 0
        while out[j] != -1:
            j, steps = out[j], steps + 1
            if steps > len(out):
                raise ConfigError(f"skeleton {name!r}: the parents of {joints[i]!r} form a cycle")
    return out


def _check_pair(name: str, joints: tuple[str, ...], what: str, pair: Any) -> tuple[str, str]:
    if isinstance(pair, str) or not isinstance(pair, Iterable):
        raise ConfigError(f"skeleton {name!r}: {what} must be a (from, to) pair of joint names")
    p = tuple(pair)
    if len(p) != 2:
        raise ConfigError(f"skeleton {name!r}: {what} must be a (from, to) pair, got {p}")
    unknown = [j for j in p if j not in joints]
    if unknown:
        raise ConfigError(f"skeleton {name!r}: {what} names unknown joint(s) {unknown}")
    if p[0] == p[1]:
        raise ConfigError(f"skeleton {name!r}: {what} runs from {p[0]!r} to itself")
    return (p[0], p[1])


def _check_bones(name: str, joints: tuple[str, ...], bones: Any) -> FrozenMap:
    if not isinstance(bones, Mapping) or not bones:
        raise ConfigError(f"skeleton {name!r}: bones must be a mapping canonical bone -> joints")
    unknown = [b for b in bones if b not in BONE_NAMES]
    if unknown:
        raise ConfigError(
            f"skeleton {name!r}: {unknown} are not canonical bones; use names of {BONE_NAMES}"
        )
    unpaired = [b for b in bones if MIRROR_BONE[b] not in bones]
    if unpaired:
        raise ConfigError(
            f"skeleton {name!r}: bones {unpaired} come without their other side "
            f"({[MIRROR_BONE[b] for b in unpaired]}); define both or neither"
        )
    return FrozenMap(
        (b, _check_pair(name, joints, f"bone {b!r}", bones[b])) for b in BONE_NAMES if b in bones
    )


def _check_frame(name: str, joints: tuple[str, ...], frame: Any) -> BodyFrame:
    if isinstance(frame, Mapping) and set(frame) == {"up", "left"}:
        up, left = frame["up"], frame["left"]
    elif isinstance(frame, tuple) and len(frame) == 2:  # a BodyFrame too
        up, left = frame
    else:
        raise ConfigError(f"skeleton {name!r}: frame must be a BodyFrame(up=..., left=...)")
    return BodyFrame(
        _check_pair(name, joints, "frame up", up), _check_pair(name, joints, "frame left", left)
    )


def _check_derived(name: str, joints: tuple[str, ...], derived: Any) -> tuple:
    try:
        items = tuple((str(d), tuple(str(j) for j in parts)) for d, parts in derived)
    except (TypeError, ValueError):
        raise ConfigError(f"skeleton {name!r}: derived must be (name, (joints...)) pairs") from None
    first = len(joints) - len(items)
    for k, (d, parts) in enumerate(items):
        if first < 0 or joints[first + k] != d:
            raise ConfigError(
                f"skeleton {name!r}: derived joint {d!r} must be joint {first + k} of joints "
                "(the derived joints come last, in order)"
            )
        bad = [j for j in parts if j not in joints[: first + k]]
        if not parts or bad:
            raise ConfigError(
                f"skeleton {name!r}: derived joint {d!r} must average earlier joints, got {parts}"
            )
    return items


_FILLABLE = ("hand_left", "hand_right", "foot_left", "foot_right")
"""The bones a skeleton may lack and still be laid out as Kinect v1 (``to_kinect_v1``)."""
FILL_FRACTION = 0.3
"""``to_kinect_v1``: a missing hand (foot) continues the forearm (shin) by this fraction."""


def _kinect_v1_sources(s: Skeleton) -> tuple[int, ...]:
    k = KINECT_V1
    src = [-1] * k.n_joints
    for b in BONE_NAMES:
        if b not in s.bones:
            if b not in _FILLABLE:
                raise ConfigError(
                    f"skeleton {s.name!r} cannot be laid out as Kinect v1: it lacks bone {b!r} "
                    "(only hands and feet may be missing)"
                )
            continue
        for kj, sj in zip(k.bones[b], s.bones[b], strict=True):
            i, j = k.index[kj], s.index[sj]
            if src[i] not in (-1, j):
                raise ConfigError(
                    f"skeleton {s.name!r}: its bones put joints {s.joints[src[i]]!r} and {sj!r} "
                    f"where Kinect v1 has one joint, {kj!r}; make the bones meet there"
                )
            src[i] = j
    for axis in ("up", "left"):
        want = tuple(s.joints[src[k.index[j]]] for j in getattr(k.frame, axis))
        if getattr(s.frame, axis) != want:
            raise ConfigError(
                f"skeleton {s.name!r}: its body frame's {axis} axis {getattr(s.frame, axis)} is "
                f"not where its bones put Kinect v1's {getattr(k.frame, axis)} ({want})"
            )
    return tuple(src)


def to_kinect_v1(positions: np.ndarray, skeleton: SkeletonLike) -> np.ndarray:
    """One skeleton's positions laid out as Kinect v1's 20 joints, through the canonical bones.

    Each Kinect v1 joint takes the position of the joint at the same place of this skeleton's
    canonical bones (``Skeleton.kinect_v1_sources``), so ``descriptor(to_kinect_v1(p, s))``
    equals ``descriptor(p, skeleton=s)`` on every bone ``s`` defines. A skeleton without hands
    (SMPL-X's 22 body joints) or feet gets a hand (foot) that continues the forearm (shin) by
    ``FILL_FRACTION`` of its length, so every frame stays a valid Kinect v1 skeleton. Those
    made-up bones are not for reading: ``retarget`` refuses a recording whose skeleton lacks a
    bone the model or the robot's correspondence reads (``Skeleton.require``).

    Args:
      positions: ``(..., n_joints, 3)`` in the skeleton's order (``complete`` adds derived
        joints first), any units.
      skeleton: a registered skeleton's name or a ``Skeleton``.

    Returns:
      ``(..., 20, 3)`` float32 positions in Kinect SDK order, the same units.
    """
    s = get(skeleton)
    pos = np.asarray(positions, np.float32)
    if pos.ndim < 2 or pos.shape[-2:] != (s.n_joints, 3):
        raise ConfigError(
            f"skeleton {s.name!r} has {s.n_joints} joints: positions must be "
            f"(..., {s.n_joints}, 3), got {pos.shape}"
        )
    src = np.asarray(s.kinect_v1_sources)
    out = pos[..., np.maximum(src, 0), :].copy()
    k = KINECT_V1
    for b in BONE_NAMES:  # parents come first in BONE_NAMES: a filled end reads filled starts
        a, c = (k.index[j] for j in k.bones[b])
        if src[c] >= 0:
            continue
        parent = next(p for p in BONE_NAMES if k.bones[p][1] == k.bones[b][0])
        pa = k.index[k.bones[parent][0]]
        out[..., c, :] = out[..., a, :] + FILL_FRACTION * (out[..., a, :] - out[..., pa, :])
    return out


KINECT_V1 = Skeleton(
    name="kinect_v1",
    joints=(
        "HipCenter", "Spine", "ShoulderCenter", "Head",
        "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft",
        "ShoulderRight", "ElbowRight", "WristRight", "HandRight",
        "HipLeft", "KneeLeft", "AnkleLeft", "FootLeft",
        "HipRight", "KneeRight", "AnkleRight", "FootRight",
    ),
    parents=(-1, 0, 1, 2, 2, 4, 5, 6, 2, 8, 9, 10, 0, 12, 13, 14, 0, 16, 17, 18),
    bones={
        "spine_lower": ("HipCenter", "Spine"), "spine_upper": ("Spine", "ShoulderCenter"),
        "neck": ("ShoulderCenter", "Head"),
        "clavicle_left": ("ShoulderCenter", "ShoulderLeft"),
        "upper_arm_left": ("ShoulderLeft", "ElbowLeft"),
        "forearm_left": ("ElbowLeft", "WristLeft"), "hand_left": ("WristLeft", "HandLeft"),
        "clavicle_right": ("ShoulderCenter", "ShoulderRight"),
        "upper_arm_right": ("ShoulderRight", "ElbowRight"),
        "forearm_right": ("ElbowRight", "WristRight"), "hand_right": ("WristRight", "HandRight"),
        "pelvis_left": ("HipCenter", "HipLeft"), "thigh_left": ("HipLeft", "KneeLeft"),
        "shin_left": ("KneeLeft", "AnkleLeft"), "foot_left": ("AnkleLeft", "FootLeft"),
        "pelvis_right": ("HipCenter", "HipRight"), "thigh_right": ("HipRight", "KneeRight"),
        "shin_right": ("KneeRight", "AnkleRight"), "foot_right": ("AnkleRight", "FootRight"),
    },
    frame=BodyFrame(up=("HipCenter", "ShoulderCenter"), left=("ShoulderRight", "ShoulderLeft")),
    description="Microsoft Kinect for Windows SDK v1: 20 joints in SDK order (NUI_SKELETON_"
    "POSITION_INDEX); MSR Action3D, UTKinect-Action3D, and BVH through a joint map",
)  # fmt: skip
"""The Kinect v1 skeleton: 20 joints in SDK order, all 19 canonical bones (each a tree edge
parent -> child), the body frame HipCenter -> ShoulderCenter (up), ShoulderRight -> ShoulderLeft
(left). Every bundled dataset and reader gives positions in this order."""

DEFAULT = KINECT_V1.name
"""The skeleton every function takes when none is named."""

_REGISTRY: dict[str, Skeleton] = {}


def register(skeleton: Skeleton, *, replace: bool = False) -> Skeleton:
    """Register ``skeleton`` under ``skeleton.name`` (again with the same spec: a no-op).

    Raises:
      ConfigError: not a ``Skeleton``, or another spec holds the name (unless ``replace``).
    """
    if not isinstance(skeleton, Skeleton):
        raise ConfigError(f"register takes a Skeleton, got {type(skeleton).__name__}")
    old = _REGISTRY.get(skeleton.name)
    if old is not None and old != skeleton and not replace:
        raise ConfigError(
            f"a different skeleton is registered as {skeleton.name!r}; pick another name "
            "(or replace=True)"
        )
    _REGISTRY[skeleton.name] = skeleton
    return skeleton


def get(skeleton: SkeletonLike = DEFAULT) -> Skeleton:
    """The registered skeleton of that name (a ``Skeleton`` is returned as it is).

    Raises:
      ConfigError: no skeleton of that name (lists the registered ones).
    """
    if isinstance(skeleton, Skeleton):
        return skeleton
    if isinstance(skeleton, str) and skeleton in _REGISTRY:
        return _REGISTRY[skeleton]
    raise ConfigError(f"unknown skeleton {skeleton!r}; registered: {', '.join(names())}")


def names() -> tuple[str, ...]:
    """Names of the registered skeletons, in registration order."""
    return tuple(_REGISTRY)


register(KINECT_V1)
