"""Is what ``jaxproj retarget`` writes for the G1 something a G1 could play? (issue 57)

Any robot of the generic IK is measured the same way (``--robot NAME|FILE``, default the G1;
its sites and joints read from its correspondence and figure: ``layout``).

Runs the command line's ``retarget`` as a user does (in-process, default options unless
``--method relaxed --model P.npz``) on recordings the default model never trained on, reads back
the NPZ it wrote, and measures the output itself (after the last stage), over time, in the world
and against the robot's own geometry:

* ``flip_steps``: steps between two valid frames where a driven joint moves more than
  ``FLIP_JOINT_DEG`` (20 deg) while every person's bone of that joint's chain (its own bones:
  upper arm and forearm for an arm, thigh, shin and foot for a leg, the hip line and lower spine
  for the waist) turns less than ``FLIP_BONE_DEG`` (10 deg), unless it is a catch-up
  (``catch_up_steps``, counted apart): the joint's step before it was at its speed cap (at least
  ``CATCH_UP_AT_CAP`` of the rated cap the feasibility filter applies, over that step's time)
  and the same way, so the filter had held the robot back while the person moved faster than the
  robot may, and this step finishes the person's move a frame late; also the largest joint step
  and the steps over 20 and 90 deg whatever the person did.
* ``contact_frames``: frames where two of the robot's own geoms (its MJCF, fixed base, MuJoCo's
  own collision pipeline with the MJCF's exclusions) penetrate by more than 1 mm; the pairs.
* ``lean``: the trunk's forward lean (deg, sagittal) when the robot stands on its soles: the
  torso's up axis seen in the sole's frame, ``atan2(z . x_sole, z . z_sole)``, mean of the two
  feet (``lean_roll``: the sideways part; the ankle rolls are not driven, so an abducted leg
  tilts its sole), against the person's forward lean (HipCenter -> ShoulderCenter against the
  capture's up axis, in the plane of the body's forward direction: +y up for Kinect v1 camera
  space and the BVH reader's output; the camera's own tilt is not removed): medians and their
  difference; and the share of frames with an ankle pitch at a limit.
* ``arms``: the angle between the robot's upper arm / forearm (torso frame) and the person's
  (the body frame as ``retarget`` levels it, ``skeleton.level_body``), deg: median and p90 over
  valid frames and both arms.
* ``foot_pitch``: each foot's pitch (deg, toes down positive) against its own flat-footed
  standing, in the trunk's frame: the robot's ankle -> toe direction in the torso frame against
  the same at the standing posture; the person's levelled foot bone against the direction the
  correspondence matches to the robot's flat foot (the foot row's ``rest``): medians over valid
  frames and both feet, and their difference.

Inputs (default): the UTKinect-Action3D people 7 and 9 (the default model trains on 3, 4, 6) and
the two CMU BVH clips at their full 120 fps, from ``../shared/data`` when it is there, else the
bundled UTKinect copies and ``tests/data/cmu_bvh`` (every 6th frame).

    python -m benchmarks.g1_playable [--method ik|relaxed --model P.npz] [--json OUT] [FILES...]
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

from jaxproj import robots
from jaxproj.cli.main import main as cli
from jaxproj.human.skeleton import BONE_NAMES, J, descriptor, level_body, world_up
from jaxproj.io.motion_files import load_motion
from jaxproj.motion.feasible import SPEED_FRACTIONS

ROBOT = "unitree_g1"
"""The default ``--robot``; any robot solved by the generic IK whose correspondence has the
arm and foot rows is measured the same way (its sites and joints are read from its data)."""
FLIP_JOINT_DEG = 20.0
FLIP_BONE_DEG = 10.0
CATCH_UP_AT_CAP = 0.95
"""A step of at least this share of its speed cap is "at the cap" (``flips``' catch-ups)."""
CONTACT_MM = 1.0
SIDES = ("left", "right")

_REPO = Path(__file__).resolve().parent.parent
_SHARED = _REPO.parent / "shared" / "data"


def default_files(folder: Path | None = None) -> list[Path]:
    """The held-out recordings (module doc), from ``folder`` (all in one) or ``../shared``."""
    utk = [f"joints_s{p:02d}_e{e:02d}.txt" for p in (7, 9) for e in (1, 2)]
    bvh = [f"131_0{i}.bvh" for i in (1, 3)]
    if folder is not None:
        return [folder / f for f in utk + bvh]
    if (_SHARED / "utkinect_action3d").is_dir():
        files = [_SHARED / "utkinect_action3d" / f for f in utk]
        return files + [_SHARED / "cmu_bvh" / f for f in bvh]
    raise SystemExit(f"{_SHARED} is missing: pass the recordings or --data FOLDER")


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (deg) between the unit vectors of ``a`` and ``b`` along the last axis."""
    na = a / np.linalg.norm(a, axis=-1, keepdims=True)
    nb = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(na * nb, -1), -1.0, 1.0)))


def _pitch(v: np.ndarray) -> float:
    """Pitch (deg) of a direction in a frame with x forward and z up: positive below the
    horizontal (toes down)."""
    return float(np.degrees(np.arctan2(-v[2], np.hypot(v[0], v[1]))))


def robot_correspondence(robot: robots.Robot):  # noqa: ANN201
    """The robot's correspondence (its bone pairs and their ``rest`` directions)."""
    if robot.generic is None:
        raise SystemExit(f"{robot.name}: this benchmark measures a robot of the generic IK")
    return robot.generic.correspondence


def layout(robot: robots.Robot) -> dict:
    """What the measures read of ``robot``, from its data: the torso (the correspondence's
    base), the sole bodies (``Figure.feet``), each side's arm and foot points (the rows of
    ``upper_arm_<side>``, ``forearm_<side>``, ``foot_<side>``) and ankle pitch joints (those
    that turn the foot's row but not the shin's)."""
    from jaxproj.robots.generic_ik import row_turned_by

    corr = robot_correspondence(robot)
    rows = {r.bone: r for r in corr.pairs}
    model = robot.load_model("fixed")
    ankles = []
    for s in SIDES:
        foot, shin = (row_turned_by(model, rows[f"{b}_{s}"], corr.base) for b in ("foot", "shin"))
        ankles += [j for j in robot.driven_joints if j in foot - shin]
    return {
        "torso": corr.base,
        "feet": tuple(body for body, _ in robot.mjcf.figure.feet),
        "points": {
            f"{b}_{s}": (rows[f"{b}_{s}"].start, rows[f"{b}_{s}"].end)
            for s in SIDES
            for b in ("upper_arm", "forearm", "foot")
        },  # fmt: skip
        "ankles": ankles,
    }


def _bones(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Person: ``(T, 19, 3)`` body-frame bone units, ``(T,)`` ok, ``(T, 3, 3)`` body frames."""
    from jaxproj.human.skeleton import body_frame

    d, ok = descriptor(positions, bones="full")
    frame, ok_f = body_frame(positions)
    ok = np.asarray(ok & ok_f)
    d = np.asarray(level_body(d, ok, "full", up=world_up(positions)))
    return d.reshape(len(d), -1, 3), ok, np.asarray(frame)


def _chain_bones(robot: robots.Robot) -> dict[str, tuple[str, ...]]:
    """Each chain's own bones (its bones no earlier chain reads)."""
    seen: set[str] = set()
    out = {}
    for c in robot.chains:
        own = tuple(b for b in c.bones if b not in seen) or tuple(c.bones)
        seen |= set(c.bones)
        out[c.name] = own
    return out


def flips(motion, bones: np.ndarray, ok: np.ndarray, robot: robots.Robot) -> dict:
    q = np.degrees(motion.angles.astype(np.float64))
    valid = motion.valid & ok
    both = valid[1:] & valid[:-1]
    signed = np.diff(q, axis=0)  # (T-1, n_joints)
    step = np.abs(signed)
    # each step's largest move the feasibility filter allows (its speed cap over the step's time)
    cap = np.degrees(robot.speed_limits("rated") * SPEED_FRACTIONS["rated"]).astype(np.float64)
    allowed = np.diff(np.asarray(motion.times, np.float64))[:, None] * cap[None, :]
    at_cap = step >= CATCH_UP_AT_CAP * allowed  # (T-1, n_joints)
    per_chain = _chain_bones(robot)
    flip = np.zeros(len(step), bool)
    catch_up = np.zeros(len(step), bool)
    worst: list[dict] = []
    caught: list[dict] = []
    for c in robot.chains:
        idx = [BONE_NAMES.index(b) for b in per_chain[c.name]]
        turn = _angle(bones[1:, idx], bones[:-1, idx]).max(axis=1)  # (T-1,)
        cols = [robot.index(j) for j in c.joints]
        over = both[:, None] & (step[:, cols] > FLIP_JOINT_DEG) & (turn < FLIP_BONE_DEG)[:, None]
        # a catch-up: the joint's step before was at its speed cap, the same way, while the
        # person moved (the filter held the robot back; this step finishes that move)
        before = np.zeros_like(over)
        before[1:] = (
            at_cap[:-1, cols]
            & (np.sign(signed[:-1, cols]) == np.sign(signed[1:, cols]))
            & both[:-1, None]
        )
        late = over & before
        f = (over & ~late).any(axis=1)
        flip |= f
        catch_up |= late.any(axis=1) & ~f
        for t in np.flatnonzero(f)[:3]:
            j = cols[int(np.argmax(np.where(over[t] & ~late[t], step[t, cols], -1.0)))]
            worst.append({"step": int(t), "joint": robot.joint_names[j],
                          "deg": round(float(step[t, j]), 1),
                          "bones_turn": round(float(turn[t]), 1)})  # fmt: skip
        for t in np.flatnonzero(late.any(axis=1))[:3]:
            j = cols[int(np.argmax(np.where(late[t], step[t, cols], -1.0)))]
            caught.append({"step": int(t), "joint": robot.joint_names[j],
                           "deg": round(float(step[t, j]), 1),
                           "step_before_deg": round(float(step[t - 1, j]), 1),
                           "bones_turn": round(float(turn[t]), 1)})  # fmt: skip
    big = step.max(axis=1)
    return {
        "flip_steps": int(flip.sum()),
        "catch_up_steps": int(catch_up.sum()),
        "steps": int(both.sum()),
        "steps_over_20": int((both & (big > 20)).sum()),
        "steps_over_90": int((both & (big > 90)).sum()),
        "max_step_deg": round(float(big[both].max(initial=0.0)), 1),
        "examples": worst[:6],
        "catch_up_examples": caught[:6],
    }


def qpos_addresses(model: mujoco.MjModel, robot: robots.Robot) -> list[int]:
    """``qpos`` index of each of ``robot.joint_names`` in ``model``."""
    return [int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)])
            for n in robot.joint_names]  # fmt: skip


def contact_pairs(model: mujoco.MjModel, data: mujoco.MjData) -> list[str]:
    """``"geom - geom"`` of every contact of the last ``mj_forward`` deeper than
    ``CONTACT_MM`` (names sorted within a pair)."""
    out = []
    for c in data.contact[: data.ncon]:
        if c.dist < -CONTACT_MM / 1000:
            b1 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, c.geom1)
            b2 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, c.geom2)
            out.append(" - ".join(sorted((str(b1), str(b2)))))
    return out


def geometry(motion, bones: np.ndarray, ok: np.ndarray, frames: np.ndarray, robot: robots.Robot,
             positions: np.ndarray) -> dict:  # fmt: skip
    """Contacts, lean, sole pitch and arm directions from the robot's MJCF (fixed base)."""
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    qadr = qpos_addresses(model, robot)
    lay = layout(robot)
    torso, feet = lay["torso"], lay["feet"]
    bid = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in (torso, *feet)}
    site = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n)
            for pair in lay["points"].values() for n in pair}  # fmt: skip
    rests = {r.bone: r.rest for r in robot_correspondence(robot).pairs if r.rest is not None}
    flat = {s: _pitch(np.asarray(rests[f"foot_{s}"])) for s in ("left", "right")}  # person's

    def sole_pitch() -> list[float]:  # deg, each foot's ankle -> toe in the torso frame
        r_t = data.xmat[bid[torso]].reshape(3, 3)
        out = []
        for s in SIDES:
            a, b = (data.site_xpos[site[n]] for n in lay["points"][f"foot_{s}"])
            out.append(_pitch(r_t.T @ (b - a)))
        return out

    data.qpos[qadr] = robot.standing
    mujoco.mj_forward(model, data)
    standing_pitch = sole_pitch()
    foot_diff: list[float] = []
    foot_robot: list[float] = []
    foot_person: list[float] = []
    t_n = len(motion.angles)
    contact = np.zeros(t_n, bool)
    pairs: dict[str, int] = {}
    lean = np.full(t_n, np.nan)
    roll = np.full(t_n, np.nan)
    arm_err: list[float] = []
    up = np.array([0.0, 1.0, 0.0])
    for t in range(t_n):
        data.qpos[qadr] = motion.angles[t]
        mujoco.mj_forward(model, data)
        for key in contact_pairs(model, data):
            contact[t] = True
            pairs[key] = pairs.get(key, 0) + 1
        r_t = data.xmat[bid[torso]].reshape(3, 3)
        leans, rolls = [], []
        for f in feet:
            z = data.xmat[bid[f]].reshape(3, 3).T @ r_t[:, 2]  # torso up in the sole's frame
            leans.append(np.degrees(np.arctan2(z[0], z[2])))
            rolls.append(np.degrees(np.arctan2(-z[1], z[2])))
        lean[t], roll[t] = float(np.mean(leans)), float(np.mean(rolls))
        if ok[t] and motion.valid[t]:
            for k, (s, p) in enumerate(zip(("left", "right"), sole_pitch(), strict=True)):
                mine = p - standing_pitch[k]
                theirs = _pitch(bones[t, BONE_NAMES.index(f"foot_{s}")]) - flat[s]
                foot_robot.append(mine)
                foot_person.append(theirs)
                foot_diff.append(mine - theirs)
            for s in SIDES:
                for bone in ("upper_arm", "forearm"):
                    a, b = lay["points"][f"{bone}_{s}"]
                    xs = data.site_xpos
                    v = r_t.T @ (xs[site[b]] - xs[site[a]])
                    arm_err.append(float(_angle(v, bones[t, BONE_NAMES.index(f"{bone}_{s}")])))
    use = motion.valid & ok
    trunk = positions[:, J["ShoulderCenter"]] - positions[:, J["HipCenter"]]
    fwd = frames[:, 0, :] - (frames[:, 0, :] @ up)[:, None] * up  # body forward, horizontal
    fwd /= np.maximum(np.linalg.norm(fwd, axis=-1, keepdims=True), 1e-9)
    person_lean = np.degrees(np.arctan2(np.sum(trunk * fwd, -1), trunk @ up))
    ankle = [robot.index(j) for j in lay["ankles"]]
    qa = motion.angles[:, ankle]
    at_limit = (qa <= robot.lower[ankle] + 1e-3) | (qa >= robot.upper[ankle] - 1e-3)
    err = np.asarray(arm_err)
    return {
        "contact_frames": int(contact.sum()),
        "contact_share": round(float(contact.mean()), 4),
        "contact_pairs": dict(sorted(pairs.items(), key=lambda kv: -kv[1])[:8]),
        "lean_robot_median": round(float(np.nanmedian(lean[use])), 1),
        "lean_person_median": round(float(np.nanmedian(person_lean[use])), 1),
        "lean_diff": round(float(np.nanmedian(lean[use]) - np.nanmedian(person_lean[use])), 1),
        "lean_roll_median": round(float(np.nanmedian(np.abs(roll[use]))), 1),
        "ankle_pitch_at_limit_share": round(float(at_limit[use].any(axis=1).mean()), 3),
        "foot_pitch_robot_median": round(float(np.median(foot_robot)), 1) if foot_robot else None,
        "foot_pitch_person_median": round(float(np.median(foot_person)), 1)
        if foot_person
        else None,
        "foot_pitch_diff": round(float(np.median(foot_diff)), 1) if foot_diff else None,
        "arm_median": round(float(np.median(err)), 2) if len(err) else None,
        "arm_p90": round(float(np.percentile(err, 90)), 2) if len(err) else None,
    }


def measure(path: Path, extra: list[str], out_dir: Path, robot_name: str = ROBOT) -> dict:
    robot = robots.get(robot_name)
    out = out_dir / f"{path.stem}.npz"
    t0 = time.perf_counter()
    argv = ["retarget", str(path), "--out", str(out), *extra]
    if "--model" not in extra:
        argv += ["--robot", robot_name]
    code = cli(argv)
    if code != 0:
        return {"file": path.name, "error": f"retarget exited {code}"}
    wall = time.perf_counter() - t0
    motion = load_motion(out, robot=robot)
    positions = np.asarray(motion.positions, np.float32)
    bones, ok, frames = _bones(positions)
    res = {"file": path.name, "frames": len(motion.angles), "retarget_s": round(wall, 1)}
    res |= flips(motion, bones, ok, robot)
    res |= geometry(motion, bones, ok, frames, robot, positions)
    return res


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="*", type=Path)
    p.add_argument("--method", default="ik", choices=("ik", "relaxed", "full"))
    p.add_argument("--model", default=None)
    p.add_argument("--robot", default=ROBOT, help="a registered robot or a robot file (--method "
                   "ik; a model names its own)")  # fmt: skip
    p.add_argument("--json", default=None)
    p.add_argument("--data", type=Path, default=None, help="a folder holding the six files")
    p.add_argument("--extra", default="", help="more retarget options, one string")
    a = p.parse_args(argv)
    extra = ["--method", a.method] + (["--model", a.model] if a.model else []) + a.extra.split()
    files = a.files or default_files(a.data)
    if a.model is not None:  # the model names its robot
        from jaxproj.projection.model_file import read_config

        robot = read_config(a.model).robot
    else:
        robot = robots.get(a.robot).name
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for f in files:
            r = measure(f, extra, Path(tmp), robot)
            rows.append(r)
            print(json.dumps(r), flush=True)
    keys = ("flip_steps", "catch_up_steps", "steps_over_90", "max_step_deg", "contact_frames",
            "lean_diff", "foot_pitch_diff", "arm_median", "arm_p90")  # fmt: skip
    print(f"{'file':24s} " + " ".join(f"{k:>16s}" for k in keys), file=sys.stderr)
    for r in rows:
        print(f"{r['file']:24s} " + " ".join(f"{r.get(k)!s:>16s}" for k in keys), file=sys.stderr)
    if a.json:
        doc = {"method": a.method, "model": a.model, "robot": robot, "rows": rows}
        Path(a.json).write_text(json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
