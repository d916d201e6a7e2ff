"""Run by tests/robots/test_shards.py in a fresh process: the command line's start asks for one
CPU device per core (``request_host_devices``; two are forced where the machine has one core),
and the generic IK split over them answers as on one device, in ``Robot.ik`` and in
``retarget``. Prints one JSON object."""

import json
import os
import sys
import tempfile
from pathlib import Path

from jaxproj._internal import shards

asked = shards.request_host_devices()  # before anything starts JAX's backends, as main() does
if asked is None:  # one core: two devices all the same, for the comparison below
    os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=2"

import jax  # noqa: E402
import numpy as np  # noqa: E402

from jaxproj import robots  # noqa: E402
from jaxproj._internal import executables  # noqa: E402
from jaxproj.io import datasets  # noqa: E402
from jaxproj.motion import retarget as retarget_module  # noqa: E402


def main() -> None:
    robot = robots.load(Path(sys.argv[1]))
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1]))[:100]
    split = np.asarray(robot.ik(d, "upper"))  # host rows: padded to 128, split over the devices
    one = np.asarray(jax.jit(lambda x: robot.traced_ik(x, "upper"))(np.asarray(d, np.float32)))
    seq = datasets.msr_action3d(subjects=[1], actions=[1])[0]
    split_motion = retarget_module.retarget(seq.positions, seq.valid, robot=robot).angles
    retarget_module.host_shards = lambda: 1  # the same call on one device
    one_motion = retarget_module.retarget(seq.positions, seq.valid, robot=robot).angles
    # a kept one-device program, loaded again in this process of several devices (a loaded
    # program is told its devices; left alone it took them all and refused its arguments)
    with tempfile.TemporaryDirectory() as tmp, executables.kept_in(Path(tmp)):
        double = jax.jit(lambda x: 2.0 * x)
        x = np.arange(4, dtype=np.float32)
        kept = np.asarray(executables.call(double, (x,), name="double", identity=("t",)))
        executables._LOADED.clear()
        loaded = np.asarray(executables.call(double, (x,), name="double", identity=("t",)))
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(json.dumps({
        "asked": asked,
        "cores": cores,
        "cpu_devices": len(jax.devices("cpu")),
        "host_shards": shards.host_shards(),
        "asked_again": shards.request_host_devices(),  # the backends run now: no effect
        "ik_rows": len(split),
        "ik_max_diff": float(np.abs(split - one).max()),
        "motion_frames": len(split_motion),
        "motion_max_diff": float(np.abs(split_motion - one_motion).max()),
        "kept_and_loaded": kept.tolist() == loaded.tolist() == [0.0, 2.0, 4.0, 6.0],
    }))  # fmt: skip


if __name__ == "__main__":
    main()
