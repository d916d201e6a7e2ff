"""BVH motion capture (Biovision hierarchy: CMU, LAFAN1, Mixamo, Xsens exports) -> Kinect v1
skeletons.

``read_bvh(path, bvh_map="auto", scale="auto", fps=None)`` returns the same ``Recording`` as
every other reader (``(T, 20, 3)`` float32 metres, Kinect SDK joint order), so everything
downstream (descriptor, IK, projection, CLI) works unchanged; ``read_skeleton(path,
format="bvh")`` and ``--format bvh`` call it (the format is registered as ``reader.FORMAT``).
The package has one module per step (``parser``, ``kinematics``, ``joint_maps``; ``reader``
chains them and holds the units); its public names are re-exported here. The steps, each
public:

1. ``parse_bvh`` -> ``BvhClip``: the ``HIERARCHY`` (joint names, parents, ``OFFSET``s, the
   ``CHANNELS`` of each joint in their file order: any of the six Euler orders, position channels
   on any joint) and the ``MOTION`` block (``Frames:``, ``Frame Time:``, one row of channel values
   per frame). ``End Site``s are kept as extra joints with no channels, named ``<parent>_End``
   (e.g. ``Head_End``, the top of the head), so a joint map may use them.
2. ``forward_kinematics`` -> ``(T, J, 3)`` joint positions in the file's own axes and units,
   vectorised over frames (one batched product per channel and per joint; the only Python loop
   is over the joints). Conventions (the BVH de-facto standard): rotations in degrees; a joint's
   local rotation is the product of its rotation channels' axis rotations in the order the
   channels are listed (``Zrotation Xrotation Yrotation`` -> ``Rz @ Rx @ Ry``, i.e. intrinsic
   Z-X-Y); position channels replace the corresponding ``OFFSET`` component (the root's
   translation; some exporters write position channels on every joint);
   ``p_joint = p_parent + R_parent @ offset``, ``R_joint = R_parent @ R_local``.
3. A joint map (``JOINT_MAPS``, ``resolve_joint_map``) picks, for each of the 20 Kinect joints
   (the joints of ``TARGET_SKELETON``, the registered ``"kinect_v1"`` skeleton), the BVH joint
   whose position it takes; ``kinect_positions`` applies it, the scale and the axis change.

Joint maps (``bvh_map=``, CLI ``--bvh-map``):

- ``"cmu"``: the CMU database's "3dsMax-friendly" BVH release (cgspeed): ``Hips``, ``Chest``,
  ``Neck``, ``Head``, ``LeftShoulder``/``LeftElbow``/``LeftWrist``/``LFingers``,
  ``LeftHip``/``LeftKnee``/``LeftAnkle``/``LeftToe`` (and the right side); checked on the two
  bundled test clips.
- ``"cmu-mb"``: the "MotionBuilder-friendly" release: ``Hips``, ``Spine``, ``Neck1``, ``Head``,
  ``LeftArm``/``LeftForeArm``/``LeftHand``/``LeftHandIndex1``,
  ``LeftUpLeg``/``LeftLeg``/``LeftFoot``/``LeftToeBase``. Its joint names and offsets were
  checked against published hierarchies of that release, not against motion data of it (no such
  file is bundled).
- ``"lafan1"``: Ubisoft La Forge's LAFAN1 dataset (22 joints, the layout of e.g.
  ``aiming1_subject1.bvh``): ``Hips``, ``Spine1``, ``Neck``, ``Head``,
  ``LeftArm``/``LeftForeArm``/``LeftHand`` (``LeftShoulder`` is the clavicle),
  ``LeftUpLeg``/``LeftLeg``/``LeftFoot``/``LeftToe``; the hands derived.
- ``"mixamo"``: Adobe Mixamo rigs, the same names with ``LeftToeBase`` for the toe, behind the
  rig's namespace (``mixamorig:Hips``, ``mixamorig1:Hips``..., or none); the hands derived.
  ``joint_maps.JOINT_MAPS`` gives the reasons for each joint (``ShoulderCenter`` = ``Neck``,
  ``Spine`` = ``Spine1``) and the public sources the names were checked against; they were
  checked on files written in those layouts (``tests/io/test_bvh_presets.py``), not on the
  datasets' own files (none is bundled).
- ``"auto"`` (default): the preset whose every joint the hierarchy has, when exactly one does;
  otherwise an ``InputError`` listing, per preset, the Kinect joints it could not map. A
  preset's names are matched behind any namespace prefix, the text before ``Hips`` in the
  hierarchy's name for it, the same for every joint (``namespaces``); ``mixamo`` also asks for
  ``Spine2`` (``DETECTION_MARKS``), which tells a Mixamo rig from CMU's MotionBuilder release
  (LAFAN1 has ``LeftToe``, Mixamo ``LeftToeBase``). The recording's ``time_source`` names the
  map and the prefix.
- a ``dict`` (Kinect joint name -> BVH joint name) or the path of a JSON or TOML file holding
  that table (flat: ``{"HipCenter": "Hips", "ShoulderLeft": "LeftArm", ...}``).

Which Kinect joints a map must give, and how the others are derived (``REQUIRED_JOINTS``,
``DERIVED_JOINTS``):

- required: ``Head``, both ``Shoulder``, ``Elbow``, ``Wrist``, ``Hip``, ``Knee`` and ``Ankle``
  joints (the descriptor's body frame and bones need them);
- ``HipCenter``: the BVH root joint when the map leaves it out;
- ``ShoulderCenter``: the midpoint of ``ShoulderLeft`` and ``ShoulderRight``;
- ``Spine``: the midpoint of ``HipCenter`` and ``ShoulderCenter``;
- ``HandLeft`` / ``HandRight``: ``Wrist + HAND_EXTENSION * (Wrist - Elbow)`` (along the
  forearm);
- ``FootLeft`` / ``FootRight``: the first child (joint or End Site) of the ankle's BVH joint.

A map naming a BVH joint the hierarchy lacks, or leaving out a required Kinect joint, raises an
``InputError`` that lists every such Kinect joint. Kinect "Left" is the performer's left: the map
pairs names, it never mirrors (``--mirror`` does that, downstream).

A converter's rest frame (``rest_frame=``, CLI ``--bvh-rest-frame``): some converted files
(CMU's MotionBuilder and 3ds Max releases, in part) begin with a synthetic reference pose, every
joint rotation 0, before the motion. By default (``"drop"``) ``read_bvh`` leaves such a frame 0
out (``rest_pose_first`` detects it: every non-root rotation channel 0 in frame 0 and not in
frame 1), so the motion starts with the file's frame 1 at time 0; ``"keep"`` reads it.

Units (``scale=``, CLI ``--bvh-scale``): metres = file units x scale. ``"auto"`` (default):
``CMU_SCALE`` for the CMU presets (CMU's documented unit, (1 / 0.45) x 2.54 cm = 0.05644 m: the
converted skeletons keep the ASF lengths). With it the bundled subject 131 has its hip joints
0.96 m and its ankles ~0.1 m above the floor, thighs 0.41 m, shins 0.39 m, upper arms 0.24 m, a
plausible adult's legs; the converted torso is short (pelvis to neck base 0.32 m, top of the
head End Site 1.44 m above the floor), a property of that skeleton, not of the scale. For
other skeletons (LAFAN1 and Mixamo among them: centimetres, 167 and 155 units head to ankle, so
``cm``; a file converted to metres reads as ``m``) the unit among
``UNITS`` (m, cm, mm, in) that makes the rest pose's head-to-ankle height (the lengths of the
``OFFSET`` chains from the root to ``Head`` and to ``AnkleLeft``) nearest to ``REFERENCE_HEIGHT_M``
(1.5 m, in ratio). Or a unit name of ``UNITS`` (``"cmu"``, ``"m"``, ``"cm"``, ``"mm"``, ``"in"``)
or a number. The descriptor does not depend on the scale; a scale off by 1000 would make every
bone shorter than ``skeleton.MIN_BONE_LENGTH`` (1 mm) and every frame invalid.

Axes: BVH files are y-up and right-handed, the performer facing +z with their left at +x (CMU;
checked: its toes point to +z and ``LeftHip`` is at +x). The positions are turned 180 degrees
about y, ``(x, y, z) -> (-x, y, -z)`` (``BVH_TO_KINECT``), into Kinect camera-space conventions:
y up, the performer facing the camera (-z) with their left at smaller x, as in the Kinect
datasets. The origin stays the file's (floor at y = 0 for CMU). The descriptor is built in a body
frame made from the skeleton itself, so any rotation gives the same angles; the change only
makes raw positions (NPZ outputs, videos) look like Kinect data. A z-up file gives the same
descriptors too.

Time: frames are ``Frame Time`` seconds apart (``times = arange(T) * frame_time``). ``fps=F``
(CLI ``--fps`` for BVH) resamples the clip to ``F`` frames per second: joint positions are
interpolated linearly between the two nearest frames on the grid ``k / F`` over the clip's
duration (a resampled frame is invalid if either frame it interpolates is); the default keeps
the clip's own rate. (For the Kinect text formats, which carry no timing, ``fps`` instead states
their rate; a BVH states its own.)

Errors: every problem with the file raises ``InputError``, one line naming the file, the 1-based
line and the problem: no ``HIERARCHY`` or ``MOTION``, bad ``OFFSET`` / ``CHANNELS`` lines,
unbalanced braces, duplicate joint names, a bad ``Frames:`` or ``Frame Time:`` line, a row with
another number of values than the hierarchy's channels (a truncated row), non-numeric values,
fewer or more rows than ``Frames:`` says. Non-finite values are not errors: the frame is kept
and marked invalid, as in every reader.
"""

from jaxproj.io.formats.bvh.joint_maps import (
    DERIVED_JOINTS,
    DETECTION_MARKS,
    HAND_EXTENSION,
    JOINT_MAPS,
    REQUIRED_JOINTS,
    ROOT_JOINT,
    TARGET_SKELETON,
    detect_joint_map,
    load_joint_map,
    namespaces,
    preset_table,
    resolve_joint_map,
)
from jaxproj.io.formats.bvh.kinematics import BVH_TO_KINECT, forward_kinematics, kinect_positions
from jaxproj.io.formats.bvh.parser import BvhClip, parse_bvh
from jaxproj.io.formats.bvh.reader import (
    CMU_SCALE,
    FORMAT,
    REFERENCE_HEIGHT_M,
    REST_FRAMES,
    UNITS,
    auto_scale,
    read_bvh,
    rest_pose_first,
)

__all__ = [
    "BVH_TO_KINECT",
    "CMU_SCALE",
    "DERIVED_JOINTS",
    "DETECTION_MARKS",
    "FORMAT",
    "HAND_EXTENSION",
    "JOINT_MAPS",
    "REFERENCE_HEIGHT_M",
    "REQUIRED_JOINTS",
    "REST_FRAMES",
    "ROOT_JOINT",
    "TARGET_SKELETON",
    "UNITS",
    "BvhClip",
    "auto_scale",
    "detect_joint_map",
    "forward_kinematics",
    "kinect_positions",
    "load_joint_map",
    "namespaces",
    "parse_bvh",
    "preset_table",
    "read_bvh",
    "resolve_joint_map",
    "rest_pose_first",
]
