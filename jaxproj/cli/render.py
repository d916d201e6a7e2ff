"""``jaxproj render``: a robot motion file -> an MP4 / GIF video in real time
(``jaxproj.viz.render``) of the robot whose joints the file names (``load_motion``); prints what
it drew (the human beside the robot only where the file holds human positions)."""

from __future__ import annotations

import argparse
from typing import Any

from jaxproj.cli import options

STRIDE = options.Bounded(int, 1, 1000)
"""``--stride``: 1..1000 motion frames per drawn frame."""

VIDEO_FPS = options.Bounded(float, 1.0, 240.0)
"""``--fps``: 1..240 video frames/s (a slide show to the fastest common displays)."""


def add_parsers(sub: Any) -> None:
    p = options.add_parser(sub, "render", "render a robot motion file to an MP4 / GIF video")
    p.add_argument(
        "motion",
        help="motion file: .npz, .csv or a robot's own document (a robot's export) of any "
        "registered robot, found by the file's joint names (jaxproj.io.motion_files)",
    )
    p.add_argument(
        "--out",
        required=True,
        help=f"output video: .mp4 (needs imageio-ffmpeg) or .gif; {options.OUTPUT_FOLDER_RULE}",
    )
    options.add_force_option(p, "--out")
    p.add_argument(
        "--robot",
        type=options.robot_name,
        default=None,
        help="the motion's robot: a name or a robot file (robot.toml) (None: the registered "
        "robot whose joints the file names)",
    )
    p.add_argument(
        "--backend",
        default="auto",
        choices=("auto", "mujoco", "matplotlib"),
        help="robot panel: MuJoCo OpenGL (needs MUJOCO_GL=egl / osmesa or a display), matplotlib "
        "stick figure, or auto (MuJoCo, else matplotlib)",
    )
    p.add_argument(
        "--stride",
        type=STRIDE,
        default=1,
        help=f"render every N-th frame, N {STRIDE.RANGE} (1,000 frames: over 30 s of a 30 fps "
        "motion per video frame)",
    )
    lo, hi = options.SIZE_RANGE
    p.add_argument(
        "--size",
        type=options.parse_size,
        default="480x360",
        help=f"one panel's WIDTHxHEIGHT, pixels, each side {lo}..{hi}",
    )
    p.add_argument(
        "--fps",
        type=VIDEO_FPS,
        default=None,
        help=f"the video's frame rate, {VIDEO_FPS.RANGE} frames/s (at most 50 for a .gif, whose "
        "delays are whole centiseconds); it plays in real time by the motion's times at any "
        "rate, a gap held on its last frame (None: the motion's rate / stride, at most 50 for a "
        ".gif)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from jaxproj.io.motion_files import load_motion
    from jaxproj.viz import render

    render.check_video_path(args.out)  # before the (slow) rendering
    out = options.output_path(
        args.out, "--out", force=args.force, inputs={"the motion file": args.motion}
    )
    motion = load_motion(args.motion, robot=args.robot)
    done = render.render_to_file(
        motion, out, fps=args.fps, backend=args.backend, size=args.size, stride=args.stride,
        overwrite=args.force,
    )  # fmt: skip
    span = float(motion.times[-1] - motion.times[0])
    print(f"{args.motion}: {motion.n_frames} frames over {span:.2f} s -> {done.path}: "
          f"{done.describe()}")  # fmt: skip
    return 0
