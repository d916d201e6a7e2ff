"""``jaxproj robot check|show ROBOT``: a robot file (or a registered robot) checked or shown.

``check`` reads the file (``jaxproj.robots.robot_file``: a broken one exits 2 with one line
naming the file and the problem) and prints what only the kinematics show
(``jaxproj.robots.check.problems``), one line each; exit status 0 when there is none, 1 when
there are. ``show`` prints the body tree, joints, chains and the rows each reads.
"""

from __future__ import annotations

import argparse
from typing import Any

from jaxproj.cli import options


def add_parsers(sub: Any) -> None:
    p = options.add_parser(sub, "robot", "check or show a robot file (robot.toml + its MJCF)")
    p.add_argument(
        "action",
        choices=("check", "show"),
        help="check: refuse a broken robot (exit 1 with one line per problem); show: its tree, "
        "joints, chains and rows",
    )
    p.add_argument("robot", help="a robot file (robot.toml) or a registered robot's name")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from jaxproj import robots
    from jaxproj.robots import check

    robot = robots.get(args.robot)
    if args.action == "show":
        print(check.describe(robot))
        return 0
    found = check.problems(robot)
    for line in found:
        print(f"{args.robot}: {line}")
    if not found:
        print(f"{args.robot}: ok: {robot.name}, {robot.n_joints} joints, {robot.n_driven} driven "
              f"in {len(robot.chains)} chains; every name resolves, every row is read, every "
              "driven joint is seen, no self-contact standing")  # fmt: skip
    return 1 if found else 0
