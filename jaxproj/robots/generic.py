"""The generic IK attached to a robot: what a robot file's ``[ik] kind = "generic"`` gives.

``with_generic_ik(robot, correspondence, config)`` returns the robot with every IK hook filled
from one ``GenericIK`` of its MJCF (``jaxproj.robots.generic_ik``): each chain's ``Chain.ik``
(the IK of that chain alone from its own descriptor columns, the landmarks' ground truth),
``Robot.ik`` (all driven joints from host or device descriptors, compiled once per bucketed
shape), ``traced_ik``, ``separate`` (where the IK has a collision term), ``track`` and
``track_step``, and ``Robot.generic``, the
``GenericSolver`` itself (its correspondence, settings and the built IK), for benchmarks and
experiments that re-build the IK with other settings. No robot writes this glue again.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import numpy as np
from jax.typing import ArrayLike

from jaxproj._internal.buckets import call_bucketed
from jaxproj._internal.jit import jit
from jaxproj._internal.shards import host_shards, over_rows
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import resolve_bones
from jaxproj.robots.base import Robot
from jaxproj.robots.generic_ik import Correspondence, GenericIK, IKConfig, own_chains

Bones = str | tuple[str, ...]


class GenericSolver:
    """One robot's generic IK and the functions ``Robot`` calls (see the module doc).

    The IK is built on first use (it reads the MJCF) and kept; so is each compiled program.

    Attributes:
      correspondence: the robot's table (``Correspondence``).
      config: the solver settings (``IKConfig``).
      robot: the robot it solves for (set by ``with_generic_ik``).
    """

    def __init__(self, correspondence: Correspondence, config: IKConfig) -> None:
        self.correspondence = correspondence
        self.config = config
        self._robot: Robot | None = None

    @property
    def robot(self) -> Robot:
        if self._robot is None:
            raise ConfigError("this GenericSolver is not attached to a robot (with_generic_ik)")
        return self._robot

    @functools.cache  # noqa: B019 (one solver per robot, kept as long as the robot)
    def build(self, collision: bool = True) -> GenericIK:
        """The robot's ``GenericIK`` (built once), with or without the collision term."""
        cfg = self.config if collision else dataclasses.replace(self.config, collision=0.0)
        return GenericIK.build(self.robot, self.correspondence, cfg)

    @functools.cache  # noqa: B019
    def _chain_solver(self, name: str) -> jax.stages.Wrapped:
        robot = self.robot
        chain = robot.chain(name)
        ik = GenericIK.build(
            robot, self.correspondence, self.config, chains=own_chains(robot.chains, chain)
        )
        cols = np.array(robot.chain_joints(chain), np.int32)
        return jit(lambda d: ik.solve(d, chain.bones)[..., cols])

    def chain_ik(self, x: np.ndarray, *, name: str) -> np.ndarray:
        """``Chain.ik`` of the chain ``name``: ``(N, 3 * len(bones))`` its own descriptor columns
        -> ``(N, len(joints))`` angles (the IK of that chain and of the chains it reads before
        it, e.g. the waist for a leg)."""
        fn = self._chain_solver(name)
        return np.asarray(call_bucketed(fn, np.asarray(x, np.float32), 1))

    def traced_ik(self, d: jax.Array, bones: Bones = "full") -> jax.Array:
        """The IK inside a trace: ``(..., 3 * n_bones)`` -> ``(..., n_driven)`` angles, rad."""
        return self.build().solve(d, bones)

    def track(
        self,
        q: jax.Array,
        valid: jax.Array,
        d: jax.Array | None = None,
        bones: Bones = "full",
        shards: int = 1,
    ) -> jax.Array:
        """``Robot.track``: ``(T, n_driven)`` per-frame answers, ``(T,)`` valid and the person's
        ``(T, m)`` descriptors (or ``None``) -> ``(T, n_driven)``, each frame re-chosen near the
        previous output among the poses with the same bone directions
        (``GenericIK.track``; ``shards``: CPU devices it may use, the same answers).
        Traceable."""
        return self.build().track(q, valid, d, bones, shards=shards)

    def track_step(
        self,
        y: jax.Array,
        q_prev: jax.Array,
        q_t: jax.Array,
        d_prev: jax.Array,
        d_t: jax.Array,
        bones: Bones = "full",
    ) -> jax.Array:
        """``Robot.track_step``: one frame of ``track`` from the last output, the last valid
        answer, this frame's answer (``(n_driven,)`` each) and the person's last valid and
        current ``(m,)`` descriptors of ``bones`` (``GenericIK.track_step``). Traceable."""
        return self.build().track_step(y, q_prev, q_t, None, (d_prev, d_t, resolve_bones(bones)))

    def track_bounds(self, valid: jax.Array, d: jax.Array, bones: Bones = "full") -> jax.Array:
        """``Robot.track_bounds``: ``(T,)`` valid and the person's ``(T, m)`` descriptors ->
        ``(T, n_driven)`` each joint's step bound into each frame (``GenericIK.step_bounds``).
        Traceable."""
        return self.build().step_bounds(valid, d, bones)

    def separate(self, q: jax.Array, start: jax.Array | None = None) -> jax.Array:
        """``Robot.separate``: ``(..., n_driven)`` angles (and optionally a second start per
        pose) -> the same with the collision pairs pushed ``config.margin`` apart
        (``GenericIK.separate``). Traceable."""
        return self.build().separate(q, start=start)

    @functools.cache  # noqa: B019
    def _jitted(self, bones: Bones, shards: int = 1) -> jax.stages.Wrapped:
        return jit(over_rows(lambda d: self.build().solve(d, bones), shards))

    def solve_driven(self, d: ArrayLike, bones: Bones = "full") -> jax.Array:
        """``Robot.ik``: ``(..., 3 * n_bones)`` descriptors (``bones`` layout, holding every bone
        of the chains) -> ``(..., n_driven)`` float32 driven angles, rad, within limits, finite.

        Compiled once per shape; host arrays are padded to a bucket of rows (one compile each)
        and, in a process with several CPU devices, their rows split over them
        (``jaxproj._internal.shards``; the same answers).
        """
        if isinstance(d, jax.Array):
            return self._jitted(bones)(d)
        x = np.asarray(d, np.float32)
        if x.ndim == 0:
            raise ConfigError(f"descriptors must be (..., 3 * n_bones), got a scalar {x!r}")
        # the buckets are multiples of MIN_ROWS (64) rows, so of any number of shards
        return call_bucketed(self._jitted(bones, host_shards()), x, 1)


def with_generic_ik(robot: Robot, correspondence: Correspondence, config: IKConfig) -> Robot:
    """``robot`` with its IK hooks from one ``GenericSolver`` (see the module doc). A robot
    whose hooks are generic already gets new ones (a variant with another table or settings:
    the experiments' way to re-build the IK).

    Raises:
      ConfigError: the robot has an IK of its own (not the generic one).
    """
    if robot.generic is None and (robot.ik is not None or robot.traced_ik is not None):
        raise ConfigError(f"robot {robot.name!r} has an IK of its own; give one without")
    solver = GenericSolver(correspondence, config)
    chains = tuple(
        dataclasses.replace(c, ik=functools.partial(solver.chain_ik, name=c.name))
        for c in robot.chains
    )
    pairs = correspondence.collision_pairs
    colliding = config.collision > 0 and (pairs == "mjcf" or len(pairs) > 0)
    out = dataclasses.replace(
        robot,
        chains=chains,
        ik=solver.solve_driven,
        traced_ik=solver.traced_ik,
        separate=solver.separate if colliding else None,  # nothing to push apart without
        track=solver.track,
        track_step=solver.track_step,
        track_bounds=solver.track_bounds,
        generic=solver,
    )
    solver._robot = out
    return out
