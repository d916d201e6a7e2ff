"""BVH joint maps: which BVH joint each of the 20 Kinect joints takes its position from.

Step 3 of ``jaxproj.io.formats.bvh`` (the package docstring lists the presets and the derived
joints): the built-in maps ``JOINT_MAPS``, map files (JSON / TOML), dicts, and the check that a map
fits a hierarchy (``resolve_joint_map``). A map's keys are joints of ``TARGET_SKELETON``, the
registered Kinect v1 skeleton (``jaxproj.human.skeletons``), whose joint order the reader's
positions come in.
"""

from __future__ import annotations

import json
import os
import tomllib
from collections.abc import Mapping
from pathlib import Path

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.io.formats.bvh.parser import BvhClip
from jaxproj.io.text import decode, one_line, read_bytes

TARGET_SKELETON: skeletons.Skeleton = skeletons.get("kinect_v1")
"""The skeleton joint maps map onto: a map's keys are its joint names, and ``kinect_positions``
gives ``(T, n_joints, 3)`` positions in its joint order. ``REQUIRED_JOINTS`` and
``DERIVED_JOINTS`` split its joints (the rules that derive a joint are Kinect v1's)."""

HAND_EXTENSION = 0.3
"""A derived Kinect hand lies this fraction of the forearm beyond the wrist (Kinect v1 data:
hand 0.07 m, forearm 0.25-0.29 m)."""

REQUIRED_JOINTS: tuple[str, ...] = (
    "Head", "ShoulderLeft", "ElbowLeft", "WristLeft", "ShoulderRight", "ElbowRight",
    "WristRight", "HipLeft", "KneeLeft", "AnkleLeft", "HipRight", "KneeRight", "AnkleRight",
)  # fmt: skip
"""Kinect joints a joint map must name (nothing in a skeleton stands in for them)."""

DERIVED_JOINTS: dict[str, str] = {
    "HipCenter": "the BVH root joint",
    "ShoulderCenter": "midpoint of ShoulderLeft and ShoulderRight",
    "Spine": "midpoint of HipCenter and ShoulderCenter",
    "HandLeft": f"WristLeft + {HAND_EXTENSION} x (WristLeft - ElbowLeft)",
    "HandRight": f"WristRight + {HAND_EXTENSION} x (WristRight - ElbowRight)",
    "FootLeft": "first child (joint or End Site) of AnkleLeft's BVH joint",
    "FootRight": "first child (joint or End Site) of AnkleRight's BVH joint",
}
"""Kinect joints a joint map may leave out, and how they are made when it does."""

JOINT_MAPS: dict[str, dict[str, str]] = {
    "cmu": {
        "HipCenter": "Hips", "Spine": "Chest", "ShoulderCenter": "Neck", "Head": "Head",
        "ShoulderLeft": "LeftShoulder", "ElbowLeft": "LeftElbow", "WristLeft": "LeftWrist",
        "HandLeft": "LFingers",
        "ShoulderRight": "RightShoulder", "ElbowRight": "RightElbow",
        "WristRight": "RightWrist", "HandRight": "RFingers",
        "HipLeft": "LeftHip", "KneeLeft": "LeftKnee", "AnkleLeft": "LeftAnkle",
        "FootLeft": "LeftToe",
        "HipRight": "RightHip", "KneeRight": "RightKnee", "AnkleRight": "RightAnkle",
        "FootRight": "RightToe",
    },
    "cmu-mb": {
        "HipCenter": "Hips", "Spine": "Spine", "ShoulderCenter": "Neck1", "Head": "Head",
        "ShoulderLeft": "LeftArm", "ElbowLeft": "LeftForeArm", "WristLeft": "LeftHand",
        "HandLeft": "LeftHandIndex1",
        "ShoulderRight": "RightArm", "ElbowRight": "RightForeArm", "WristRight": "RightHand",
        "HandRight": "RightHandIndex1",
        "HipLeft": "LeftUpLeg", "KneeLeft": "LeftLeg", "AnkleLeft": "LeftFoot",
        "FootLeft": "LeftToeBase",
        "HipRight": "RightUpLeg", "KneeRight": "RightLeg", "AnkleRight": "RightFoot",
        "FootRight": "RightToeBase",
    },
}  # fmt: skip
"""Built-in joint maps (Kinect joint -> BVH joint) of the two CMU BVH releases.

``cmu`` (3dsMax-friendly): ``LeftShoulder`` is the shoulder joint (``LeftCollar`` the clavicle),
``Neck`` the base of the neck at shoulder height (``lowerneck`` sits lower, at ``Chest2``),
``LFingers`` the hand (``lhand`` coincides with ``LeftWrist``). ``cmu-mb`` (MotionBuilder-friendly):
``LeftShoulder`` is the clavicle and ``LeftArm`` the shoulder joint, ``Neck1`` the upper neck
(``Neck`` coincides with ``Spine1``), ``LeftHandIndex1`` the hand (``LeftFingerBase`` coincides
with ``LeftHand``)."""


def load_joint_map(path: str | os.PathLike[str]) -> dict[str, str]:
    """A joint map file: JSON or TOML (by extension; ``.toml``, else JSON), one flat table of
    Kinect joint name -> BVH joint name.

    Raises:
      InputError: unreadable file, bad syntax, not a flat table of names.
    """
    data = read_bytes(path)
    text = decode(path, data)
    try:
        if Path(path).suffix.lower() == ".toml":
            table = tomllib.loads(text)
        else:
            table = json.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as err:
        raise InputError(path, f"not a joint map: {one_line(err)}") from None
    if not isinstance(table, dict):
        raise InputError(path, "a joint map is a table of Kinect joint name -> BVH joint name")
    return _check_map(table, lambda problem: InputError(path, problem))


def _check_map(table: Mapping, error) -> dict[str, str]:
    bad_values = [k for k, v in table.items() if not isinstance(v, str)]
    if bad_values:
        raise error(f"joint map values must be BVH joint names (strings): {bad_values}")
    target = TARGET_SKELETON
    unknown = [k for k in table if k not in target.index]
    if unknown:
        raise error(f"unknown Kinect joint name(s) {unknown} in the joint map; the "
                    f"{target.n_joints} joints of the {target.name} skeleton are "
                    f"{', '.join(target.joints)}")  # fmt: skip
    return {str(k): str(v) for k, v in table.items()}


def _unmapped(table: Mapping[str, str], names: tuple[str, ...]) -> list[str]:
    """Kinect joints the table cannot give from a hierarchy with these joint names."""
    out = [f"{k} ({v} not in the hierarchy)" for k, v in table.items() if v not in names]
    out += [f"{k} (not in the map)" for k in REQUIRED_JOINTS if k not in table]
    return out


def detect_joint_map(clip: BvhClip) -> str:
    """The preset of ``JOINT_MAPS`` whose every joint the hierarchy has.

    Raises:
      InputError: no preset fits (lists, per preset, the Kinect joints it could not map) or more
        than one does.
    """
    fits = [k for k, table in JOINT_MAPS.items() if not _unmapped(table, clip.names)]
    if len(fits) == 1:
        return fits[0]
    if fits:
        raise InputError(clip.source, f"the hierarchy fits several joint maps ({', '.join(fits)}):"
                                      " give one (--bvh-map, bvh_map=)")  # fmt: skip
    why = "; ".join(
        f"{k!r} could not map {', '.join(_unmapped(t, clip.names))}" for k, t in JOINT_MAPS.items()
    )
    raise InputError(
        clip.source,
        f"no built-in joint map fits this BVH skeleton ({len(clip.names)} joints, root "
        f"{clip.names[0]}): {why}. Give a map (--bvh-map FILE.json|FILE.toml, bvh_map=dict) "
        "of Kinect joint -> BVH joint",
    )


def resolve_joint_map(
    clip: BvhClip, bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto"
) -> tuple[str, dict[str, str]]:
    """``(name, table)`` of the joint map for ``clip``: a preset name, ``"auto"``, a file path
    (JSON / TOML) or a dict; checked against the hierarchy.

    Raises:
      ConfigError: a dict with unknown Kinect names or non-string values.
      InputError: a map file that cannot be read; a map that does not fit the hierarchy (lists
        every Kinect joint it could not map).
    """
    if isinstance(bvh_map, Mapping):
        name, table = "dict", _check_map(bvh_map, ConfigError)
    elif str(bvh_map) == "auto":
        name = detect_joint_map(clip)
        table = JOINT_MAPS[name]
    elif str(bvh_map) in JOINT_MAPS:
        name, table = str(bvh_map), JOINT_MAPS[str(bvh_map)]
    else:
        p = Path(bvh_map)
        if not p.exists():
            raise ConfigError(
                f"bvh map {str(bvh_map)!r}: not a built-in map ({', '.join(JOINT_MAPS)}, auto) "
                "nor an existing JSON / TOML file"
            )
        name, table = str(p), load_joint_map(p)
    missing = _unmapped(table, clip.names)
    if missing:
        raise InputError(
            clip.source,
            f"joint map {name!r} could not map {len(missing)} Kinect joint(s): "
            f"{', '.join(missing)}; the hierarchy's joints: {', '.join(clip.names)}",
        )
    return name, dict(table)
