"""Robots as data: the ``Robot`` spec and the registry of robots.

A robot is an MJCF and one robot file (``robot_file``, TOML): every folder here that holds a
``robot.toml`` is read and registered under the name it gives (``nao_h25``, the NAO H25 V5 and
the default; ``unitree_g1``, the Unitree G1; ``unitree_h1``, the Unitree H1), and a user's robot
file is registered where it is first taken (``get(path)``, ``--robot PATH``). The NAO's file
names two pieces of Python of its folder: its closed-form IK (``[ik] kind = "python"``) and its
NAOqi export (``[exports]``); the others use the generic IK and no Python. Everything above
``robots/`` takes a ``robot: Robot`` and names no robot: below the public API as a required
argument; the public entry points take the robot from what they are given (a ``Model`` records
its robot, a ``Motion`` carries one) or ``robot=`` (a ``Robot`` or a name; ``None``: ``get()``,
the default robot). ``tests/test_layers.py`` checks that no module above ``robots/`` imports a
robot's package or names a registered robot.

``register(robot)`` adds a robot under ``robot.name``; ``get(name)`` returns it; ``names()``
lists them; ``for_joints(joint_names)`` finds the robot a file's joint names belong to (how
``load_motion`` and ``jaxproj render`` know a motion's robot); ``DEFAULT`` is the name of the
default robot (``"nao_h25"``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path, PurePath

from jaxproj.errors import ConfigError
from jaxproj.robots.base import Chain, CoupledLimit, Export, Mjcf, Robot, clip_coupled
from jaxproj.robots.robot_file import describe, digest, load

BUNDLED_FILES: tuple[Path, ...] = tuple(sorted(Path(__file__).parent.glob("*/robot.toml")))
"""The robot files shipped with jaxproj (one folder each, with its MJCF), registered on import."""

NAO_H25 = load(Path(__file__).parent / "nao_h25" / "robot.toml")
"""The NAO H25 V5 (26 joints, 10 driven: head, arms to the elbow; three chains; NAOqi JSON), read
from its robot file ``nao_h25/robot.toml`` and MJCF ``nao_h25/nao_h25.xml``; its IK is the closed
form the file names (``nao_h25/ik.py``)."""

UNITREE_G1 = load(Path(__file__).parent / "unitree_g1" / "robot.toml")
"""The Unitree G1 (29 joints, 21 driven: waist, legs to the ankle pitch, arms to the elbow),
read from its robot file ``unitree_g1/robot.toml`` and MJCF ``unitree_g1/unitree_g1.xml``."""

__all__ = ["DEFAULT", "NAO_H25", "UNITREE_G1", "Chain", "CoupledLimit", "Export", "Mjcf", "Robot",
           "BUNDLED_FILES", "clip_coupled", "describe", "for_joints", "get", "identity",
           "is_file_name", "load", "names", "register", "unregister"]  # fmt: skip

DEFAULT = "nao_h25"
"""Name of the default robot."""

_REGISTRY: dict[str, Robot] = {}


def register(robot: Robot, *, replace: bool = False) -> Robot:
    """Add ``robot`` to the registry under ``robot.name`` and return it.

    Raises:
      ConfigError: not a ``Robot``, or the name is taken by another robot (unless ``replace``).
    """
    if not isinstance(robot, Robot):
        raise ConfigError(f"register needs a jaxproj.robots.Robot, got {type(robot).__name__}")
    old = _REGISTRY.get(robot.name)
    if old is not None and old is not robot and not replace:
        raise ConfigError(f"a robot named {robot.name!r} is already registered")
    _REGISTRY[robot.name] = robot
    return robot


def unregister(name: str) -> None:
    """Remove the robot ``name`` (tests; the default robot cannot be removed)."""
    if name == DEFAULT:
        raise ConfigError(f"the default robot {DEFAULT!r} cannot be unregistered")
    if name not in _REGISTRY:
        raise ConfigError(f"no robot named {name!r}; registered: {names()}")
    del _REGISTRY[name]


def is_file_name(name: object) -> bool:
    """Whether ``name`` is a robot file's path (a ``Path``, or a str ending in ``.toml``)
    rather than a registered robot's name."""
    return isinstance(name, PurePath) or (isinstance(name, str) and name.endswith(".toml"))


def get(name: str | PurePath | Robot | None = None) -> Robot:
    """The robot registered as ``name`` (``None``: the default; a ``Robot`` is returned as is),
    or the robot of the robot file at ``name`` (``is_file_name``), read (``load``) and
    registered under its name.

    Raises:
      ConfigError: no robot of that name; a robot file that does not load, or whose robot's
        name is taken by another robot (another file, or a built-in robot).
    """
    if isinstance(name, Robot):
        return name
    if is_file_name(name):
        robot = load(name)  # type: ignore[arg-type]
        old = _REGISTRY.get(robot.name)
        same_file = old is not None and old.file is not None and old.file == robot.file
        if old is not None and old is not robot and not same_file:
            where = f"from {old.file}" if old.file is not None else "built in"
            raise ConfigError(f"{robot.file}: a robot named {robot.name!r} is registered already "
                              f"({where}); give yours another name")  # fmt: skip
        return register(robot, replace=True)
    key = DEFAULT if name is None else name
    if key not in _REGISTRY:
        raise ConfigError(f"unknown robot {key!r}; registered robots: {names()}")
    return _REGISTRY[key]


def names() -> tuple[str, ...]:
    """Names of the registered robots, sorted."""
    return tuple(sorted(_REGISTRY))


def for_joints(joint_names: Sequence[str]) -> Robot:
    """The registered robot whose joints ``joint_names`` are (a motion file's columns).

    Args:
      joint_names: joint names, in any order; a subset of one robot's ``joint_names`` is enough
        (a file may leave joints out: they take the robot's standing posture).

    Returns:
      The robot whose ``joint_names`` hold every name: the default robot when it does, else the
      one robot that does (when several do, the one with exactly these joints, if one has).

    Raises:
      ConfigError: no registered robot has all the names (the message lists the unknown ones,
        against the default robot, and the registered robots), or several do equally well.
    """
    wanted = [str(n) for n in joint_names]
    fits = [r for r in _REGISTRY.values() if all(r.has_joint(n) for n in wanted)]
    if not fits:
        default = _REGISTRY[DEFAULT]
        unknown = [n for n in wanted if not default.has_joint(n)]
        raise ConfigError(
            f"unknown joint names {unknown[:6]}{' ...' if len(unknown) > 6 else ''}: they are "
            f"no registered robot's joints (registered robots: {', '.join(names())})"
        )
    if any(r.name == DEFAULT for r in fits):
        return _REGISTRY[DEFAULT]
    exact = [r for r in fits if set(r.joint_names) == set(wanted)]
    if len(fits) == 1 or len(exact) == 1:
        return fits[0] if len(fits) == 1 else exact[0]
    raise ConfigError(
        f"joint names {wanted[:4]} ... fit several robots ({', '.join(r.name for r in fits)}): "
        "name the robot (robot=...)"
    )


register(NAO_H25)
for _file in BUNDLED_FILES:
    register(load(_file))


@functools.cache
def _digest(path: Path, mtime_ns: int, size: int) -> str:
    return digest(path)


def identity(robot: Robot) -> tuple[str, str] | None:
    """``(name, digest)`` of a robot read from a robot file and registered under its name (the
    robot ``get(name)`` gives), whose Python, if its file names any, is ``jaxproj``'s own;
    ``None`` for any other robot (built in Python, a variant of a registered one, an IK module of
    the user's). ``digest``: sha256 of the robot file and its MJCF (``robot_file.digest``). What
    the command line's kept executables key a robot's programs by
    (``jaxproj._internal.executables``)."""
    if robot.file is None or not robot.file.is_file() or _REGISTRY.get(robot.name) is not robot:
        return None
    for fn in (robot.ik, robot.traced_ik):
        if fn is not None and not str(getattr(fn, "__module__", "")).startswith("jaxproj."):
            return None
    stat = robot.file.stat()
    return robot.name, _digest(robot.file.resolve(), stat.st_mtime_ns, stat.st_size)
