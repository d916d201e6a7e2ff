"""A toy robot that proves the robot seam: 9 joints (a waist held still, 2 head, 3 per arm).

Everything a ``Robot`` needs, and nothing of the NAO: its own joint names, limits and posture,
five chains unlike the NAO's (gaze; each shoulder; each elbow) with their own closed-form IK from
bone directions, and
a tiny MJCF (written to a folder the caller names) with the arm sites the task-space metrics read.

Kinematics (torso frame: x forward, y left, z up; both arms alike, shoulders at ``y = +-0.1``):
an arm hangs along ``-z`` at zero; the upper arm is ``Ry(pitch) Rx(roll) (0, 0, -1)`` and the
forearm ``Ry(pitch) Rx(roll) Ry(elbow) (0, 0, -1)``; both segments are ``LINK`` m long. The
head's angles follow the neck bone as the NAO's do: ``yaw = atan2(n_y, n_z)``,
``pitch = atan2(n_x, n_z)``.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Literal

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj.human.skeleton import resolve_bones
from jaxproj.robots import Chain, Mjcf, Robot

JOINTS = (
    "waist", "head_yaw", "head_pitch",
    "l_shoulder_pitch", "l_shoulder_roll", "l_elbow",
    "r_shoulder_pitch", "r_shoulder_roll", "r_elbow",
)  # fmt: skip
DRIVEN = JOINTS[1:]
LOWER = np.array([-1.0, -1.5, -0.6, -2.0, -0.3, 0.0, -2.0, -1.3, 0.0], np.float32)
UPPER = np.array([1.0, 1.5, 0.6, 2.0, 1.3, 2.0, 2.0, 0.3, 2.0], np.float32)
STANDING = np.array([0.0, 0.0, 0.0, 0.0, 0.1, 0.2, 0.0, -0.1, 0.2], np.float32)
LINK = 0.1
SHOULDER_Y = 0.1

ARM_SITES = {
    "left": ("l_shoulder", "l_elbow", "l_wrist"),
    "right": ("r_shoulder", "r_elbow", "r_wrist"),
}

_ARM = """
      <body name="{s}_upper" pos="0 {y} 0">
        <joint name="{s}_shoulder_pitch" axis="0 1 0" range="-2 2"/>
        <joint name="{s}_shoulder_roll" axis="1 0 0" range="{rlo} {rhi}"/>
        <geom type="sphere" size="0.02" pos="0 0 -0.05" mass="0.1" contype="0" conaffinity="0"/>
        <site name="{s}_shoulder" pos="0 0 0"/>
        <body name="{s}_fore" pos="0 0 -{L}">
          <joint name="{s}_elbow" axis="0 1 0" range="0 2"/>
          <geom type="sphere" size="0.02" pos="0 0 -0.05" mass="0.1" contype="0" conaffinity="0"/>
          <site name="{s}_elbow" pos="0 0 0"/>
          <site name="{s}_wrist" pos="0 0 -{L}"/>
        </body>
      </body>"""

MJCF_XML = f"""<mujoco model="toy">
  <worldbody>
    <body name="torso">
      <geom type="box" size="0.05 0.08 0.1" mass="1" contype="0" conaffinity="0"/>
      <body name="hips" pos="0 0 -0.12">
        <joint name="waist" axis="0 0 1" range="-1 1"/>
        <geom type="sphere" size="0.03" mass="0.2" contype="0" conaffinity="0"/>
      </body>
      <body name="head" pos="0 0 0.15">
        <joint name="head_yaw" axis="0 0 1" range="-1.5 1.5"/>
        <joint name="head_pitch" axis="0 1 0" range="-0.6 0.6"/>
        <geom type="sphere" size="0.04" mass="0.2" contype="0" conaffinity="0"/>
      </body>{_ARM.format(s="l", y=SHOULDER_Y, rlo=-0.3, rhi=1.3, L=LINK)}{
    _ARM.format(s="r", y=-SHOULDER_Y, rlo=-1.3, rhi=0.3, L=LINK)
}
    </body>
  </worldbody>
</mujoco>
"""


def _unit(v: jax.Array) -> jax.Array:
    n = jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True))
    return v / jnp.maximum(n, 1e-9)


def _head(x: jax.Array) -> jax.Array:
    """``(N, 3)`` neck directions -> ``(N, 2)`` (yaw, pitch), clipped (traceable)."""
    n = _unit(jnp.asarray(x, jnp.float32))
    yaw = jnp.clip(jnp.arctan2(n[..., 1], n[..., 2]), LOWER[1], UPPER[1])
    pitch = jnp.clip(jnp.arctan2(n[..., 0], n[..., 2]), LOWER[2], UPPER[2])
    return jnp.stack([yaw, pitch], axis=-1)


def _arm(x: jax.Array, side: Literal["l", "r"]) -> jax.Array:
    """``(N, 6)`` upper arm and forearm directions -> ``(N, 3)`` (pitch, roll, elbow), clipped
    (traceable)."""
    x = jnp.asarray(x, jnp.float32)
    u, f = _unit(x[..., :3]), _unit(x[..., 3:])
    pitch = jnp.arctan2(-u[..., 0], -u[..., 2])
    roll = jnp.arctan2(u[..., 1], jnp.sqrt(u[..., 0] ** 2 + u[..., 2] ** 2))
    cross = jnp.cross(u, f)
    elbow = jnp.arctan2(jnp.sqrt(jnp.sum(cross * cross, axis=-1)), jnp.sum(u * f, axis=-1))
    k = JOINTS.index(f"{side}_shoulder_pitch")
    out = jnp.stack([pitch, roll, elbow], axis=-1)
    lo = jnp.broadcast_to(LOWER[k : k + 3], out.shape)
    return jnp.clip(out, lo, jnp.broadcast_to(UPPER[k : k + 3], out.shape))


def head_ik(x: np.ndarray) -> np.ndarray:
    """``(N, 3)`` neck directions -> ``(N, 2)`` (yaw, pitch), clipped to the limits."""
    return np.asarray(_head(x))


def arm_ik(x: np.ndarray, side: Literal["l", "r"]) -> np.ndarray:
    """``(N, 6)`` upper arm and forearm directions -> ``(N, 3)`` (pitch, roll, elbow)."""
    return np.asarray(_arm(x, side))


def shoulder_ik(x: np.ndarray, side: Literal["l", "r"]) -> np.ndarray:
    """``(N, 3)`` upper arm directions -> ``(N, 2)`` (pitch, roll): they fix it alone."""
    x = np.asarray(x, np.float32)
    return np.asarray(_arm(np.concatenate([x, x], axis=-1), side))[:, :2]


def elbow_ik(x: np.ndarray, side: Literal["l", "r"]) -> np.ndarray:
    """``(N, 6)`` upper arm and forearm directions -> ``(N, 1)`` elbow."""
    return np.asarray(_arm(x, side))[:, 2:]


CHAINS = (
    Chain("gaze", ("neck",), DRIVEN[:2], head_ik),
    Chain("left_shoulder", ("upper_arm_left",), DRIVEN[2:4], partial(shoulder_ik, side="l")),
    Chain("left_elbow", ("upper_arm_left", "forearm_left"), DRIVEN[4:5],
          partial(elbow_ik, side="l")),
    Chain("right_shoulder", ("upper_arm_right",), DRIVEN[5:7], partial(shoulder_ik, side="r")),
    Chain("right_elbow", ("upper_arm_right", "forearm_right"), DRIVEN[7:],
          partial(elbow_ik, side="r")),
)  # fmt: skip
"""Five chains, none called ``head`` and none an arm: a chain set unlike the NAO's (head, left
arm, right arm), so that nothing in the seam leans on the NAO's chain names or count."""
_CORES = (_head, partial(_arm, side="l"), partial(_arm, side="r"))
_CORE_BONES = (("neck",), ("upper_arm_left", "forearm_left"), ("upper_arm_right", "forearm_right"))


def solve_driven(d: jax.Array, bones: str | tuple[str, ...] = "upper") -> jax.Array:
    """``(N, 3 * n_bones)`` descriptors -> ``(N, 8)`` driven angles (the chains side by side).

    Pure ``jnp`` (traceable): the toy's IK runs inside the jitted motion pipeline too.
    """
    names = resolve_bones(bones)
    d = jnp.asarray(d, jnp.float32)
    parts = []
    for bones, core in zip(_CORE_BONES, _CORES, strict=True):
        cols = [3 * names.index(b) + i for b in bones for i in range(3)]
        parts.append(core(d[..., cols]))
    return jnp.concatenate(parts, axis=-1)


def arm_fk(q: np.ndarray) -> np.ndarray:
    """Independent FK: ``(F, 9)`` -> ``(F, 2, 3, 3)`` shoulder / elbow / wrist points (float64)."""
    q = np.asarray(q, np.float64)

    def ry(a: np.ndarray) -> np.ndarray:
        c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
        return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                         np.stack([-s, z, c], -1)], -2)  # fmt: skip

    def rx(a: np.ndarray) -> np.ndarray:
        c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
        return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1),
                         np.stack([z, s, c], -1)], -2)  # fmt: skip

    down = np.array([0.0, 0.0, -LINK])
    out = np.zeros((len(q), 2, 3, 3))
    for i, (side, y) in enumerate((("l", SHOULDER_Y), ("r", -SHOULDER_Y))):
        k = JOINTS.index(f"{side}_shoulder_pitch")
        upper = ry(q[:, k]) @ rx(q[:, k + 1])
        shoulder = np.array([0.0, y, 0.0])
        elbow = shoulder + upper @ down
        wrist = elbow + (upper @ ry(q[:, k + 2])) @ down
        out[:, i] = np.stack([np.broadcast_to(shoulder, elbow.shape), elbow, wrist], axis=1)
    return out


def _load(path: Path, mount: str = "fixed", without: tuple[str, ...] = ()) -> mujoco.MjModel:
    """The toy MJCF (its base is fixed whatever ``mount``), less the bodies ``without``."""
    spec = mujoco.MjSpec.from_file(str(path))
    for name in without:
        spec.delete(spec.body(name))
    return spec.compile()


def make_toy_robot(folder: Path | None = None, name: str = "toy") -> Robot:
    """The toy ``Robot``; with ``folder``, its MJCF is written there and attached."""
    mjcf = None
    if folder is not None:
        path = Path(folder) / "toy.xml"
        path.write_text(MJCF_XML)
        mjcf = Mjcf(path=path, load=partial(_load, path), arm_sites=ARM_SITES,
                    fk_without=("hips", "head"))  # fmt: skip
    return Robot(
        name=name,
        title="Toy robot (tests)",
        joint_names=JOINTS,
        lower=LOWER,
        upper=UPPER,
        standing=STANDING,
        driven_joints=DRIVEN,
        chains=CHAINS,
        ik=solve_driven,
        velocity_limits=np.full(len(JOINTS), 5.0, np.float32),
        loose_joints=("l_elbow", "r_elbow"),
        mjcf=mjcf,
    )
