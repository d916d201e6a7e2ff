"""``jaxproj render``: a robot motion file -> an MP4 / GIF video in real time
(``jaxproj.viz.render``) of the robot whose joints the file names (``load_motion``); prints what
it drew (the human beside the robot only where the file holds human positions)."""

from __future__ import annotations

import argparse
from typing import Any

from jaxproj.cli import options


def add_parsers(sub: Any) -> None:
    p = options.add_parser(sub, "render", "render a robot motion file to an MP4 / GIF video")
    p.add_argument(
        "motion",
        help="motion file: .npz, .csv or a robot's own document (NAOqi .json) of any registered "
        "robot, found by the file's joint names (jaxproj.io.motion_files)",
    )
    p.add_argument(
        "--out",
        required=True,
        help=f"output video: .mp4 (needs imageio-ffmpeg) or .gif; {options.OUTPUT_FOLDER_RULE}",
    )
    p.add_argument(
        "--backend",
        default="auto",
        choices=("auto", "mujoco", "matplotlib"),
        help="robot panel: MuJoCo OpenGL (needs MUJOCO_GL=egl / osmesa or a display), matplotlib "
        "stick figure, or auto (MuJoCo, else matplotlib)",
    )
    p.add_argument("--stride", type=int, default=1, help="render every N-th frame")
    p.add_argument(
        "--size",
        type=options.parse_size,
        default="480x360",
        help="one panel's WIDTHxHEIGHT, pixels",
    )
    p.add_argument(
        "--fps",
        type=float,
        default=None,
        help="the video's frame rate; it plays in real time by the motion's times at any rate, "
        "a gap held on its last frame (None: the motion's rate / stride, at most 50 for a .gif)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from jaxproj.io.motion_files import load_motion
    from jaxproj.viz import render

    out = options.output_path(args.out, "--out")
    render.check_video_path(out)  # before the (slow) rendering
    motion = load_motion(args.motion)
    done = render.render_to_file(
        motion, out, fps=args.fps, backend=args.backend, size=args.size, stride=args.stride
    )
    span = float(motion.times[-1] - motion.times[0])
    print(f"{args.motion}: {motion.n_frames} frames over {span:.2f} s -> {done.path}: "
          f"{done.describe()}")  # fmt: skip
    return 0
