"""The jaxproj command line: thin subcommands over the public API.

Subcommands: ``info`` (versions, devices, robot, bundled data), ``retarget`` (a skeleton
recording or BVH clip -> a robot-feasible joint trajectory of a registered robot as NPZ, CSV or
the robot's own document),
``render`` (a motion file -> MP4 / GIF), ``build`` (a projector), ``evaluate`` (batch
evaluation against the IK), ``demo`` (the main job) and ``robot check|show`` (a robot file);
one module per group (``jaxproj.cli.info``, ``.retarget``, ``.render``, ``.projector``,
``.demo``, ``.robot``), their shared
options in ``jaxproj.cli.options``; every subcommand runs with the persistent compilation cache
(``jaxproj.cli.cache``; ``--no-cache`` to run without). Every user error prints one line naming
the file and the problem on stderr and exits with status 2 (a usage error too:
``options.Parser``); no traceback. Output files are written only into folders that exist, never
over an existing file without ``--force``, never over one of the command's inputs; every check
that needs no computation runs before any.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from jaxproj import __version__, robots
from jaxproj._internal.shards import request_host_devices
from jaxproj.cli import cache, demo, info, options, projector, render, retarget, robot
from jaxproj.errors import JaxprojError

DESCRIPTION = (
    "jaxproj: retarget Kinect skeleton recordings to humanoid robot joint angles (robots: "
    f"{', '.join(robots.names())}; default {robots.DEFAULT}), build and evaluate the learned "
    "projector, render motions, and run the paper's demo."
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``jaxproj`` command."""
    p = options.Parser(
        prog="jaxproj", description=DESCRIPTION, formatter_class=options.HelpFormatter
    )
    p.add_argument("--version", action="version", version=f"jaxproj {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for group in (info, retarget, projector, demo, render, robot):
        group.add_parsers(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxproj`` console script; returns the exit status.

    Asks XLA for one CPU device per core first (``shards.request_host_devices``; not where JAX
    runs already, as in a caller's process that has used it), so that the generic IK's frames
    run on every core (``jaxproj._internal.shards``)."""
    request_host_devices()
    args = build_parser().parse_args(argv)
    try:
        with cache.compilation_cache(enabled=not args.no_cache):
            return int(args.func(args))
    except JaxprojError as e:
        print(f"jaxproj: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("jaxproj: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
