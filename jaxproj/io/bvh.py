"""BVH input, under its older name: the public names of ``jaxproj.io.formats.bvh`` (parser,
forward kinematics, joint maps, ``read_bvh``), re-exported. The code and its documentation live
in that package."""

from __future__ import annotations

from jaxproj.io.formats.bvh import (
    BVH_TO_KINECT,
    CMU_SCALE,
    DERIVED_JOINTS,
    HAND_EXTENSION,
    JOINT_MAPS,
    REFERENCE_HEIGHT_M,
    REQUIRED_JOINTS,
    UNITS,
    BvhClip,
    auto_scale,
    detect_joint_map,
    forward_kinematics,
    kinect_positions,
    load_joint_map,
    parse_bvh,
    read_bvh,
    resolve_joint_map,
)

__all__ = [
    "BVH_TO_KINECT",
    "CMU_SCALE",
    "DERIVED_JOINTS",
    "HAND_EXTENSION",
    "JOINT_MAPS",
    "REFERENCE_HEIGHT_M",
    "REQUIRED_JOINTS",
    "UNITS",
    "BvhClip",
    "auto_scale",
    "detect_joint_map",
    "forward_kinematics",
    "kinect_positions",
    "load_joint_map",
    "parse_bvh",
    "read_bvh",
    "resolve_joint_map",
]
