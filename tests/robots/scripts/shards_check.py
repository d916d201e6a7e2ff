"""Run by tests/robots/test_shards.py in a fresh process: the command line's start asks for one
CPU device per core (``request_host_devices``; two are forced where the machine has one core),
and the generic IK split over them answers as on one device, in ``Robot.ik`` and in
``retarget``. Prints one JSON object."""

import json
import os
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

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
    robot = robots.get(Path(sys.argv[1]))  # registered: its programs can be kept
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1]))[:100]
    split = np.asarray(robot.ik(d, "upper"))  # host rows: padded to 128, split over the devices
    one = np.asarray(jax.jit(lambda x: robot.traced_ik(x, "upper"))(np.asarray(d, np.float32)))
    seq = datasets.msr_action3d(subjects=[1], actions=[1])[0]
    split_motion = retarget_module.retarget(seq.positions, seq.valid, robot=robot).angles
    retarget_module.host_shards = lambda: 1  # the same call on one device
    one_motion = retarget_module.retarget(seq.positions, seq.valid, robot=robot).angles
    seen: dict[int, str] = {}
    # `on_devices` hands items to whichever thread asks next: a thread done quickly could take
    # both items (seen in the suite, 2026-11-30). Each thread waits here for the other, so each
    # takes one item before either is done.
    both = threading.Barrier(2, timeout=120)

    def note(i: int) -> None:
        if i < 2:
            both.wait()
        seen[i] = str(jax.config.jax_default_device)

    shards.on_devices(note, range(4), jax.devices())
    # a kept one-device program, loaded again in this process of several devices (a loaded
    # program is told its devices; left alone it took them all and refused its arguments)
    with tempfile.TemporaryDirectory() as tmp, executables.kept_in(Path(tmp)):
        double = jax.jit(lambda x: 2.0 * x)
        x = np.arange(4, dtype=np.float32)
        kept = np.asarray(executables.call(double, (x,), name="double", identity=("t",)))
        executables._LOADED.clear()
        loaded = np.asarray(executables.call(double, (x,), name="double", identity=("t",)))
        # the kept program loaded onto each device by a thread of its own
        each: dict[int, Any] = {}

        def twice(i: int) -> None:
            both.wait()
            each[i] = executables.call(double, (x + i,), name="double", identity=("t",))

        shards.on_devices(twice, range(2), jax.devices()[::-1])
        on_each = sorted(str(next(iter(v.devices()))) for v in each.values())
        # a program split over the CPU devices (a batch's IK rows, `over_rows`), kept, then
        # loaded by a thread a device onto its own devices (remapped onto the thread's one
        # device, XLA aborted the process: 2026-11-30)
        split_double = jax.jit(shards.over_rows(lambda r: 2.0 * r, 2))
        rows = np.arange(8, dtype=np.float32).reshape(4, 2)
        executables.call(split_double, (rows,), name="split", identity=("t",))
        executables._LOADED.clear()
        spread: dict[int, Any] = {}

        def split_twice(i: int) -> None:
            both.wait()
            spread[i] = executables.call(split_double, (rows + i,), name="split", identity=("t",))

        shards.on_devices(split_twice, range(2), jax.devices())
        kept_slots = sorted(str(k[1]) for k in executables._LOADED if k[0].name.startswith("split"))
        spread_right = all(np.asarray(v).tolist() == (2 * (rows + i)).tolist()
                           for i, v in spread.items())  # fmt: skip
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
        "kept_on_each": on_each,
        "kept_each_right": all(np.asarray(v).tolist() == (2 * (x + i)).tolist()
                               for i, v in each.items()),
        "devices": [str(d) for d in jax.devices()],
        "spread_threads": sorted(set(seen.values())),
        "kept_spread_slots": kept_slots,
        "kept_spread_right": spread_right,
    }))  # fmt: skip


if __name__ == "__main__":
    main()
