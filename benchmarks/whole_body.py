"""Whole-body motion as the field measures it (issue 59): what ``jaxproj retarget REC --robot
unitree_g1 --root world --out m.npz`` writes, read back from the file, replayed kinematically on
the robot's own MJCF with its free base:

* ``slide_cm_s``: stance-foot sliding, the horizontal speed (cm/s) of each foot's sole (the mean
  of its geoms' lowest points) over the steps where the file says that foot is in contact in
  both frames: median and p95 over both feet;
* ``stance_height_mm``: the stance feet's lowest point above the floor: median, p95 and max
  (the root's step bound can leave a stance foot above the floor: ``whole_body.LIFT_SLACK``);
* ``sole_tilt_deg``: the stance feet's tilt (the foot body's z axis against the vertical; the
  G1's sole box is square to it): median and p90;
* ``penetration_mm``: how far the lowest point of any robot geom goes below the floor (max over
  frames; 0 if none does);
* ``root_jump_cm``: the largest amount by which one frame's root step exceeds the person's
  scaled HipCenter step (``scale`` of the file's meta);
* ``root_jump_ref_cm`` (hip-centred recordings only, when the run holds a recording of the same
  motion with a moving pelvis: the files' names agree up to the first dot, as in
  ``tests/data/formats/same_motion``): the same against that recording's scaled HipCenter
  steps, frame for frame (a hip-centred recording's own pelvis never moves: ``reference`` names
  the file);
* ``trunk_deg``: the robot's torso up axis against the person's trunk (HipCenter ->
  ShoulderCenter), both in the world frame: median and p90 over valid frames;
  ``torso_tilt_deg`` / ``person_tilt_deg``: each one's median angle from the vertical;
* ``legs_deg``: the robot's thighs and shins (its correspondence rows' points) against the
  person's, in the world frame: median and p90 over valid frames and the four bones;
* ``contact_share``: frames with each foot in contact (left, right);
* ``retarget_first_s``, ``fixed_s``, ``world_s``: the command's wall time in this process: the
  first fixed-base run (compiling), a second one, and a second whole-body run (its programs,
  retargeted without the legs' levelling, compiled by the first: the difference from
  ``fixed_s`` is the whole-body stage).

* ``contact_frames``: frames where two of the robot's geoms penetrate by more than 1 mm (MuJoCo,
  the MJCF's own exclusions; ``benchmarks.g1_playable``'s measure) in the file's angles, which
  the stance IK has moved from the fixed-base ones (self-contact does not depend on the root);
* ``speed_spikes``: steps where a joint moves faster than its rated speed
  (``Robot.speed_limits("rated")``, the feasibility filter's cap at ``speed_fraction`` 1): the
  stance IK runs after the filter.

    python -m benchmarks.whole_body [--data FOLDER] [--json OUT] [--extra "OPTIONS"] [FILES...]
    python -m benchmarks.whole_body --picture MOTION.npz OUT.png 0,300,500
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from benchmarks import g1_playable as gp
from jaxproj import robots
from jaxproj.cli.main import main as cli
from jaxproj.human.skeleton import J
from jaxproj.io.motion_files import Motion, load_motion
from jaxproj.motion.stance import _foot_points
from jaxproj.motion.stance import subtree as _subtree
from jaxproj.motion.whole_body import CENTRED, _point, world_frame
from jaxproj.robots.base import joint_qpos_index


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    na = a / np.linalg.norm(a, axis=-1, keepdims=True)
    nb = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(na * nb, -1), -1.0, 1.0)))


def measure_motion(motion: Motion) -> dict:
    """The measures of one whole-body motion (module doc)."""
    robot = motion.robot
    assert motion.root_pos is not None and motion.root_rot is not None
    assert motion.contacts is not None and motion.positions is not None
    model = robot.load_model("free")
    data = mujoco.MjData(model)
    adr = joint_qpos_index(model, robot.joint_names)
    free = int(model.jnt_qposadr[0])
    corr = robot.generic.correspondence
    torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, corr.base)
    feet = [_subtree(model, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b))
            for b, _ in robot.mjcf.figure.feet]  # fmt: skip
    everything = list(range(1, model.nbody))
    rows = {r.bone: (r.start, r.end) for r in corr.pairs}
    legs = [f"{b}_{s}" for s in ("left", "right") for b in ("thigh", "shin")]

    n = motion.n_frames
    sole = np.zeros((n, len(feet), 3))
    sole_low = np.zeros((n, len(feet)))
    lowest = np.zeros(n)
    torso_up = np.zeros((n, 3))
    sole_up = np.zeros((n, len(feet), 3))
    robot_legs = np.zeros((n, len(legs), 3))
    for t in range(n):
        data.qpos[free : free + 3] = motion.root_pos[t]
        data.qpos[free + 3 : free + 7] = np.roll(motion.root_rot[t], 1)  # xyzw -> wxyz
        data.qpos[adr] = motion.angles[t]
        mujoco.mj_kinematics(model, data)
        for k, tree in enumerate(feet):
            sole_up[t, k] = data.xmat[tree[0]].reshape(3, 3)[:, 2]
            pts, rad = _foot_points(model, data, tree, 0)  # body 0: the world
            sole[t, k] = pts.mean(axis=0)
            sole_low[t, k] = np.min(pts[:, 2] - rad)
        pts, rad = _foot_points(model, data, everything, 0)
        lowest[t] = np.min(pts[:, 2] - rad)
        torso_up[t] = data.xmat[torso].reshape(3, 3)[:, 2]
        for i, bone in enumerate(legs):
            a, b = rows[bone]
            robot_legs[t, i] = _point(model, data, b) - _point(model, data, a)
    c = motion.contacts
    dt = np.diff(motion.times)
    both = c[1:] & c[:-1]
    speed = np.linalg.norm(np.diff(sole[..., :2], axis=0), axis=-1) / dt[:, None] * 100
    slide = speed[both[:, : len(feet)]]
    stance = sole_low[c[:, : len(feet)]] * 1000
    tilt = _angle(sole_up, np.array([0.0, 0.0, 1.0]))[c[:, : len(feet)]]
    # the person in the world (the file's positions, the world frame found again from them)
    valid = motion.valid & np.isfinite(motion.positions).all(axis=(1, 2))
    world = world_frame(motion.positions, valid, robot)
    person = world.to_world(motion.positions)
    trunk = person[:, J["ShoulderCenter"]] - person[:, J["HipCenter"]]
    person_legs = np.stack(
        [person[:, J[b]] - person[:, J[a]] for a, b in (("HipLeft", "KneeLeft"),
         ("KneeLeft", "AnkleLeft"), ("HipRight", "KneeRight"), ("KneeRight", "AnkleRight"))],
        axis=1,
    )  # fmt: skip
    jump = _root_excess(motion, _pelvis_steps(motion))
    trunk_err = _angle(torso_up, trunk)[valid]
    leg_err = _angle(robot_legs, person_legs)[valid]
    vertical = np.array([0.0, 0.0, 1.0])
    fixed = robot.load_model("fixed")
    fixed_data = mujoco.MjData(fixed)
    fixed_adr = joint_qpos_index(fixed, robot.joint_names)
    touching = 0
    for t in range(n):
        fixed_data.qpos[fixed_adr] = motion.angles[t]
        mujoco.mj_forward(fixed, fixed_data)
        touching += bool(gp.contact_pairs(fixed, fixed_data))
    driven = np.asarray(robot.driven_index)
    rated = np.asarray(robot.speed_limits("rated"), np.float64)[driven]
    joint_step = np.abs(np.diff(motion.angles[:, driven].astype(np.float64), axis=0))
    spikes = int(np.sum(np.any(joint_step / dt[:, None] > rated[None], axis=1)))
    return {
        "frames": n,
        "fps": round(motion.fps, 3),
        "scale": round(world.scale, 4),
        "contact_share": [round(float(x), 3) for x in c.mean(axis=0)],
        "slide_cm_s_median": round(float(np.median(slide)), 2) if slide.size else None,
        "slide_cm_s_p95": round(float(np.percentile(slide, 95)), 2) if slide.size else None,
        "stance_height_mm_median": round(float(np.median(stance)), 2) if stance.size else None,
        "stance_height_mm_p95": (
            round(float(np.percentile(stance, 95)), 2) if stance.size else None
        ),
        "stance_height_mm_max": round(float(stance.max()), 2) if stance.size else None,
        "sole_tilt_deg_median": round(float(np.median(tilt)), 2) if tilt.size else None,
        "sole_tilt_deg_p90": round(float(np.percentile(tilt, 90)), 2) if tilt.size else None,
        "penetration_mm": round(float(max(0.0, -lowest.min()) * 1000), 2),
        "root_jump_cm": round(float(max(0.0, jump.max(initial=0.0)) * 100), 2),
        "trunk_deg_median": round(float(np.median(trunk_err)), 2),
        "trunk_deg_p90": round(float(np.percentile(trunk_err, 90)), 2),
        "torso_tilt_deg": round(float(np.median(_angle(torso_up, vertical)[valid])), 2),
        "person_tilt_deg": round(float(np.median(_angle(trunk, vertical)[valid])), 2),
        "legs_deg_median": round(float(np.median(leg_err)), 2),
        "legs_deg_p90": round(float(np.percentile(leg_err, 90)), 2),
        "contact_frames": touching,
        "speed_spikes": spikes,
        "root_travel_m": round(
            float(np.linalg.norm(motion.root_pos[-1, :2] - motion.root_pos[0, :2])), 3
        ),  # fmt: skip
    }


def _pelvis_steps(motion: Motion) -> np.ndarray:
    """``(T - 1,)``: the person's scaled HipCenter steps in the world frame (m); NaN where a
    step leaves an invalid frame."""
    assert motion.positions is not None
    valid = motion.valid & np.isfinite(motion.positions).all(axis=(1, 2))
    hip = world_frame(motion.positions, valid, motion.robot).to_world(motion.positions)
    step = np.linalg.norm(np.diff(hip[:, J["HipCenter"]], axis=0), axis=-1)
    return np.where(valid[1:] & valid[:-1], step, np.nan)


def _root_excess(motion: Motion, pelvis: np.ndarray) -> np.ndarray:
    """The root's steps less ``pelvis`` (``(T - 1,)``, m), where both are known."""
    assert motion.root_pos is not None
    root = np.linalg.norm(np.diff(motion.root_pos.astype(np.float64), axis=0), axis=-1)
    excess = root - pelvis
    return excess[np.isfinite(excess)]


def same_motion_references(motions: dict[str, Motion]) -> dict[str, str]:
    """For each hip-centred file (its person's pelvis moves less than ``whole_body.CENTRED``)
    of ``motions`` (by file name), the first other file of the same motion (the names agree up
    to the first dot), of as many frames, whose pelvis moves."""

    def centred(m: Motion) -> bool:
        assert m.positions is not None
        hip = m.positions[:, J["HipCenter"]]
        return bool(np.ptp(hip[np.isfinite(hip).all(axis=1)], axis=0).max() < CENTRED)

    refs = {}
    for name, m in motions.items():
        if not centred(m):
            continue
        for other, r in motions.items():
            if (other != name and other.split(".")[0] == name.split(".")[0]
                    and len(r.angles) == len(m.angles) and not centred(r)):  # fmt: skip
                refs[name] = other
                break
    return refs


_PERSON = (("HipCenter", "Spine"), ("Spine", "ShoulderCenter"), ("ShoulderCenter", "Head"),
           ("ShoulderCenter", "ShoulderLeft"), ("ShoulderLeft", "ElbowLeft"),
           ("ElbowLeft", "WristLeft"), ("ShoulderCenter", "ShoulderRight"),
           ("ShoulderRight", "ElbowRight"), ("ElbowRight", "WristRight"), ("HipCenter", "HipLeft"),
           ("HipLeft", "KneeLeft"), ("KneeLeft", "AnkleLeft"), ("AnkleLeft", "FootLeft"),
           ("HipCenter", "HipRight"), ("HipRight", "KneeRight"), ("KneeRight", "AnkleRight"),
           ("AnkleRight", "FootRight"))  # fmt: skip


def picture(motion: Motion, out: Path, frames: list[int], beside: float = 0.9) -> None:
    """A PNG of ``frames`` of a whole-body ``motion``: per frame a side view (top) and a front
    view (bottom) of the robot (its bodies joined to their parents, blue) and the person (the
    file's positions in the same world frame, red, ``beside`` m to the robot's left), over the
    floor (grey)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    assert motion.root_pos is not None and motion.root_rot is not None
    assert motion.positions is not None and motion.contacts is not None
    robot = motion.robot
    model = robot.load_model("free")
    data = mujoco.MjData(model)
    adr = joint_qpos_index(model, robot.joint_names)
    valid = motion.valid & np.isfinite(motion.positions).all(axis=(1, 2))
    person = world_frame(motion.positions, valid, robot).to_world(motion.positions)
    person = person + np.array([0.0, beside, 0.0])
    fig = plt.figure(figsize=(2.6 * len(frames), 5.6))
    for i, t in enumerate(frames):
        data.qpos[0:3] = motion.root_pos[t]
        data.qpos[3:7] = np.roll(motion.root_rot[t], 1)
        data.qpos[adr] = motion.angles[t]
        mujoco.mj_kinematics(model, data)
        centre = (motion.root_pos[t] + person[t, J["HipCenter"]]) / 2
        for row, view in enumerate(((0, -90), (0, 0))):
            ax = fig.add_subplot(2, len(frames), row * len(frames) + i + 1, projection="3d")
            for b in range(2, model.nbody):
                a, c = data.xpos[model.body_parentid[b]], data.xpos[b]
                ax.plot(*zip(a, c, strict=True), color="tab:blue", lw=1.5)
            for a, b in _PERSON:
                ax.plot(*zip(person[t, J[a]], person[t, J[b]], strict=True), color="tab:red",
                        lw=1.5)  # fmt: skip
            xs, ys = np.meshgrid(centre[0] + np.array([-0.8, 0.8]),
                                 centre[1] + np.array([-1.0, 1.0]))  # fmt: skip
            ax.plot_surface(xs, ys, 0 * xs, alpha=0.2, color="grey")
            ax.set(xlim=centre[0] + np.array([-0.8, 0.8]), ylim=centre[1] + np.array([-1, 1]),
                   zlim=(0, 1.6), xticklabels=[], yticklabels=[])  # fmt: skip
            ax.view_init(*view)
            feet = "".join("LR"[k] for k in range(2) if motion.contacts[t, k]) or "-"
            ax.set_title(f"{motion.times[t]:.2f} s, contact {feet}", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=70)
    plt.close(fig)


def measure(path: Path, extra: list[str], out_dir: Path, robot: str = gp.ROBOT) -> dict:
    """``jaxproj retarget PATH --robot ROBOT`` in this process: the fixed base twice (the first
    compiles; the second is timed: ``fixed_s``), then ``--root world`` twice (the second timed:
    ``world_s``), then the whole-body file's measures."""
    out = out_dir / f"{path.stem}.npz"

    def run(*more: str) -> float:
        t0 = time.perf_counter()
        rc = cli(["retarget", str(path), "--robot", robot, "--out", str(out), "--force",
                  *more, *extra])  # fmt: skip
        if rc != 0:
            raise SystemExit(f"retarget {path} exited {rc}")
        return time.perf_counter() - t0

    first = run()
    fixed = run()
    run("--root", "world")  # its own programs (no legs' levelling): compiled once
    world = run("--root", "world")
    return {"file": path.name, "retarget_first_s": round(first, 1), "fixed_s": round(fixed, 1),
            "world_s": round(world, 1), **measure_motion(load_motion(out))}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="*", type=Path)
    p.add_argument("--data", type=Path, default=None, help="a folder holding the six files")
    p.add_argument("--robot", default=gp.ROBOT)
    p.add_argument("--json", default=None)
    p.add_argument("--extra", default="", help="more retarget options, one string")
    p.add_argument(
        "--picture",
        nargs=3,
        metavar=("MOTION", "OUT", "FRAMES"),
        default=None,
        help="only draw frames (comma-separated) of a whole-body MOTION file to a PNG",
    )
    a = p.parse_args(argv)
    if a.picture:
        motion, out, frames = a.picture
        picture(load_motion(motion), Path(out), [int(f) for f in frames.split(",")])
        return 0
    files = a.files or gp.default_files(a.data)
    robot = robots.get(a.robot).name
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for f in files:
            r = measure(f, a.extra.split(), Path(tmp), robot)
            rows.append(r)
            print(json.dumps(r), flush=True)
        motions = {f.name: load_motion(Path(tmp) / f"{f.stem}.npz") for f in files}
        refs = same_motion_references(motions)
        for r in rows:
            if r["file"] in refs:
                ref = refs[r["file"]]
                jump = _root_excess(motions[r["file"]], _pelvis_steps(motions[ref]))
                r["root_jump_ref_cm"] = round(float(max(0.0, jump.max(initial=0.0)) * 100), 2)
                r["reference"] = ref
                print(json.dumps({k: r[k] for k in ("file", "reference", "root_jump_ref_cm")}))
    if a.json:
        Path(a.json).write_text(json.dumps({"robot": robot, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
