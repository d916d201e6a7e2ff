"""``jaxproj info``: versions, devices, the robot model, the bundled datasets and the
compilation cache's folder and size."""

from __future__ import annotations

import argparse
import json
import os
from typing import Any

from jaxproj import __version__
from jaxproj.cli import cache, options


def add_parsers(sub: Any) -> None:
    p = options.add_parser(sub, "info", "versions, devices, robot model and bundled data")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def collect() -> dict:
    """What ``jaxproj info`` reports, as JSON-ready data."""
    import jax
    import mujoco

    from jaxproj import robots
    from jaxproj.io import datasets

    robot = robots.get()  # the default robot

    from jaxproj._internal.mujoco_gl import gl_failure

    folder = cache.active_folder()
    files, size = cache.usage(folder)
    msr = datasets.dataset_summary("msr")
    utk = datasets.dataset_summary("utkinect")
    return {
        "jaxproj": __version__,
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "devices": [str(d) for d in jax.devices()],
        "rendering": {
            "mujoco_gl": os.environ.get("MUJOCO_GL", ""),
            "mujoco_available": gl_failure() is None,
            "problem": gl_failure(),
        },
        "robot": {
            "name": robot.title,
            "mjcf": str(robot.require_mjcf().path.resolve()),
            "joints": list(robot.joint_names),
            "driven_joints": list(robot.driven_joints),
        },
        "compilation_cache": {
            "folder": None if folder is None else str(folder),
            "files": files,
            "bytes": size,
        },
        "datasets": {
            "msr_action3d": {k: msr[k] for k in ("sequences", "frames", "subjects")},
            "utkinect_action3d": {
                k: utk[k] for k in ("recordings", "frames", "subjects", "segments")
            },
        },
    }


def rendering_line(r: dict) -> str:
    """``collect()["rendering"]`` in words: the MuJoCo OpenGL back-end, or why it is missing."""
    gl = r["mujoco_gl"]
    gl = f"MUJOCO_GL={gl}" if gl else "MUJOCO_GL unset (GLFW, needs a display)"
    if r["mujoco_available"]:
        return f"MuJoCo OpenGL, {gl} (a context is created when rendering; else matplotlib)"
    return (
        f"MuJoCo OpenGL unavailable: {r['problem']}; `jaxproj render` draws the robot with "
        "matplotlib (--backend matplotlib), or install the back-end / change MUJOCO_GL"
    )


def run(args: argparse.Namespace) -> int:
    info = collect()
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"jaxproj {info['jaxproj']}  (jax {info['jax']}, mujoco {info['mujoco']})")
    print(f"devices: {', '.join(info['devices'])}")
    print(f"rendering: {rendering_line(info['rendering'])}")
    r = info["robot"]
    print(f"robot: {r['name']}, {len(r['joints'])} joints, mjcf {r['mjcf']}")
    print(f"driven joints ({len(r['driven_joints'])}): {', '.join(r['driven_joints'])}")
    m = info["datasets"]["msr_action3d"]
    print(
        f"dataset msr_action3d (--data msr): {m['sequences']} sequences, {m['frames']} frames, "
        f"{m['subjects']} subjects"
    )
    u = info["datasets"]["utkinect_action3d"]
    print(
        f"dataset utkinect_action3d (--data utkinect): {u['recordings']} recordings, "
        f"{u['frames']} frames, {u['subjects']} subjects, {u['segments']} action segments"
    )
    c = info["compilation_cache"]
    if c["folder"] is None:
        print("compilation cache: off")
    else:
        print(f"compilation cache: {c['folder']} ({c['files']} files, {c['bytes'] / 1e6:.1f} MB)")
    return 0
