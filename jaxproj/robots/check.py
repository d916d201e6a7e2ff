"""What ``jaxproj robot check`` and ``jaxproj robot show`` say about a robot.

Reading a robot file already refuses a broken one (``robot_file``: unknown keys and names,
limits that disagree with the MJCF, a chain that reads no row, a row that no chain reads).
``problems(robot)`` adds what only the kinematics show: a driven joint that changes none of
the rows its chain reads (the bones cannot see it: only the pull toward standing sets it), and
self-contact in the standing posture (two of the robot's own geoms deeper than
``CONTACT_DEPTH`` into each other, by MuJoCo's contact filter). ``describe(robot)`` is the body
tree, the joints with their limits and speeds, and per chain the rows it reads.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from jaxproj.robots.base import Robot, joint_qpos_index
from jaxproj.robots.generic_ik import chain_rows, mjcf_collision_pairs
from jaxproj.robots.kinematics import points_at

CONTACT_DEPTH = 1e-3
"""m: a standing-posture contact deeper than this is a problem (the rollouts' threshold)."""


def standing_contacts(robot: Robot) -> list[tuple[str, str, float]]:
    """``(geom, geom, depth m)`` of every pair of the robot's own geoms in contact deeper than
    ``CONTACT_DEPTH`` in the standing posture (its MJCF as written, MuJoCo's contact filter:
    a body and its parent do not collide), the deepest point per pair; empty for a robot
    without an MJCF."""
    if robot.mjcf is None:
        return []
    model = robot.load_model("free")
    data = mujoco.MjData(model)
    data.qpos[joint_qpos_index(model, robot.joint_names)] = robot.standing
    mujoco.mj_forward(model, data)
    deepest: dict[tuple[str, str], float] = {}
    for c in data.contact[: data.ncon]:
        g = [int(x) for x in c.geom]
        if c.dist < -CONTACT_DEPTH and all(model.geom_bodyid[x] > 0 for x in g):  # not the world
            key = (model.geom(g[0]).name or f"geom {g[0]}", model.geom(g[1]).name or f"geom {g[1]}")
            deepest[key] = max(deepest.get(key, 0.0), float(-c.dist))
    return [(a, b, d) for (a, b), d in deepest.items()]


def unobservable(robot: Robot, samples: int = 8, seed: int = 0) -> list[tuple[str, str]]:
    """``(chain, joint)`` of every chain joint that turns none of the rows the chain reads
    (``generic_ik.chain_rows``), numerically: at ``samples`` postures within the limits
    (``seed``) a 1e-3 rad turn of the joint moves no row's unit direction by more than 1e-7
    (so a hinge about a limb's own axis counts, as a link's twist does); empty for a robot
    without the generic IK."""
    if robot.generic is None:
        return []
    corr = robot.generic.correspondence
    model = robot.load_model("fixed")
    rng = np.random.default_rng(seed)
    poses = rng.uniform(robot.lower, robot.upper, (samples, robot.n_joints))
    out: list[tuple[str, str]] = []
    for chain in robot.chains:
        rows = chain_rows(model, corr, chain)
        points = [p for r in rows for p in (r.start, r.end)]

        def directions(q: np.ndarray, points: list = points) -> np.ndarray:
            x = points_at(model, robot.joint_names, q, points, corr.base).reshape(-1, 2, 3)
            v = x[:, 1] - x[:, 0]
            return v / np.linalg.norm(v, axis=1, keepdims=True)

        for joint in chain.joints:
            k = robot.index(joint)
            seen = False
            for q in poses:
                step = q.copy()
                step[k] += 1e-3 if q[k] + 1e-3 <= robot.upper[k] else -1e-3
                seen |= bool(np.abs(directions(step) - directions(q)).max() > 1e-7)
            if not seen:
                out.append((chain.name, joint))
    return out


def problems(robot: Robot) -> list[str]:
    """One line per problem (see the module doc); empty: none found."""
    lines = [
        f"chain {chain!r}: the joint {joint!r} changes the direction of none of the rows the "
        "chain reads: no bone can set it (add a row it turns, or leave it undriven)"
        for chain, joint in unobservable(robot)
    ]
    lines += [
        f"standing posture: the geoms {a!r} and {b!r} are {1000 * depth:.1f} mm inside each "
        "other (move the geoms, or exclude the pair in the MJCF's <contact>)"
        for a, b, depth in standing_contacts(robot)
    ]
    return lines


def _deg(x: float) -> str:
    return f"{math.degrees(x):.1f}"


def describe(robot: Robot) -> str:
    """The robot as text: file, body tree with joints, joints (limits deg, speed rad/s,
    driven), chains with the rows each reads, collision pairs."""
    lines = [f"{robot.name}: {robot.title}"]
    if robot.file is not None:
        lines.append(f"  file: {robot.file}")
    if robot.mjcf is None:
        return "\n".join(lines)
    lines.append(f"  mjcf: {robot.mjcf.path}")
    model = robot.load_model("fixed")
    lines.append("body tree (joints):")
    depth = {0: -1}
    for b in range(1, model.nbody):
        depth[b] = depth[int(model.body_parentid[b])] + 1
        first, n = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        joints = ", ".join(model.joint(first + k).name for k in range(n))
        lines.append(f"  {'  ' * depth[b]}{model.body(b).name}" + (f" ({joints})" if n else ""))
    v = robot.velocity_limits
    lines.append(f"joints ({robot.n_joints}, {robot.n_driven} driven): name, limits deg, rad/s")
    for i, j in enumerate(robot.joint_names):
        speed = "-" if v is None else f"{v[i]:g}"
        mark = " driven" if j in robot.driven_joints else ""
        loose = " loose" if j in robot.loose_joints else ""
        lines.append(f"  {i:2d} {j} [{_deg(robot.lower[i])}, {_deg(robot.upper[i])}] "
                     f"{speed}{mark}{loose}")  # fmt: skip
    if robot.generic is not None:
        corr = robot.generic.correspondence
        lines.append(f"chains (solved in this order; directions in the frame of {corr.base!r}):")
        for chain in robot.chains:
            lines.append(f"  {chain.name}: joints {', '.join(chain.joints)}")
            for row in chain_rows(model, corr, chain):
                bone = row.bone if row.minus is None else f"{row.bone} - {row.minus}"
                lines.append(f"    reads {bone}: {row.start} -> {row.end} (weight {row.weight:g})")
        pairs = corr.collision_pairs
        n = len(mjcf_collision_pairs(model)) if isinstance(pairs, str) else len(pairs)
        lines.append(f"collision pairs: {n}" + (" (the MJCF's)" if isinstance(pairs, str) else ""))
    else:
        lines.append("chains: " + ", ".join(f"{c.name} ({', '.join(c.joints)})"
                                            for c in robot.chains))  # fmt: skip
    return "\n".join(lines) + "\n" + _standing_line(robot)


def _standing_line(robot: Robot) -> str:
    q = robot.standing
    moved = np.flatnonzero(q != 0)
    if not len(moved):
        return "standing posture: every joint at 0"
    return "standing posture: " + ", ".join(f"{robot.joint_names[i]} {_deg(q[i])}" for i in moved)
