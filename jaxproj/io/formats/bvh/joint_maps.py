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


def _humanik_map(toe: str) -> dict[str, str]:
    """LAFAN1's and Mixamo's map (the same MotionBuilder / HumanIK joint names; only the toe
    differs): ``JOINT_MAPS`` says why each joint."""
    table = {"HipCenter": "Hips", "Spine": "Spine1", "ShoulderCenter": "Neck", "Head": "Head"}
    for side in ("Left", "Right"):
        table |= {
            f"Shoulder{side}": f"{side}Arm", f"Elbow{side}": f"{side}ForeArm",
            f"Wrist{side}": f"{side}Hand", f"Hip{side}": f"{side}UpLeg",
            f"Knee{side}": f"{side}Leg", f"Ankle{side}": f"{side}Foot",
            f"Foot{side}": f"{side}{toe}",
        }  # fmt: skip
    return table


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
    "lafan1": _humanik_map("Toe"),
    "mixamo": _humanik_map("ToeBase"),
}  # fmt: skip
"""Built-in joint maps (Kinect joint -> BVH joint): the two CMU BVH releases, LAFAN1 and Mixamo.

``cmu`` (3dsMax-friendly): ``LeftShoulder`` is the shoulder joint (``LeftCollar`` the clavicle),
``Neck`` the base of the neck at shoulder height (``lowerneck`` sits lower, at ``Chest2``),
``LFingers`` the hand (``lhand`` coincides with ``LeftWrist``). ``cmu-mb`` (MotionBuilder-friendly):
``LeftShoulder`` is the clavicle and ``LeftArm`` the shoulder joint, ``Neck1`` the upper neck
(``Neck`` coincides with ``Spine1``), ``LeftHandIndex1`` the hand (``LeftFingerBase`` coincides
with ``LeftHand``).

``lafan1`` (Ubisoft La Forge's LAFAN1, github.com/ubisoft/ubisoft-laforge-animation-dataset; its 22
joints: ``Hips``; ``LeftUpLeg``/``LeftLeg``/``LeftFoot``/``LeftToe`` and the right side;
``Spine``/``Spine1``/``Spine2``/``Neck``/``Head``; ``LeftShoulder``/``LeftArm``/``LeftForeArm``/
``LeftHand`` and the right side; every End Site at offset 0) and ``mixamo`` (Adobe Mixamo rigs:
the same names, ``LeftToeBase`` for the toe, ``HeadTop_End`` / ``LeftToe_End`` ends and, in most
rigs, finger chains ``LeftHandThumb1..3``, ``LeftHandIndex1..3``, ...; every name behind a
namespace prefix, ``namespaces``) share one map: ``LeftShoulder`` is the clavicle and
``LeftArm`` the shoulder joint, ``LeftForeArm`` the elbow, ``LeftHand`` the wrist,
``LeftUpLeg`` / ``LeftLeg`` / ``LeftFoot`` hip, knee and ankle, ``LeftToe`` / ``LeftToeBase`` the
foot (the ball of the foot, as CMU's ``LeftToe``). ``ShoulderCenter`` is ``Neck``, the base of the
neck, about 6 cm above the shoulder joints in both rest skeletons (LAFAN1: ``Neck`` 25.8 cm above
``Spine2``, the clavicles 19.7 cm, level with the shoulder joints in a T-pose; Mixamo: ``Neck``
15.0 cm, the shoulder joints 8.8 cm), which is where the Kinect v1 tracker puts its
``ShoulderCenter`` too (a median 8 cm above the mid-shoulder point, along the trunk, in the
bundled MSR Action3D recordings of subjects 1, 3 and 5); the derived mid-shoulder point would
sit on the shoulder line. ``Spine`` is ``Spine1``, the middle of the three spine joints: 34 %
(LAFAN1) and 43 % (Mixamo) of the way up from the hips to the neck, the Kinect ``Spine`` 42 %
(the same recordings); a joint of the spine rather than the derived midpoint, so the spine's
bend shows. ``Head`` is ``Head`` (the base of the skull,
as in the CMU maps; LAFAN1 has no head top). The hands are derived (``DERIVED_JOINTS``): LAFAN1
has no joint beyond the wrist and Mixamo's finger chains are left out of some rigs (the 25-joint
"no fingers" skeleton).

Sources for the names and offsets: the header of LAFAN1's ``aiming1_subject1.bvh`` (7184 frames)
as reproduced in two independent public notes of retargeting projects (they agree: root
``Hips`` with ``Xposition Yposition Zposition Zrotation Yrotation Xrotation``, every other joint
``Zrotation Yrotation Xrotation``, each bone along its joint's local +x, centimetres, y up,
``Frame Time: 0.033333``); GMR's ``utils/lafan1.py`` (positions / 100, cm -> m) and its
``ik_configs/bvh_lafan1_to_*.json`` (``LeftArm``, ``LeftForeArm``, ``LeftUpLeg``, ``LeftLeg``,
``LeftToe``); the dataset's ``lafan1/extract.py`` and README (30 fps). Mixamo: the Mixamo BVH
``tests/test_freebvh.bvh`` of github.com/20tab/bvh-python (root ``mixamorig:Hips``, T-pose rest
pose, y up, facing +z, left at +x, centimetres, ``HeadTop_End`` / eyes / three-segment fingers as
joints, ``Zrotation Yrotation Xrotation``); ``mixamorig1:`` / ``mixamorig2:`` namespaces and
colon-less ``mixamorigHips`` / ``mixamorig_Hips`` names from the bone-name tables of projects
that load Mixamo rigs (Unity, three.js, Godot)."""

DETECTION_MARKS: dict[str, tuple[str, ...]] = {"mixamo": ("Spine2",)}
"""Joints (bare names, before the namespace) that ``bvh_map="auto"`` also asks of a hierarchy to
pick the preset, beyond the preset's own joints: a Mixamo rig has three spine joints,
``Spine``, ``Spine1``, ``Spine2``, where CMU's MotionBuilder-friendly release, whose other names
the ``mixamo`` map shares, has two."""

ROOT_JOINT = "Hips"
"""The pelvis joint every preset maps ``HipCenter`` to; a namespace is the text before it in the
hierarchy's name for it (``namespaces``)."""


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


def namespaces(clip: BvhClip) -> list[str]:
    """The namespace prefixes the hierarchy's joints may carry: for each joint (End Sites aside)
    whose name ends with ``ROOT_JOINT``, the text before it, in hierarchy order, then ``""`` (no
    prefix) if no joint is called ``ROOT_JOINT`` itself.

    Mixamo rigs name every joint ``mixamorig:Hips``, ``mixamorig:Spine``, ...; a rig imported
    more than once becomes ``mixamorig1:``, ``mixamorig2:``...; tools that drop the colon leave
    ``mixamorig_Hips`` or ``mixamorigHips``; some exporters write no prefix. Any such prefix is
    taken as it is found, so a preset fits under any namespace, provided every joint it maps
    carries the same one.
    """
    found = [
        name[: len(name) - len(ROOT_JOINT)]
        for name, end in zip(clip.names, clip.end_site, strict=True)
        if not end and name.endswith(ROOT_JOINT)
    ]
    return list(dict.fromkeys([*found, ""]))


def _with_prefix(table: Mapping[str, str], prefix: str) -> dict[str, str]:
    return {k: prefix + v for k, v in table.items()}


def _preset_problems(
    clip: BvhClip, name: str, prefix: str, detecting: bool
) -> tuple[list[str], list[str]]:
    """What keeps preset ``name`` under namespace ``prefix`` from the hierarchy (nothing: it
    fits): the Kinect joints it cannot map (``_unmapped``) and, when ``detecting``, its
    ``DETECTION_MARKS`` the hierarchy lacks (prefixed)."""
    unmapped = _unmapped(_with_prefix(JOINT_MAPS[name], prefix), clip.names)
    marks = [prefix + m for m in DETECTION_MARKS.get(name, ()) if prefix + m not in clip.names]
    return unmapped, marks if detecting else []


def _fits(problems: tuple[list[str], list[str]]) -> bool:
    return not (problems[0] or problems[1])


def preset_table(clip: BvhClip, name: str, detecting: bool = False) -> tuple[str, dict[str, str]]:
    """``(namespace, table)`` of preset ``name`` for this hierarchy: the first of its
    ``namespaces`` under which the preset fits (every BVH joint of the table, and for
    ``detecting`` its ``DETECTION_MARKS``, in the hierarchy), its joint names prefixed with it;
    the first namespace if none fits (``resolve_joint_map`` then reports what is missing)."""
    spaces = namespaces(clip)
    prefix = next((p for p in spaces if _fits(_preset_problems(clip, name, p, detecting))),
                  spaces[0])  # fmt: skip
    return prefix, _with_prefix(JOINT_MAPS[name], prefix)


def detect_joint_map(clip: BvhClip) -> str:
    """The preset of ``JOINT_MAPS`` whose every joint (and ``DETECTION_MARKS``) the hierarchy has,
    under one namespace (``namespaces``).

    Raises:
      InputError: no preset fits (lists, per preset and for the namespace it came nearest under,
        the Kinect joints it could not map and the marks the hierarchy lacks) or more than one
        does.
    """
    spaces = namespaces(clip)
    problems = {  # per preset, under the namespace it comes nearest to fitting
        k: min((_preset_problems(clip, k, p, True) for p in spaces),
               key=lambda problem: len(problem[0]) + len(problem[1]))
        for k in JOINT_MAPS
    }  # fmt: skip
    fits = [k for k, problem in problems.items() if _fits(problem)]
    if len(fits) == 1:
        return fits[0]
    if fits:
        raise InputError(clip.source, f"the hierarchy fits several joint maps ({', '.join(fits)}):"
                                      " give one (--bvh-map, bvh_map=)")  # fmt: skip
    why = []
    for k, (unmapped, marks) in problems.items():
        parts = [f"could not map {', '.join(unmapped)}"] if unmapped else []
        parts += [f"lacks {', '.join(marks)} (which a {k} hierarchy has)"] if marks else []
        why.append(f"{k!r} {' and '.join(parts)}")
    raise InputError(
        clip.source,
        f"no built-in joint map fits this BVH skeleton ({len(clip.names)} joints, root "
        f"{clip.names[0]}): {'; '.join(why)}. Give a map (--bvh-map FILE.json|FILE.toml, "
        "bvh_map=dict) of Kinect joint -> BVH joint",
    )


def resolve_joint_map(
    clip: BvhClip, bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto"
) -> tuple[str, dict[str, str]]:
    """``(name, table)`` of the joint map for ``clip``: a preset name, ``"auto"``, a file path
    (JSON / TOML) or a dict; checked against the hierarchy. A preset's joint names come with the
    hierarchy's namespace prefix (``preset_table``); a dict's or a file's are taken as they are.

    Raises:
      ConfigError: a dict with unknown Kinect names or non-string values.
      InputError: a map file that cannot be read; a map that does not fit the hierarchy (lists
        every Kinect joint it could not map).
    """
    if isinstance(bvh_map, Mapping):
        name, table = "dict", _check_map(bvh_map, ConfigError)
    elif str(bvh_map) == "auto":
        name = detect_joint_map(clip)
        table = preset_table(clip, name, detecting=True)[1]
    elif str(bvh_map) in JOINT_MAPS:
        name = str(bvh_map)
        table = preset_table(clip, name)[1]
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
