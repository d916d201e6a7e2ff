"""The generic IK's rows split over the CPU devices (``jaxproj._internal.shards``): the command
line asks for one device per core, and the split answers equal one device's to the bit; a
thread a device (``shards.on_devices``, a batch's calls spread over the devices) loads the kept
programs for its device.

In a fresh process (a process's device count is fixed when JAX starts), on the small robot
file of the robot-file tests."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import jax

from jaxproj._internal import shards

SCRIPT = Path(__file__).resolve().parent / "scripts" / "shards_check.py"
TWO_ARMS = Path(__file__).resolve().parents[1] / "data" / "robots" / "two_arms" / "robot.toml"


def test_the_split_ik_answers_as_one_device_does() -> None:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env["JAX_PLATFORMS"] = "cpu"
    out = subprocess.run(
        [sys.executable, str(SCRIPT), str(TWO_ARMS)],
        capture_output=True, text=True, env=env, timeout=600, check=False,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    r = json.loads(out.stdout)
    cores = r["cores"]
    assert r["asked"] == (min(cores, shards.MAX_SHARDS) if cores > 1 else None)
    assert r["cpu_devices"] == (r["asked"] or 2) and r["host_shards"] >= 2
    assert r["asked_again"] is None
    assert r["ik_rows"] == 100 and r["ik_max_diff"] == 0.0
    assert r["motion_frames"] > 20 and r["motion_max_diff"] == 0.0
    assert r["kept_and_loaded"]
    # shards.on_devices: a thread a device, and a kept program loaded onto each
    assert r["spread_threads"] == r["kept_on_each"] == sorted(r["devices"][:2])
    assert r["kept_each_right"]
    # a kept program of the rows split over the CPU devices, loaded by the thread of each
    assert r["kept_spread_slots"] == ["0", "1"] and r["kept_spread_right"]


def test_a_running_backend_is_left_alone() -> None:
    jax.devices()  # this process's backends run: the flag could no longer take effect
    before = os.environ.get("XLA_FLAGS")
    assert shards.request_host_devices() is None
    assert os.environ.get("XLA_FLAGS") == before
    assert shards.host_shards() == 1  # the test process has one CPU device
    assert shards.over_rows(abs, 1) is abs
