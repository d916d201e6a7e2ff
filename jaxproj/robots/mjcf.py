"""Compiling a robot's MJCF with a free or a fixed base, and without some subtrees.

``load(path, mount, without, free_joint=..., root_body=...)`` is every robot's ``Mjcf.load``:
``mount="free"`` compiles the file as it is (the root body carries the free joint);
``mount="fixed"`` deletes the free joint, so the root body is welded to the world at its
``qpos0`` pose, and ``without`` deletes bodies with their subtrees and everything that refers
to them (actuators, equalities, contact excludes). With the base welded the subtrees share no
degree of freedom, so each part keeps exactly the dynamics it has in the whole model, less the
contacts across parts.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from jaxproj.errors import ConfigError, InputError

MOUNTS: tuple[str, ...] = ("free", "fixed")
"""The base mounts ``load`` accepts."""


def load(
    path: Path,
    mount: str = "free",
    without: Sequence[str] = (),
    *,
    free_joint: str,
    root_body: str,
) -> mujoco.MjModel:
    """Compile the MJCF at ``path`` (see the module doc).

    Raises:
      ConfigError: ``mount`` is not in ``MOUNTS``; ``without`` with the free mount, or naming a
        body the model does not have (or the root body).
      InputError: the file is missing, lacks ``free_joint``, or MuJoCo cannot compile it.
    """
    if mount not in MOUNTS:
        raise ConfigError(f"mount must be one of {MOUNTS}, got {mount!r}")
    without = tuple(without)
    if without and mount != "fixed":
        raise ConfigError(f"without= needs the fixed mount, got {mount!r}")
    if not path.is_file():
        raise InputError(path, "bundled MJCF model is missing")
    try:
        if mount == "free":
            return mujoco.MjModel.from_xml_path(str(path))
        spec = mujoco.MjSpec.from_file(str(path))
        root = spec.joint(free_joint)
        if root is None:
            raise InputError(path, f"no free joint named {free_joint!r} to remove")
        spec.delete(root)
        remove_subtrees(spec, without, root_body)
        return spec.compile()
    except ValueError as err:  # mujoco reports XML / compile errors as ValueError
        if isinstance(err, (InputError, ConfigError)):
            raise
        raise InputError(path, f"MuJoCo cannot compile the model ({mount} mount): {err}") from err


def remove_subtrees(spec: mujoco.MjSpec, roots: Sequence[str], root_body: str) -> None:
    """Delete the bodies ``roots`` with their subtrees and whatever refers to them, in place."""
    bodies: set[str] = set()
    joints: set[str] = set()
    for name in roots:
        body = spec.body(name)
        if body is None or name == root_body:
            raise ConfigError(f"without= names {name!r}, which is not a removable body of the "
                              "model")  # fmt: skip
        stack = [body]
        while stack:
            b = stack.pop()
            bodies.add(b.name)
            joints.update(j.name for j in b.joints)
            stack.extend(b.bodies)
    for act in list(spec.actuators):
        if act.target in joints:
            spec.delete(act)
    for eq in list(spec.equalities):
        if eq.name1 in joints or eq.name2 in joints or eq.name1 in bodies or eq.name2 in bodies:
            spec.delete(eq)
    for ex in list(spec.excludes):
        if ex.bodyname1 in bodies or ex.bodyname2 in bodies:
            spec.delete(ex)
    for name in roots:
        spec.delete(spec.body(name))


def torque_accelerations(
    model: mujoco.MjModel,
    joint_names: Sequence[str],
    lower: np.ndarray,
    upper: np.ndarray,
    samples: int = 4096,
    seed: int = 0,
) -> np.ndarray:
    """Per joint, the acceleration its motor's peak torque gives the limb it moves at that
    limb's most inertial posture: ``tau_max / max_q M_jj(q)`` (rad/s^2), ``M`` the joint-space
    inertia (armature included) of ``model`` as compiled (a fixed base: the limb alone),
    ``tau_max`` the larger end of the joint's actuator ``forcerange``, the maximum over
    ``samples`` postures drawn uniformly within ``[lower, upper]`` (``seed``) and the zero
    posture. Gravity, the other joints' coupling and a standing robot's own weight are left
    out: an upper bound on what the joint can do, not what it does under load.

    Args:
      model: a compiled MJCF with one actuator (with a ``forcerange``) per joint.
      joint_names: ``(n,)`` the joints, in the order of the answer.
      lower, upper: ``(n,)`` their limits, rad.

    Returns:
      ``(n,)`` float32 rad/s^2.

    Raises:
      ConfigError: a joint the model lacks, or without an actuator with a torque range.
    """
    adr, dof, tau = [], [], []
    for name in joint_names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise ConfigError(f"the MJCF has no joint named {name!r}")
        acts = [a for a in range(model.nu) if int(model.actuator_trnid[a, 0]) == jid]
        peak = max((float(np.max(np.abs(model.actuator_forcerange[a]))) for a in acts), default=0)
        if not peak > 0:
            raise ConfigError(f"joint {name!r}: no actuator with a forcerange (peak torque)")
        adr.append(int(model.jnt_qposadr[jid]))
        dof.append(int(model.jnt_dofadr[jid]))
        tau.append(peak)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(lower, np.float64), np.asarray(upper, np.float64)
    poses = np.concatenate([np.zeros((1, len(adr))), rng.uniform(lo, hi, (samples, len(adr)))])
    full = np.zeros((model.nv, model.nv))
    most = np.zeros(len(adr))
    for q in poses:
        data.qpos[adr] = q
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        most = np.maximum(most, full[dof, dof])
    return (np.asarray(tau) / most).astype(np.float32)
