"""Robots as files (``jaxproj.robots.robot_file``): the G1's file, a robot from any folder, and
broken files refused with one line that names the file and the problem."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError
from jaxproj.robots import robot_file
from jaxproj.robots.base import joint_qpos_index

TWO_ARMS = Path(__file__).parents[1] / "data" / "robots" / "two_arms"


@pytest.fixture
def two_arms(tmp_path: Path):
    """A copy of the two-armed test robot's folder; its ``robot.toml`` (unregistered after the
    test if the test registered it: other tests of the worker count the registered robots)."""
    shutil.copytree(TWO_ARMS, tmp_path / "two_arms")
    yield tmp_path / "two_arms" / "robot.toml"
    if "two_arms" in robots.names():
        robots.unregister("two_arms")


def test_the_g1_file_takes_joints_and_limits_from_its_mjcf_and_speeds_from_its_table():
    g1 = robots.get("unitree_g1")
    assert g1.file is not None and g1.file.name == "robot.toml" and g1.mjcf is not None
    # the MJCF read independently of MuJoCo: every hinge in file order, its range
    tree = ET.parse(g1.mjcf.path)
    hinges = [j for j in tree.find("worldbody").iter("joint") if j.get("type", "hinge") == "hinge"]
    assert g1.joint_names == tuple(j.get("name") for j in hinges)
    ranges = np.array([[float(v) for v in j.get("range").split()] for j in hinges], np.float32)
    np.testing.assert_array_equal(g1.lower, ranges[:, 0])
    np.testing.assert_array_equal(g1.upper, ranges[:, 1])
    # the file's patterns, resolved per joint (Unitree's URDF: knee 20, waist roll 30, wrist
    # pitch 22, shoulders 37 rad/s)
    v = dict(zip(g1.joint_names, g1.velocity_limits.tolist(), strict=True))
    assert (v["left_knee_joint"], v["waist_roll_joint"], v["right_wrist_pitch_joint"]) == (
        20,
        30,
        22,
    )
    assert v["left_shoulder_yaw_joint"] == v["right_shoulder_roll_joint"] == 37
    assert g1.generic is not None and len(g1.generic.correspondence.pairs) == 12
    assert [c.name for c in g1.chains] == [
        "waist",
        "left_arm",
        "right_arm",
        "left_leg",
        "right_leg",
    ]
    assert all(c.ik is not None for c in g1.chains) and g1.track is not None


def test_a_robot_file_from_a_folder_registers_once_and_an_edit_reads_again(two_arms):
    try:
        robot = robots.get(two_arms)
        assert robots.get(str(two_arms)) is robot is robots.get("two_arms")
        assert robot.joint_names[:4] == ("left_shoulder_pitch", "left_shoulder_roll",
                                         "left_shoulder_yaw", "left_elbow")  # fmt: skip
        assert robot.acceleration_limits.tolist() == [40, 40, 40, 60] * 2
        text = two_arms.read_text().replace('"*" = 6.0', '"*" = 5.0')
        two_arms.write_text(text)
        edited = robots.get(two_arms)
        assert edited is not robot and edited.velocity_limits.tolist() == [5.0] * 8
        assert robots.get("two_arms") is edited
    finally:
        robots.unregister("two_arms")


def test_a_robot_file_may_not_take_a_registered_robots_name(two_arms):
    two_arms.write_text(two_arms.read_text().replace('name = "two_arms"', 'name = "unitree_g1"'))
    with pytest.raises(ConfigError, match="registered already"):
        robots.get(two_arms)
    assert robots.get("unitree_g1").file != two_arms


BROKEN = {
    "unknown key": ('title = "Two-armed test robot"', 'title = "x"\ncolour = "red"',
                    "unknown key(s) ['colour']"),
    "schema": ("schema = 1", "schema = 2", "schema: this jaxproj reads robot files of schema 1"),
    "no mjcf": ('mjcf = "two_arms.xml"', 'mjcf = "none.xml"', "mjcf: no such MJCF file"),
    "driven joint": ('driven = [\n  "left_shoulder_pitch"', 'driven = [\n  "left_shoulder_pich"',
                     "joints.driven: the MJCF has no joint(s) ['left_shoulder_pich']"),
    "no speed": ('"*" = 6.0', '"left_*" = 6.0',
                 "joints.velocity: no key matches the joint 'right_shoulder_pitch'"),
    "two speeds": ('"*" = 6.0', '"*" = 6.0\n"left_elbow" = 3.0',
                   "joints.velocity: several keys match (['*', 'left_elbow'])"),
    "row site": ('end = "left_wrist"', 'end = "left_wirst"',
                 "ik.rows[1].end: the MJCF has no site or body 'left_wirst'"),
    "row bone": ('bone = "forearm_left"', 'bone = "forearm_lft"',
                 "ik.rows[1]: unknown bone 'forearm_lft'"),
    "ik kind": ('kind = "generic"', 'kind = "closed_form"', "ik.kind: must be \"generic\""),
    "limits": ("[evaluation]", "[joints.limits]\nleft_elbow = [-2.0, 0.0]\n\n[evaluation]",
               "joints.limits.left_elbow: [-2.0, 0.0] disagrees with the MJCF's range"),
    "unread row": ("[evaluation]",
                   '[[ik.rows]]\nbone = "neck"\nstart = "torso_site"\nend = "neck_site"\n\n'
                   "[evaluation]", "rows read by no chain"),
    "chains": ('[[chains]]\nname = "right_arm"', '[[unused]]\nname = "right_arm"',
               "unknown key(s) ['unused']"),
    "driven twice": ('joints = ["right_shoulder_pitch"', 'joints = ["left_shoulder_pitch"',
                     "the robot:"),
    "figure site": ('["neck_site", "pelvis_site"]', '["neck_site", "hip_site"]',
                    "figure.links: the MJCF has no site named 'hip_site'"),
    "iterations": ("iterations = 12", "iterations = 0", "ik: IKConfig: iterations"),
    "not toml": ("schema = 1", "schema = = 1", "not a TOML file"),
    "order": ("loose = [", 'order = ["left_elbow", "left_elbow"]\nloose = [',
              "joints.order: must name every hinge and slide joint of the MJCF once"),
    "coupled": ("loose = [", 'coupled = [["left_elbow", "left_elbw"]]\nloose = [',
                "joints.coupled: the MJCF has no joint(s) ['left_elbw']"),
    "coupled limit": ("[evaluation]", '[[joints.coupled_limits]]\njoint = "left_elbow"\n'
                      'by = "left_shoulder_yaw"\nsymmetric = true\n'
                      "table_deg = [[10.0, -20.0, 20.0], [5.0, -10.0, 10.0]]\n\n[evaluation]",
                      "joints.coupled_limits[0].table_deg: a symmetric table starts at by = 0"),
    "knots": ("[evaluation]", '[[joints.coupled_limits]]\njoint = "left_elbow"\n'
              'by = "left_shoulder_yaw"\ntable_deg = [[10.0, -20.0, 20.0], [5.0, -10.0, 10.0]]'
              "\n\n[evaluation]", "knots must increase strictly"),
    "export": ("[evaluation]", '[exports]\n".json" = "jaxproj.robots.nao_h25.naoqi:EXPRT"\n\n'
               "[evaluation]", "exports..json: the module 'jaxproj.robots.nao_h25.naoqi' has no "
               "'EXPRT'"),
    "export suffix": ("[evaluation]", '[exports]\n".csv" = "jaxproj.robots.nao_h25.naoqi:EXPORT"'
                      "\n\n[evaluation]", "is not an Export of suffix '.csv'"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_robot_file_is_refused_with_one_line_naming_file_and_problem(two_arms, case):
    old, new, message = BROKEN[case]
    text = two_arms.read_text()
    assert old in text
    two_arms.write_text(text.replace(old, new, 1))
    with pytest.raises(ConfigError) as err:
        robot_file.load(two_arms)
    line = str(err.value)
    assert "\n" not in line and line.startswith(f"{two_arms.resolve()}: ")
    assert message in line


def test_an_mjcf_that_does_not_compile_is_named(two_arms):
    xml = two_arms.parent / "two_arms.xml"
    xml.write_text(xml.read_text().replace("</worldbody>", "</wrldbody>"))
    with pytest.raises(ConfigError, match=r"robot.toml: mjcf: MuJoCo cannot compile two_arms.xml"):
        robot_file.load(two_arms)


def test_a_model_embeds_a_file_robot_that_loads_without_its_folder(two_arms, tmp_path):
    robot = robot_file.load(two_arms)
    doc = robot_file.embed(robot)
    assert doc is not None and doc["sha256"] == robot_file.digest(two_arms)
    shutil.rmtree(two_arms.parent)
    again = robot_file.from_embedded(doc)
    assert again.file is not None and again.file.parent != two_arms.parent
    assert again.joint_names == robot.joint_names
    np.testing.assert_array_equal(again.acceleration_limits, robot.acceleration_limits)
    with pytest.raises(ConfigError, match="digest"):
        robot_file.from_embedded({**doc, "sha256": "0" * 64})


def test_robot_check_names_an_unseen_joint_and_standing_contact(two_arms, capsys):
    from jaxproj.cli.main import main

    assert main(["robot", "check", str(two_arms)]) == 0
    assert capsys.readouterr().out.count("ok: two_arms, 8 joints, 8 driven in 2 chains") == 1
    # the left arm reads its upper arm only: the elbow and the upper arm's own twist are unseen
    text = two_arms.read_text()
    text = text.replace('bones = ["upper_arm_left", "forearm_left"]', 'bones = ["upper_arm_left"]')
    text = text.replace('[[ik.rows]]\nbone = "forearm_left"', '[[unread]]\nbone = "forearm_left"')
    two_arms.write_text(text.replace("[[unread]]", "[unread_rows]"))
    with pytest.raises(ConfigError, match="unknown key"):  # the schema is strict
        robot_file.load(two_arms)
    two_arms.write_text(text.replace('[[unread]]\nbone = "forearm_left"\nstart = "left_elbow"\n'
                                     'end = "left_wrist"\n', ""))  # fmt: skip
    xml = two_arms.parent / "two_arms.xml"  # and the torso as wide as the shoulders
    xml.write_text(xml.read_text().replace('0 0 0.1" size="0.08"', '0 0 0.1" size="0.19"'))
    assert main(["robot", "check", str(two_arms)]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(": ", 2)[1] for line in lines] == [
        "chain 'left_arm'", "chain 'left_arm'", "standing posture", "standing posture",
    ]  # fmt: skip
    assert "'left_shoulder_yaw'" in lines[0] and "'left_elbow'" in lines[1]
    assert "'torso_geom' and 'left_fore_geom'" in lines[2] + lines[3]
    assert main(["robot", "show", str(two_arms)]) == 0
    shown = capsys.readouterr().out
    assert "left_upper (left_shoulder_pitch, left_shoulder_roll, left_shoulder_yaw)" in shown
    assert "reads upper_arm_right: right_shoulder -> right_elbow (weight 1)" in shown


def test_a_robot_without_a_free_joint_is_fixed_as_written(two_arms):
    text = two_arms.read_text().replace('free_joint = "root"\nroot_body = "torso"\n', "")
    two_arms.write_text(text)
    xml = two_arms.parent / "two_arms.xml"
    xml.write_text(xml.read_text().replace('<freejoint name="root"/>', ""))
    robot = robot_file.load(two_arms)
    assert robot.mjcf is not None and robot.mjcf.free_joint is None
    for mount in ("free", "fixed"):
        assert robot.load_model(mount).nq == robot.n_joints == 8
    assert robot.load_model("fixed", ("left_upper",)).nq == 4
    q = np.asarray(robot.solve_ik(np.tile(np.array([0.0, 0.0, -1.0] * 4, np.float32), (2, 1)),
                                  ("upper_arm_left", "forearm_left", "upper_arm_right",
                                   "forearm_right")))  # fmt: skip
    assert np.isfinite(q).all() and np.abs(q).max() < 0.05  # arms hanging: the standing posture


def _python_ik(path: Path, module: str) -> None:
    """Replace the file's generic IK (``[ik]`` and its rows) with ``kind = "python"``."""
    text = path.read_text()
    head, tail = text.split("[ik]\n", 1)
    path.write_text(f'{head}[ik]\nkind = "python"\nmodule = "{module}"\n\n[evaluation]'
                    f"{tail.split('[evaluation]', 1)[1]}")  # fmt: skip


@pytest.mark.parametrize(
    ("module", "message"),
    [
        ("jaxproj.no_such_module", "ik.module: cannot import 'jaxproj.no_such_module'"),
        ("jaxproj.robots.base", "ik.module: the module 'jaxproj.robots.base' has no 'attach'"),
        # the NAO's closed form refuses a robot other than the one its file describes
        ("jaxproj.robots.nao_h25.ik", "ik.module: the NAO closed-form IK drives"),
    ],
)
def test_a_python_ik_is_a_module_the_file_names(two_arms, module, message):
    _python_ik(two_arms, module)
    with pytest.raises(ConfigError) as err:
        robot_file.load(two_arms)
    line = str(err.value)
    assert "\n" not in line and line.startswith(f"{two_arms.resolve()}: ") and message in line


def test_joint_order_is_the_files_and_limits_follow_it(two_arms):
    as_written = robot_file.load(two_arms)
    order = as_written.joint_names[::-1]
    text = two_arms.read_text()
    two_arms.write_text(
        text.replace("loose = [", f"order = {list(order)!r}\nloose = [".replace("'", '"'))
    )
    robot = robot_file.load(two_arms)
    assert robot.joint_names == order
    np.testing.assert_array_equal(robot.lower, as_written.lower[::-1])
    np.testing.assert_array_equal(robot.upper, as_written.upper[::-1])
    assert robot.mjcf is not None
    model = robot.load_model("free")
    index = joint_qpos_index(model, robot.joint_names)  # the same joints, addressed by name
    assert index.tolist() == joint_qpos_index(model, as_written.joint_names).tolist()[::-1]


def test_the_nao_is_a_robot_file_with_its_closed_form_and_naoqi_export():
    from jaxproj.robots.nao_h25 import ik, naoqi, robot

    nao = robots.get("nao_h25")
    assert nao is robots.NAO_H25 and nao.file == robot.FILE
    bare = robot_file.describe(robot.FILE)  # the file's robot before the IK module attaches
    assert bare.ik is None and bare.traced_ik is None and all(c.ik is None for c in bare.chains)
    assert nao.ik is ik.solve_driven and nao.whole_chain is ik.WHOLE_BODY
    assert all(c.ik is not None for c in nao.chains) and nao.exports == {".json": naoqi.EXPORT}
    # the configuration order is ALMotion's, not the MJCF's tree order (arms before legs)
    assert nao.joint_names[6:9] == ("LWristYaw", "LHand", "LHipYawPitch")
    assert nao.coupled_joints == (("LHipYawPitch", "RHipYawPitch"),)
    # the head envelope: the published half table (7 rows from yaw 0) mirrored to 13 knots
    env = nao.coupled_limits[0]
    assert (env.joint, env.by, len(env.knots)) == ("HeadPitch", "HeadYaw", 13)
    np.testing.assert_allclose(np.degrees(env.knots[[0, 6, 12]]), [-119.52, 0.0, 119.52], atol=1e-4)
    np.testing.assert_array_equal(env.upper, env.upper[::-1])
    assert [c.bandwidth for c in nao.chains] == [0.01125, 0.01875, 0.01875]
