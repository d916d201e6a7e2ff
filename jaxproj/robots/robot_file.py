"""A robot as a file: an MJCF plus one TOML file, read into a ``Robot`` with no Python per robot.

``load(path)`` reads a robot file (schema 1, documented in ``docs/guide/robots.md``) and its
MJCF and returns the ``Robot``: joint names, their order and limits come from the MJCF (its
hinge and slide joints in file order); the file says which joints are driven, the chains, the
correspondence rows and the IK settings, speeds and accelerations with their sources, the
evaluation's sites and the figure. A key the schema does not know, a name the MJCF lacks or a
value of the wrong kind is a ``ConfigError`` that names the file and the key.

The same file (same path, same bytes of the file and of its MJCF) gives the same ``Robot``
object, so that compiled programs keyed on the robot are shared.

Sections (every key optional unless marked):

- top level: ``schema = 1`` (required), ``name`` (required, an identifier), ``title``,
  ``mjcf`` (required, relative to the file), ``free_joint``, ``root_body`` (both or neither:
  an MJCF without a free joint is fixed as written).
- ``[joints]``: ``driven`` (required, joint names), ``standing`` (joint -> rad; others 0),
  ``loose`` (joint names), ``order`` (the configuration order, where it is not the MJCF's),
  ``coupled`` (``[leader, follower]`` pairs), ``elbow_pairs`` (``[yaw, roll]`` pairs);
  ``[[joints.coupled_limits]]``: ``joint``, ``by``, ``source``, ``table_deg``, ``symmetric``;
  ``[joints.velocity]``, ``[joints.rated]``,
  ``[joints.acceleration]``: a ``source`` string and joint name or shell pattern -> value
  (rad/s, rad/s^2), each joint matched by exactly one key; ``[joints.limits]``: joint ->
  ``[lower, upper]`` restated from a source, checked against the MJCF (1e-4 rad).
- ``[[chains]]``: ``name``, ``bones``, ``joints`` (required), ``bandwidth``,
  ``keep_bandwidth`` (a boolean: ``Chain.keep_bandwidth``).
- ``[ik]``: ``kind = "generic"`` (the generic IK; required), ``base`` (required), the
  ``IKConfig`` fields (``iterations``, ``starts``, ``neutral``, ``collision``, ``margin``,
  ``damping``, ``gtol``, ``seed``), ``collision_pairs`` (``"mjcf"`` or pairs of geoms),
  ``source``; ``[[ik.rows]]``: ``bone``, ``start``, ``end`` (required), ``weight``,
  ``minus``, ``rest``; ``[ik.ranges]``: joint -> ``[lower, upper]`` (``inf``: no bound). Or
  ``kind = "python"`` and ``module``: a module whose ``attach(robot) -> Robot`` gives the IK
  (the NAO's closed form); it reads its robot's data with ``describe``.
- ``[exports]``: file suffix -> ``"package.module:NAME"`` of an ``Export``.
- ``[projection]``: ``deviation_scale``.
- ``[evaluation]``: ``arm_sites`` (side -> three sites), ``hand_sites``, ``fk_without``,
  ``split`` (part -> bodies), ``head_root``, ``warp_validated`` (a boolean).
- ``[figure]``: ``label``, ``links``, ``head`` (``[body, length]``), ``parents``, ``feet``,
  ``head_geom``.

Size: over 500 lines: the schema's one reader (a function per section, each error naming the
file and the key), the embedding in model files and the cache of read files, which a reader
checks against the schema together.
"""

from __future__ import annotations

import fnmatch
import functools
import hashlib
import importlib
import os
import re
import tempfile
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.robots import mjcf as _mjcf
from jaxproj.robots.base import Chain, CoupledLimit, Export, Figure, Mjcf, Robot
from jaxproj.robots.generic import with_generic_ik
from jaxproj.robots.generic_ik import BonePair, Correspondence, IKConfig

SCHEMA = 1
"""The robot file schema this version reads."""

LIMIT_TOLERANCE = 1e-4
"""rad: how far a limit restated in ``[joints.limits]`` may differ from the MJCF's."""

_TOP = {"schema", "name", "title", "mjcf", "free_joint", "root_body", "joints", "chains", "ik",
        "projection", "evaluation", "figure", "exports"}  # fmt: skip
_JOINTS = {"driven", "standing", "loose", "velocity", "rated", "acceleration", "limits", "order",
           "coupled", "elbow_pairs", "coupled_limits"}  # fmt: skip
_COUPLED_LIMIT = {"joint", "by", "source", "table_deg", "symmetric"}
_CHAIN = {"name", "bones", "joints", "bandwidth", "keep_bandwidth"}
_IK_SETTINGS = {"iterations", "starts", "neutral", "collision", "margin", "damping", "gtol", "seed"}
_IK = {"kind", "base", "collision_pairs", "source", "rows", "ranges", *_IK_SETTINGS}
_IK_PYTHON = {"kind", "module", "source"}
_ROW = {"bone", "start", "end", "weight", "minus", "rest"}
_EVALUATION = {"arm_sites", "hand_sites", "fk_without", "split", "head_root", "warp_validated"}
_FIGURE = {"label", "links", "head", "parents", "feet", "head_geom"}
_PROJECTION = {"deviation_scale"}


class _File:
    """The parsed TOML of one robot file and the helpers that name it in their errors."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self.data = tomllib.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ConfigError(f"{path}: no such robot file") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
            raise ConfigError(f"{path}: not a TOML file: {err}") from None

    def error(self, where: str, problem: str) -> ConfigError:
        return ConfigError(f"{self.path}: {where}: {' '.join(problem.split())}")

    def table(self, data: Any, where: str, allowed: set[str]) -> dict[str, Any]:
        if not isinstance(data, dict):
            raise self.error(where, f"must be a table, got {type(data).__name__}")
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise self.error(where, f"unknown key(s) {unknown}; allowed: {sorted(allowed)}")
        return data

    def string(self, data: Mapping[str, Any], key: str, where: str, default: Any = ...) -> Any:
        if key not in data:
            if default is ...:
                raise self.error(where, f"the key {key!r} is required")
            return default
        value = data[key]
        if not (isinstance(value, str) and value):
            raise self.error(f"{where}.{key}", f"must be a non-empty string, got {value!r}")
        return value

    def names(self, data: Mapping[str, Any], key: str, where: str, default: Any = ...) -> Any:
        if key not in data:
            if default is ...:
                raise self.error(where, f"the key {key!r} is required")
            return default
        value = data[key]
        if not (isinstance(value, list) and all(isinstance(v, str) and v for v in value)):
            raise self.error(f"{where}.{key}", f"must be a list of names, got {value!r}")
        return tuple(value)

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(where, f"must be a number, got {value!r}")
        return float(value)

    def flag(self, data: Mapping[str, Any], key: str, where: str) -> bool:
        value = data.get(key, False)
        if not isinstance(value, bool):
            raise self.error(f"{where}.{key}", f"must be true or false, got {value!r}")
        return value

    def string_map(self, value: Any, where: str) -> dict[str, str]:
        if not (isinstance(value, dict) and all(isinstance(v, str) for v in value.values())):
            raise self.error(where, f"must be a table of name -> name, got {value!r}")
        return dict(value)

    def pairs(self, value: Any, where: str) -> tuple[tuple[str, str], ...]:
        ok = isinstance(value, list) and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(s, str) for s in p)
            for p in value
        )
        if not ok:
            raise self.error(where, f"must be a list of [name, name] pairs, got {value!r}")
        return tuple((str(a), str(b)) for a, b in value)


def _model_names(model: mujoco.MjModel, kind: mujoco.mjtObj, count: int) -> set[str]:
    return {mujoco.mj_id2name(model, kind, i) for i in range(count)} - {None}


def _joint_table(f: _File, data: Any, where: str, joints: Sequence[str]) -> np.ndarray | None:
    """A ``[joints.velocity]``-like table: ``source`` (a string, for the reader) and name /
    pattern -> value -> ``(n_joints,)`` float32, or ``None`` where the file has no such table."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise f.error(where, "must be a table of joint name or pattern -> value")
    source = data.get("source", "")
    if not isinstance(source, str):
        raise f.error(f"{where}.source", "must be a string")
    keys = {k: f.number(v, f"{where}.{k}") for k, v in data.items() if k != "source"}
    values = np.empty(len(joints), np.float32)
    for i, joint in enumerate(joints):
        hits = [k for k in keys if fnmatch.fnmatchcase(joint, k)]
        if len(hits) != 1:
            what = "no key matches" if not hits else f"several keys match ({hits})"
            raise f.error(where, f"{what} the joint {joint!r}; each joint needs exactly one")
        values[i] = keys[hits[0]]
    unused = [k for k in keys if not any(fnmatch.fnmatchcase(j, k) for j in joints)]
    if unused:
        raise f.error(where, f"key(s) {unused} match no joint of the MJCF")
    return values


def _point(f: _File, value: Any, where: str) -> Any:
    if isinstance(value, str) and value:
        return value
    if (
        isinstance(value, list)
        and len(value) == 2
        and isinstance(value[0], str)
        and isinstance(value[1], list)
        and len(value[1]) == 3
    ):
        return (value[0], tuple(f.number(v, where) for v in value[1]))
    raise f.error(where, f"must be a site or body name, or [body, [x, y, z]], got {value!r}")


def _correspondence(f: _File, ik: dict[str, Any], joints: Sequence[str]) -> Correspondence:
    rows = ik.get("rows")
    if not (isinstance(rows, list) and rows):
        raise f.error("ik.rows", "at least one [[ik.rows]] table is required")
    pairs = []
    for k, row in enumerate(rows):
        where = f"ik.rows[{k}]"
        row = f.table(row, where, _ROW)
        rest = row.get("rest")
        if rest is not None:
            if not (isinstance(rest, list) and len(rest) == 3):
                raise f.error(f"{where}.rest", f"must be [x, y, z], got {rest!r}")
            rest = tuple(f.number(v, f"{where}.rest") for v in rest)
        try:
            pairs.append(
                BonePair(
                    f.string(row, "bone", where),
                    _point(f, row.get("start"), f"{where}.start"),
                    _point(f, row.get("end"), f"{where}.end"),
                    weight=f.number(row.get("weight", 1.0), f"{where}.weight"),
                    minus=f.string(row, "minus", where, None),
                    rest=rest,
                )
            )
        except ConfigError as err:
            if str(err).startswith(str(f.path)):
                raise
            raise f.error(where, str(err)) from None
    ranges = []
    for joint, value in f.table(ik.get("ranges", {}), "ik.ranges", set(joints)).items():
        if not (isinstance(value, list) and len(value) == 2):
            raise f.error(f"ik.ranges.{joint}", f"must be [lower, upper], got {value!r}")
        lo, hi = (f.number(v, f"ik.ranges.{joint}") for v in value)
        ranges.append((joint, lo, hi))
    collision = ik.get("collision_pairs", [])
    if collision != "mjcf":
        collision = f.pairs(collision, "ik.collision_pairs")
    try:
        return Correspondence(
            base=f.string(ik, "base", "ik"),
            pairs=tuple(pairs),
            collision_pairs=collision,
            ranges=tuple(ranges),
            source=f.string(ik, "source", "ik", ""),
        )
    except ConfigError as err:
        raise f.error("ik", str(err)) from None


def _ik_config(f: _File, ik: dict[str, Any]) -> IKConfig:
    kwargs: dict[str, Any] = {}
    for key in _IK_SETTINGS & set(ik):
        value = f.number(ik[key], f"ik.{key}")
        if key in ("iterations", "starts", "seed"):
            if value != int(value):
                raise f.error(f"ik.{key}", f"must be a whole number, got {ik[key]!r}")
            value = int(value)
        kwargs[key] = value
    try:
        return IKConfig(**kwargs)
    except ConfigError as err:
        raise f.error("ik", str(err)) from None


def _check_names(f: _File, model: mujoco.MjModel, robot_data: dict[str, Any]) -> None:
    """Every site, body and geom name the file gives exists in the MJCF."""
    sites = _model_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite)
    bodies = _model_names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    geoms = _model_names(model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom)

    def need(name: str, kinds: set[str], where: str, what: str) -> None:
        if name not in kinds:
            raise f.error(where, f"the MJCF has no {what} named {name!r}")

    ev = robot_data.get("evaluation", {})
    for side, names in ev.get("arm_sites", {}).items():
        for s in names:
            need(s, sites, f"evaluation.arm_sites.{side}", "site")
    for s in ev.get("hand_sites", ()):
        need(s, sites, "evaluation.hand_sites", "site")
    for b in (*ev.get("fk_without", ()), *(b for v in ev.get("split", {}).values() for b in v)):
        need(b, bodies, "evaluation", "body")
    if "head_root" in ev:
        need(ev["head_root"], bodies, "evaluation.head_root", "body")
    fig = robot_data.get("figure", {})
    for a, b in fig.get("links", ()):
        need(a, sites, "figure.links", "site")
        need(b, sites, "figure.links", "site")
    for body, site in fig.get("feet", ()):
        need(body, bodies, "figure.feet", "body")
        need(site, sites, "figure.feet", "site")
    if "head" in fig:
        need(fig["head"][0], bodies, "figure.head", "body")
    if "head_geom" in fig:
        need(fig["head_geom"], geoms, "figure.head_geom", "geom")
    ik = robot_data.get("ik", {})
    if ik.get("kind") != "python":
        need(ik.get("base", ""), bodies, "ik.base", "body")
    for k, row in enumerate(ik.get("rows", ())):
        for end in ("start", "end"):
            p = row.get(end)
            name = p if isinstance(p, str) else p[0]
            if name not in sites and name not in bodies:
                raise f.error(f"ik.rows[{k}].{end}", f"the MJCF has no site or body {name!r}")
    if isinstance(ik.get("collision_pairs"), list):
        for a, b in ik["collision_pairs"]:
            need(a, geoms, "ik.collision_pairs", "geom")
            need(b, geoms, "ik.collision_pairs", "geom")


def _describe(path: Path) -> tuple[Robot, _File, dict[str, Any]]:
    """The robot the file describes, without its IK, the parsed file and its top table."""
    f = _File(path)
    d = f.table(f.data, "the file", _TOP)
    if d.get("schema") != SCHEMA:
        raise f.error("schema", f"this jaxproj reads robot files of schema {SCHEMA}, "
                                f"got {d.get('schema')!r}")  # fmt: skip
    name = f.string(d, "name", "the file")
    mjcf_path = (path.parent / f.string(d, "mjcf", "the file")).resolve()
    if not mjcf_path.is_file():
        raise f.error("mjcf", f"no such MJCF file {mjcf_path}")
    free_joint = f.string(d, "free_joint", "the file", None)
    root_body = f.string(d, "root_body", "the file", None)
    try:
        model = mujoco.MjModel.from_xml_path(str(mjcf_path))
    except ValueError as err:
        raise f.error("mjcf", f"MuJoCo cannot compile {mjcf_path.name}: {err}") from None
    hinge = {int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)}
    ids = [i for i in range(model.njnt) if int(model.jnt_type[i]) in hinge]
    joint_names = tuple(model.joint(i).name for i in ids)
    if not joint_names:
        raise f.error("mjcf", "the MJCF has no hinge or slide joint")
    if not all(joint_names):
        raise f.error("mjcf", "every hinge and slide joint of the MJCF needs a name")
    unlimited = [joint_names[k] for k, i in enumerate(ids) if not model.jnt_limited[i]]
    if unlimited:
        raise f.error("mjcf", f"joints without a range (limited): {unlimited}")
    jt = f.table(d.get("joints"), "joints", _JOINTS)
    order = f.names(jt, "order", "joints", None)
    if order is not None:  # the configuration order (a controller's), not the MJCF's tree order
        if sorted(order) != sorted(joint_names):
            missing = sorted(set(joint_names) - set(order))
            extra = sorted(set(order) - set(joint_names))
            raise f.error("joints.order", f"must name every hinge and slide joint of the MJCF "
                          f"once (missing {missing}, unknown or repeated {extra})")  # fmt: skip
        ids = [ids[joint_names.index(j)] for j in order]
        joint_names = order
    lower = model.jnt_range[ids, 0].astype(np.float32)
    upper = model.jnt_range[ids, 1].astype(np.float32)
    if free_joint is not None:
        fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, free_joint)
        if fid < 0 or int(model.jnt_type[fid]) != int(mujoco.mjtJoint.mjJNT_FREE):
            raise f.error("free_joint", f"the MJCF has no free joint named {free_joint!r}")
        if root_body is None:
            raise f.error("the file", "free_joint needs root_body (the body it carries)")
    if root_body is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, root_body) < 0:
        raise f.error("root_body", f"the MJCF has no body named {root_body!r}")
    _check_names(f, model, d)
    known = set(joint_names)

    def joints_of(value: tuple[str, ...], where: str) -> tuple[str, ...]:
        unknown = [j for j in value if j not in known]
        if unknown:
            raise f.error(where, f"the MJCF has no joint(s) {unknown}")
        return value

    driven = joints_of(f.names(jt, "driven", "joints"), "joints.driven")
    loose = joints_of(f.names(jt, "loose", "joints", ()), "joints.loose")
    standing = np.zeros(len(joint_names), np.float32)
    for j, v in f.table(jt.get("standing", {}), "joints.standing", known).items():
        standing[joint_names.index(j)] = f.number(v, f"joints.standing.{j}")
    for j, v in f.table(jt.get("limits", {}), "joints.limits", known).items():
        if not (isinstance(v, list) and len(v) == 2):
            raise f.error(f"joints.limits.{j}", f"must be [lower, upper], got {v!r}")
        lo, hi = (f.number(x, f"joints.limits.{j}") for x in v)
        k = joint_names.index(j)
        if max(abs(lo - lower[k]), abs(hi - upper[k])) > LIMIT_TOLERANCE:
            raise f.error(f"joints.limits.{j}", f"[{lo}, {hi}] disagrees with the MJCF's range "
                                                f"[{lower[k]:.6g}, {upper[k]:.6g}]")  # fmt: skip
    coupled = f.pairs(jt.get("coupled", []), "joints.coupled")
    elbow_pairs = f.pairs(jt.get("elbow_pairs", []), "joints.elbow_pairs")
    for where, pairs in (("joints.coupled", coupled), ("joints.elbow_pairs", elbow_pairs)):
        joints_of(tuple(j for pair in pairs for j in pair), where)
    coupled_limits = _coupled_limits(f, jt.get("coupled_limits", []), known)
    velocity = _joint_table(f, jt.get("velocity"), "joints.velocity", joint_names)
    rated = _joint_table(f, jt.get("rated"), "joints.rated", joint_names)
    accel = _joint_table(f, jt.get("acceleration"), "joints.acceleration", joint_names)

    chains_data = d.get("chains")
    if not (isinstance(chains_data, list) and chains_data):
        raise f.error("chains", "at least one [[chains]] table is required")
    chains = []
    for k, c in enumerate(chains_data):
        where = f"chains[{k}]"
        c = f.table(c, where, _CHAIN)
        bw = c.get("bandwidth")
        try:
            chains.append(
                Chain(
                    f.string(c, "name", where),
                    f.names(c, "bones", where),
                    joints_of(f.names(c, "joints", where), f"{where}.joints"),
                    bandwidth=None if bw is None else f.number(bw, f"{where}.bandwidth"),
                    keep_bandwidth=f.flag(c, "keep_bandwidth", where),
                )
            )
        except ConfigError as err:
            if str(err).startswith(str(f.path)):
                raise
            raise f.error(where, str(err)) from None

    ev = f.table(d.get("evaluation", {}), "evaluation", _EVALUATION)
    fig = f.table(d.get("figure", {}), "figure", _FIGURE)
    head = fig.get("head")
    if head is not None:
        if not (isinstance(head, list) and len(head) == 2 and isinstance(head[0], str)):
            raise f.error("figure.head", f"must be [body, length], got {head!r}")
        head = (head[0], f.number(head[1], "figure.head"))
    figure = Figure(
        label=f.string(fig, "label", "figure", ""),
        links=f.pairs(fig.get("links", []), "figure.links"),
        head=head,
        parents=f.string_map(fig.get("parents", {}), "figure.parents"),
        feet=f.pairs(fig.get("feet", []), "figure.feet"),
        head_geom=f.string(fig, "head_geom", "figure", None),
    )
    arm_sites = {}
    for side, sites in f.table(ev.get("arm_sites", {}), "evaluation.arm_sites",
                               set(ev.get("arm_sites", {}))).items():  # fmt: skip
        if not (isinstance(sites, list) and len(sites) == 3):
            raise f.error(f"evaluation.arm_sites.{side}", "must be [shoulder, elbow, wrist]")
        arm_sites[side] = tuple(sites)
    split = {part: f.names(ev["split"], part, "evaluation.split") for part in ev.get("split", {})}
    mj = Mjcf(
        path=mjcf_path,
        load=functools.partial(_load, mjcf_path, free_joint, root_body),
        free_joint=free_joint,
        arm_sites=arm_sites,
        fk_without=f.names(ev, "fk_without", "evaluation", ()),
        hand_sites=f.names(ev, "hand_sites", "evaluation", ()),
        split=split,
        head_root=f.string(ev, "head_root", "evaluation", None),
        figure=figure,
        warp_validated=f.flag(ev, "warp_validated", "evaluation"),
    )
    proj = f.table(d.get("projection", {}), "projection", _PROJECTION)
    scale = proj.get("deviation_scale")
    try:
        robot = Robot(
            name=name,
            title=f.string(d, "title", "the file", name),
            joint_names=joint_names,
            lower=lower,
            upper=upper,
            standing=standing,
            driven_joints=driven,
            chains=tuple(chains),
            velocity_limits=velocity,
            rated_speeds=rated,
            acceleration_limits=accel,
            loose_joints=loose,
            coupled_joints=coupled,
            elbow_pairs=elbow_pairs,
            coupled_limits=coupled_limits,
            exports=_exports(f, d.get("exports", {})),
            mjcf=mj,
            deviation_scale=None if scale is None else f.number(scale, "projection"),
            file=path,
        )
    except ConfigError as err:
        raise f.error("the robot", str(err)) from None
    return robot, f, d


def _read(robot: Robot, f: _File, d: dict[str, Any]) -> Robot:
    """The robot of a ``_describe`` result with its IK attached."""
    joint_names = robot.joint_names
    ik = d.get("ik")
    if isinstance(ik, dict) and ik.get("kind") == "python":
        return _python_ik(f, f.table(ik, "ik", _IK_PYTHON), robot)
    ik = f.table(ik, "ik", _IK)
    if ik.get("kind") != "generic":
        raise f.error("ik.kind", f'must be "generic" (the generic IK) or "python" (a module\'s), '
                                 f"got {ik.get('kind')!r}")  # fmt: skip
    robot = with_generic_ik(robot, _correspondence(f, ik, joint_names), _ik_config(f, ik))
    assert robot.generic is not None
    try:  # every name resolves, every chain reads a row and every row is read (0.2 s; kept)
        robot.generic.build()
    except ConfigError as err:
        raise f.error("ik", str(err)) from None
    return robot


def _coupled_limits(f: _File, data: Any, known: set[str]) -> tuple[CoupledLimit, ...]:
    """``[[joints.coupled_limits]]``: ``joint``, ``by``, ``source`` and the published table
    ``table_deg`` (rows ``[by, lower, upper]`` in degrees, ``by`` increasing); ``symmetric``:
    the table gives ``by >= 0`` only and holds mirrored for ``by < 0``."""
    if not isinstance(data, list):
        raise f.error(
            "joints.coupled_limits", "must be a list of tables ([[joints.coupled_limits]])"
        )
    out = []
    for k, item in enumerate(data):
        where = f"joints.coupled_limits[{k}]"
        item = f.table(item, where, _COUPLED_LIMIT)
        joint, by = f.string(item, "joint", where), f.string(item, "by", where)
        for name in (joint, by):
            if name not in known:
                raise f.error(where, f"the MJCF has no joint {name!r}")
        rows = item.get("table_deg")
        if not (isinstance(rows, list) and rows and all(isinstance(r, list) and len(r) == 3
                                                         for r in rows)):  # fmt: skip
            raise f.error(f"{where}.table_deg", "must be a list of [by, lower, upper] rows (deg)")
        table = np.array([[f.number(v, f"{where}.table_deg") for v in r] for r in rows])
        if f.flag(item, "symmetric", where):
            if table[0, 0] != 0.0:
                raise f.error(f"{where}.table_deg", "a symmetric table starts at by = 0")
            mirror = table[:0:-1].copy()
            mirror[:, 0] *= -1.0
            table = np.concatenate([mirror, table])
        try:
            out.append(
                CoupledLimit(
                    joint=joint,
                    by=by,
                    knots=np.radians(table[:, 0]).astype(np.float32),
                    lower=np.radians(table[:, 1]).astype(np.float32),
                    upper=np.radians(table[:, 2]).astype(np.float32),
                    source=f.string(item, "source", where, ""),
                )
            )
        except ConfigError as err:
            raise f.error(where, str(err)) from None
    return tuple(out)


def _reference(f: _File, value: Any, where: str) -> Any:
    """The object a ``"package.module:NAME"`` string names (imported here)."""
    if not (isinstance(value, str) and re.fullmatch(r"[\w.]+:\w+", value)):
        raise f.error(where, f'must be "package.module:NAME", got {value!r}')
    module, name = value.split(":")
    try:
        return getattr(importlib.import_module(module), name)
    except ImportError as err:
        raise f.error(where, f"cannot import {module!r}: {err}") from None
    except AttributeError:
        raise f.error(where, f"the module {module!r} has no {name!r}") from None


def _exports(f: _File, data: Any) -> dict[str, Export]:
    """``[exports]``: file suffix -> ``"package.module:NAME"`` of an ``Export``."""
    out = {}
    for suffix, ref in f.table(
        data, "exports", set(data) if isinstance(data, dict) else set()
    ).items():
        export = _reference(f, ref, f"exports.{suffix}")
        if not isinstance(export, Export) or export.suffix != suffix:
            raise f.error(f"exports.{suffix}", f"{ref} is not an Export of suffix {suffix!r}")
        out[suffix] = export
    return out


def _python_ik(f: _File, ik: dict[str, Any], robot: Robot) -> Robot:
    """``[ik] kind = "python"``: the module ``ik.module`` completes the robot: its
    ``attach(robot) -> Robot`` gives the IK (``Robot.ik``, ``traced_ik``, each chain's ``ik``,
    ``whole_chain``, ``ik_constants``) of the robot the file describes. Importing it runs its
    code, as any Python package does."""
    attach = _reference(f, f"{f.string(ik, 'module', 'ik')}:attach", "ik.module")
    try:
        out = attach(robot)
    except ConfigError as err:
        raise f.error("ik.module", str(err)) from None
    if not isinstance(out, Robot) or out.name != robot.name or out.ik is None:
        raise f.error("ik.module", "its attach(robot) must return the robot with its IK")
    return out


def _load(
    path: Path,
    free_joint: str | None,
    root_body: str | None,
    mount: str = "free",
    without: Sequence[str] = (),
) -> mujoco.MjModel:
    """``Mjcf.load`` of a robot file's MJCF: ``jaxproj.robots.mjcf.load``; an MJCF without a
    free joint is already fixed, so both mounts compile it as it is (less ``without``)."""
    if free_joint is not None and root_body is not None:
        return _mjcf.load(path, mount, without, free_joint=free_joint, root_body=root_body)
    if mount not in _mjcf.MOUNTS:
        raise ConfigError(f"mount must be one of {_mjcf.MOUNTS}, got {mount!r}")
    spec = mujoco.MjSpec.from_file(str(path))
    _mjcf.remove_subtrees(spec, tuple(without), root_body or "")
    return spec.compile()


def digest(path: str | Path) -> str:
    """sha256 over the robot file's bytes and its MJCF's (hex): what identifies a robot file."""
    path = Path(path).resolve()
    h = hashlib.sha256(path.read_bytes())
    mjcf = tomllib.loads(path.read_text(encoding="utf-8")).get("mjcf")
    if isinstance(mjcf, str) and (path.parent / mjcf).is_file():
        h.update((path.parent / mjcf).read_bytes())
    return h.hexdigest()


_EXTERNAL = re.compile(r"""\b(file|meshdir|texturedir|assetdir)\s*=""")


def embed(robot: Robot) -> dict[str, str] | None:
    """What a model file stores of ``robot`` so that it loads without the robot's folder: the
    robot file's and its MJCF's text and names and their ``digest``; ``None`` for a robot not
    read from a file, or whose MJCF refers to other files (meshes, includes: those models need
    the robot's folder, or the robot registered, where they are loaded)."""
    if robot.file is None or robot.mjcf is None:
        return None
    mjcf_text = robot.mjcf.path.read_text(encoding="utf-8")
    if _EXTERNAL.search(mjcf_text):
        return None
    return {
        "name": robot.name,
        "file": robot.file.name,
        "text": robot.file.read_text(encoding="utf-8"),
        "mjcf": robot.mjcf.path.name,
        "mjcf_text": mjcf_text,
        "sha256": digest(robot.file),
    }


def from_embedded(doc: Mapping[str, Any]) -> Robot:
    """The robot of an ``embed`` record: its two files written (once) to a folder named by
    their digest under the system's temporary folder, then ``load``-ed.

    Raises:
      ConfigError: a malformed record, or a robot file that does not load.
    """
    try:
        sha, file, text = str(doc["sha256"]), str(doc["file"]), str(doc["text"])
        mjcf, mjcf_text = str(doc["mjcf"]), str(doc["mjcf_text"])
    except (KeyError, TypeError) as err:
        raise ConfigError(f"an embedded robot record lacks {err}") from None
    if not re.fullmatch(r"[0-9a-f]{64}", sha) or Path(file).name != file or Path(mjcf).name != mjcf:
        raise ConfigError("an embedded robot record has a bad digest or file name")
    folder = Path(tempfile.gettempdir()) / "jaxproj-robots" / sha
    folder.mkdir(parents=True, exist_ok=True)
    for name, body in ((mjcf, mjcf_text), (file, text)):
        target = folder / name
        if not target.is_file() or target.read_text(encoding="utf-8") != body:
            tmp = folder / f".{name}.{os.getpid()}"
            tmp.write_text(body, encoding="utf-8")
            tmp.replace(target)
    robot = load(folder / file)
    if digest(folder / file) != sha:
        raise ConfigError(f"the embedded robot {doc.get('name')!r} does not match its digest")
    return robot


@functools.cache
def _described(path: Path, sha: str) -> tuple[Robot, _File, dict[str, Any]]:
    del sha  # part of the cache key only: an edited file is read again
    return _describe(path)


@functools.cache
def _cached(path: Path, sha: str, ik: bool) -> Robot:
    """One read of a file (``_described``, its MJCF compiled once) for both ``describe`` and
    ``load``: a Python IK's module describes its own robot while ``load`` attaches it."""
    return _read(*_described(path, sha)) if ik else _described(path, sha)[0]


def _key(path: str | Path) -> tuple[Path, str]:
    p = Path(path).expanduser().resolve()
    if not p.is_file():
        raise ConfigError(f"{p}: no such robot file")
    try:
        return p, digest(p)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"{p}: not a TOML file: {err}") from None


def load(path: str | Path) -> Robot:
    """The ``Robot`` of the robot file at ``path`` (see the module doc).

    Raises:
      ConfigError: the file is missing, not TOML, or breaks the schema (the message names the
        file and the key); its MJCF does not compile or lacks a name the file uses.
    """
    return _cached(*_key(path), True)


def describe(path: str | Path) -> Robot:
    """The robot the file at ``path`` describes before its IK is attached (``Robot.ik`` and the
    generic IK's hooks ``None``): what a Python IK module (``[ik] kind = "python"``) reads of its
    own robot (joint names, limits, standing posture, chains) without importing itself again.

    Raises:
      ConfigError: as ``load``.
    """
    return _cached(*_key(path), False)
