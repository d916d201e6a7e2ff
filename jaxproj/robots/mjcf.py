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
