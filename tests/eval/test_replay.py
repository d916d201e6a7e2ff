"""``jaxproj.eval.replay``: the MJX replay's floor and self depths are MuJoCo's, pose by pose."""

from __future__ import annotations

import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError
from jaxproj.eval import replay

G1 = robots.get("unitree_g1")


def test_the_replay_finds_the_floor_and_self_contacts_mujoco_finds() -> None:
    """Random poses within the limits (arms and legs swung far: some limbs cross), the root
    turned and at heights from 0.2 to 0.8 m (some feet below the floor): the MJX depths are
    MuJoCo's to 0.1 mm, and both kinds occur, so the comparison sees real contacts."""
    rng = np.random.default_rng(3)
    f = 24
    angles = rng.uniform(G1.lower, G1.upper, (f, G1.n_joints))
    pos = np.column_stack([rng.uniform(-1, 1, (f, 2)), rng.uniform(0.2, 0.8, f)])
    yaw = rng.uniform(-np.pi, np.pi, f)
    tilt = rng.uniform(-0.2, 0.2, f)
    # (x, y, z, w): a turn about z, then a small one about x
    s, c = np.sin(tilt / 2), np.cos(tilt / 2)
    rot = np.column_stack([s * np.cos(yaw / 2), s * np.sin(yaw / 2), c * np.sin(yaw / 2),
                           c * np.cos(yaw / 2)])  # fmt: skip
    got = replay.replay_depths(G1, pos, rot, angles)
    assert got.floor_m.shape == got.self_m.shape == (f,)
    ref = replay.host_depths(G1, pos, rot, angles)
    want = np.column_stack([ref.floor_m, ref.self_m])
    assert np.abs(got.floor_m - want[:, 0]).max() < 1e-4
    assert np.abs(got.self_m - want[:, 1]).max() < 1e-4
    assert (want[:, 0] > 1e-3).sum() >= 3 and (want[:, 0] == 0).sum() >= 3
    assert (want[:, 1] > 1e-3).sum() >= 3


def test_the_replay_refuses_what_it_cannot_pose() -> None:
    n = G1.n_joints
    with pytest.raises(ConfigError, match="must be"):
        replay.replay_depths(G1, np.zeros((3, 3)), np.zeros((3, 4)), np.zeros((3, n + 1)))
    q = np.zeros((3, n))
    q[1, 0] = np.nan
    with pytest.raises(ConfigError, match="frame 1 holds NaN"):
        replay.replay_depths(G1, np.zeros((3, 3)), np.tile([0, 0, 0, 1.0], (3, 1)), q)
