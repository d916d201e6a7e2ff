"""The matplotlib panels of ``jaxproj.viz.render``: the human skeleton and the robot's stick
figure (MuJoCo CPU kinematics, no OpenGL; drawn as ``robot.mjcf.figure`` says), each a 3-D axes on
an Agg canvas of exact pixel size, and the ``Camera`` both panels (and the MuJoCo one) are seen
from; ``robot_qpos`` / ``kinematics``, a robot's configuration in its MuJoCo model;
``robot_box``, the part of space a robot panel shows.

Framing: each panel shows a cube that holds its figure over the frames drawn, like the person's
(``_HumanPanel``: the skeleton over the motion's valid frames, 10 % spare). The robot's comes
from the robot's own geometry (``robot_box``): the forward kinematics of its MJCF (body origins,
sites, geom centres) in the standing posture and in every drawn frame, so any robot (0.6 m
or 1.3 m tall) stands whole in the picture, at the size the person has beside it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import BONES, J
from jaxproj.robots import Robot
from jaxproj.robots.base import joint_qpos_index, mj_site_ids

LEFT_COLOR = (0.95, 0.6, 0.2)
RIGHT_COLOR = (0.2, 0.6, 0.95)
CENTRE_COLOR = (0.25, 0.25, 0.3)

_DPI = 100

BOX_SPARE = 1.1
"""How much larger than its figure's extent (over the frames drawn) a panel's cube is."""

MAX_BOX_FRAMES = 2000
"""``robot_box`` reads at most this many frames, evenly spread (the drawn frames' extent)."""


def robot_label(robot: Robot) -> str:
    """How captions and legends name ``robot``: ``robot.mjcf.figure.label``,
    else ``robot.title``."""
    return (robot.mjcf.figure.label if robot.mjcf is not None else "") or robot.title


def robot_qpos(
    robot: Robot, model: Any, angles: np.ndarray, root: np.ndarray | None = None
) -> np.ndarray:
    """MuJoCo ``qpos`` of one configuration of ``robot``.

    Args:
      model: ``robot.load_model(...)`` (either mount).
      angles: ``(n_joints,)`` joint angles, ``robot.joint_names`` order, rad.
      root: ``(7,)`` the root body's position (m) and orientation (quaternion x, y, z, w: a
        whole-body motion's ``root_pos`` and ``root_rot``) for the free mount, or ``None``.

    Returns:
      ``(nq,)`` float64: ``model.qpos0`` with the angles placed, each coupled follower at its
      leader (``Robot.couple``) and, for the free mount, the base at ``root`` (default: the
      origin with identity orientation).
    """
    import mujoco

    q = np.asarray(angles, dtype=np.float64)
    if q.shape != (robot.n_joints,):
        raise ConfigError(f"angles must have shape ({robot.n_joints},), got {q.shape}")
    q = robot.couple(q)
    qpos = np.array(model.qpos0, dtype=np.float64)
    free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    if free.size:
        a = int(model.jnt_qposadr[free[0]])
        qpos[a : a + 7] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
        if root is not None:
            r = np.asarray(root, np.float64)
            qpos[a : a + 7] = (*r[:3], r[6], *r[3:6])  # MuJoCo's quaternion: w first
    qpos[joint_qpos_index(model, robot.joint_names)] = q
    return qpos


class Kinematics(NamedTuple):
    """Forward kinematics of one configuration (``kinematics``), in the root body's frame."""

    sites: np.ndarray
    """``(len(sites), 3)`` float64 positions of the named sites, m."""
    bodies: np.ndarray
    """``(nbody, 3)`` float64 body origins, m."""
    axes: np.ndarray
    """``(nbody, 3, 3)`` float64 body orientations (columns: the body's x, y, z axes)."""


def kinematics(robot: Robot, model: Any, angles: np.ndarray, sites: Sequence[str]) -> Kinematics:
    """CPU MuJoCo forward kinematics (``mj_kinematics``) of one configuration, in the frame of the
    root body (the MJCF's first body: the default robot's torso).

    Args:
      model: ``robot.load_model(...)`` (either mount); angles: ``(n_joints,)`` rad.
      sites: MJCF site names.

    Raises:
      ConfigError: a bad shape, or a site the model does not have.
    """
    import mujoco

    sids = mj_site_ids(model, sites)
    data = mujoco.MjData(model)
    data.qpos[:] = robot_qpos(robot, model, angles)
    mujoco.mj_kinematics(model, data)
    root, rot = data.xpos[1], data.xmat[1].reshape(3, 3)
    return Kinematics(
        (data.site_xpos[sids] - root) @ rot,
        (data.xpos - root) @ rot,
        rot.T @ data.xmat.reshape(-1, 3, 3),
    )


@dataclass(frozen=True)
class Camera:
    """Where both panels are seen from, in the body / torso frame (x forward, y left, z up).

    Attributes:
      azimuth: degrees; direction of the viewer around the vertical axis, from straight in front
        (0, on +x) towards the figure's left (+90, on +y). The default, 30, sees the figure from
        the front, a little from its left side (its left arm appears on the viewer's right).
      elevation: degrees above the horizontal (-90 < elevation < 90).
      distance: m, camera to ``lookat`` (MuJoCo panel), or ``None`` (default): far enough that
        the robot's cube (``robot_box``) fills the picture. The matplotlib panels always fit
        their cube.
      lookat: the point looked at, in the robot model's world frame (its root welded where its
        MJCF puts it), m (MuJoCo panel), or ``None`` (default): the centre of the robot's cube.
    """

    azimuth: float = 30.0
    elevation: float = 12.0
    distance: float | None = None
    lookat: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        try:
            lookat = None if self.lookat is None else tuple(float(v) for v in self.lookat)
            dist = () if self.distance is None else (float(self.distance),)
            values = (float(self.azimuth), float(self.elevation), *dist, *(lookat or ()))
        except (TypeError, ValueError):
            values, lookat = (math.nan,), ()
        if (lookat is not None and len(lookat) != 3) or not all(math.isfinite(v) for v in values):
            raise ConfigError(f"camera values must be finite numbers, lookat 3 of them: {self}")
        object.__setattr__(self, "lookat", lookat)
        if not -90.0 < self.elevation < 90.0:
            raise ConfigError(
                f"camera elevation must lie in (-90, 90) degrees, got {self.elevation}"
            )
        if self.distance is not None and self.distance <= 0:
            raise ConfigError(f"camera distance must be > 0 m, got {self.distance}")


def robot_box(
    robot: Robot, model: Any, angles: np.ndarray | None = None, roots: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """The cube a robot panel shows: it holds the robot in its standing posture and in every
    configuration of ``angles``, with ``BOX_SPARE`` to spare.

    The robot's extent is read from its own MJCF by CPU forward kinematics (``mj_kinematics``):
    every body origin, site and geom centre, in ``model``'s world frame (the frame the panels
    draw in). No robot's size is assumed.

    With ``roots`` (a whole-body motion's panel, whose view follows the root over the floor):
    the robot at each configuration's root pose, its points taken about the root horizontally,
    the floor (z = 0) included; the standing posture is not added.

    Args:
      model: ``robot.load_model("fixed")``, or ``"free"`` with ``roots``.
      angles: ``(N, n_joints)`` configurations drawn, rad (``robot.joint_names`` order), or
        ``None``: the standing posture only. At most ``MAX_BOX_FRAMES`` of them are read,
        evenly spread.
      roots: ``(N, 7)`` their root poses (``robot_qpos``'s ``root``), or ``None``.

    Returns:
      ``(centre, half)``: ``(3,)`` float64 m, the cube's centre (with ``roots``: less
      ``(root_x, root_y, 0)``), and its half side, m.
    """
    import mujoco

    q = np.empty((0, robot.n_joints))
    if angles is not None and len(angles):
        q = np.asarray(angles, np.float64).reshape(-1, robot.n_joints)
    r = None if roots is None else np.asarray(roots, np.float64).reshape(-1, 7)
    if len(q) > MAX_BOX_FRAMES:
        pick = np.linspace(0, len(q) - 1, MAX_BOX_FRAMES).round().astype(int)
        q, r = q[pick], None if r is None else r[pick]
    if r is None:
        q = np.concatenate([np.asarray(robot.standing, np.float64)[None], q])
    data = mujoco.MjData(model)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    if r is not None:
        lo[2] = 0.0  # the floor is shown
    for i, row in enumerate(q):
        data.qpos[:] = robot_qpos(robot, model, row, None if r is None else r[i])
        mujoco.mj_kinematics(model, data)
        pts = np.concatenate([data.xpos[1:], data.site_xpos, data.geom_xpos])
        if r is not None:
            pts = pts - np.array([r[i, 0], r[i, 1], 0.0])
        lo, hi = np.minimum(lo, pts.min(axis=0)), np.maximum(hi, pts.max(axis=0))
    half = max(float((hi - lo).max()) / 2.0 * BOX_SPARE, 0.05)
    return (lo + hi) / 2.0, half


# --- matplotlib panels ----------------------------------------------------------------------


class _Canvas:
    """One matplotlib 3-D axes on an Agg canvas of exactly ``size`` pixels (no pyplot)."""

    def __init__(self, size: tuple[int, int], camera: Camera, centre: np.ndarray, half: float):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        self.size = size
        self.fig = Figure(figsize=(size[0] / _DPI, size[1] / _DPI), dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.fig)
        ax: Any = self.fig.add_axes((0.0, 0.0, 1.0, 0.93), projection="3d")  # an Axes3D
        ax.set_axis_off()
        ax.view_init(elev=camera.elevation, azim=camera.azimuth)
        for i, set_lim in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            set_lim(centre[i] - half, centre[i] + half)
        ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.25)
        self.ax = ax
        self.lines = Line3DCollection([], linewidths=3.0, capstyle="round")
        ax.add_collection3d(self.lines, autolim=False)
        (self.head,) = ax.plot([], [], [], "o", color=CENTRE_COLOR, ms=10)
        font = float(np.clip(size[1] / 32.0, 6.0, 14.0))
        self.text = self.fig.text(0.02, 0.985, "", fontsize=font, va="top", family="monospace")
        self.grid_lines: Any = None  # follow()'s floor lines

    def follow(self, centre: np.ndarray, half: float, step: float = 0.5) -> None:
        """Move the view to the cube of half side ``half`` about ``centre`` (a whole-body
        motion's panel follows its figure over the floor) and draw the floor lines at z = 0,
        ``step`` m apart, that fall in it: fixed in the world, so the figure is seen to move
        over them (matplotlib's 3-D axes do not clip, so only the lines inside are drawn)."""
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        for i, set_lim in enumerate((self.ax.set_xlim, self.ax.set_ylim, self.ax.set_zlim)):
            set_lim(centre[i] - half, centre[i] + half)
        if self.grid_lines is None:
            self.grid_lines = Line3DCollection([], colors=[(0.8, 0.8, 0.8)], linewidths=0.8)
            self.ax.add_collection3d(self.grid_lines, autolim=False)
        lo, hi = centre[:2] - half, centre[:2] + half
        segs = [
            np.array([[x, lo[1], 0.0], [x, hi[1], 0.0]])
            for x in np.arange(math.ceil(lo[0] / step), math.floor(hi[0] / step) + 1) * step
        ] + [
            np.array([[lo[0], y, 0.0], [hi[0], y, 0.0]])
            for y in np.arange(math.ceil(lo[1] / step), math.floor(hi[1] / step) + 1) * step
        ]
        self.grid_lines.set_segments(segs if abs(centre[2]) <= half else [])

    def floor(self, z: float, centre: np.ndarray, half: float) -> None:
        """A faint square on the floor at height ``z``, for depth."""
        x0, x1 = centre[0] - 0.8 * half, centre[0] + 0.8 * half
        y0, y1 = centre[1] - 0.8 * half, centre[1] + 0.8 * half
        xs, ys = [x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0]
        self.ax.plot(xs, ys, [z] * 5, "-", color=(0.75, 0.75, 0.75), lw=1.0)

    def draw(self, segments: list, colors: list, head: np.ndarray | None, label: str) -> np.ndarray:
        """Render one frame: ``segments`` ``[(2, 3) arrays]``, one colour each, a head point."""
        self.lines.set_segments(segments)
        self.lines.set_color(colors if colors else "none")
        if head is None:
            self.head.set_data_3d([], [], [])
        else:
            self.head.set_data_3d([head[0]], [head[1]], [head[2]])
        self.text.set_text(label)
        self.canvas.draw()
        rgb = np.asarray(self.canvas.buffer_rgba())[..., :3]
        w, h = self.size
        if rgb.shape[:2] != (h, w):  # never expected with an integral inch size at 100 dpi
            raise RuntimeError(f"matplotlib drew {rgb.shape[:2]} pixels, expected {(h, w)}")
        return np.ascontiguousarray(rgb)

    def close(self) -> None:
        self.fig.clear()


def side_color(name: str) -> tuple[float, float, float]:
    """The house colour of a body, site or bone named ``name``: left limbs orange (``Left...``,
    ``L...``, ``l_...``, ``left_...``), right limbs blue (the same with right), the rest dark
    grey."""
    if "Left" in name or name.startswith(("L", "l_", "left_")):
        return LEFT_COLOR
    if "Right" in name or name.startswith(("R", "r_", "right_")):
        return RIGHT_COLOR
    return CENTRE_COLOR


def _follow_box(points: np.ndarray, ok: np.ndarray, anchor: np.ndarray) -> tuple[np.ndarray, float]:
    """``robot_box`` with roots, of a point figure: ``(T, n, 3)`` world points (floor z = 0)
    of the ``(T,)`` ``ok`` frames about ``(T, 3)`` ``anchor`` (its x, y) -> ``(offset, half)``."""
    rel = points[ok] - (anchor[ok] * np.array([1.0, 1.0, 0.0]))[:, None, :]
    lo = np.minimum(rel.min(axis=(0, 1)), [np.inf, np.inf, 0.0])
    hi = rel.max(axis=(0, 1))
    return (lo + hi) / 2.0, max(float((hi - lo).max()) / 2.0 * BOX_SPARE, 0.3)


class _HumanPanel:
    """The Kinect skeleton in its own body frame (hips at 0), matplotlib; or, given
    ``world`` ``(T, 20, 3)`` (a whole-body motion: the person in the world frame, floor at
    z = 0), there, the view following the hips over the floor."""

    def __init__(
        self,
        positions: np.ndarray,
        size: tuple[int, int],
        camera: Camera,
        world: np.ndarray | None = None,
    ):
        import jax.numpy as jnp

        from jaxproj.human.skeleton import body_frame

        self.pairs = [(J[a], J[b]) for a, b in BONES]
        self.colors = [side_color(b) for _, b in BONES]
        self.world = world is not None
        if world is not None:
            self.points = np.asarray(world, np.float64)
            self.ok: np.ndarray = np.asarray(np.isfinite(self.points).all(axis=(1, 2)))
            hips = np.where(self.ok[:, None], self.points[:, J["HipCenter"]], 0.0)
            self.anchor = hips
            self.offset: np.ndarray = np.zeros(3)
            self.half = 1.0
            if self.ok.any():
                self.offset, self.half = _follow_box(self.points, self.ok, hips)
            self.canvas = _Canvas(size, camera, self.offset, self.half)
            return
        raw = np.asarray(positions, dtype=np.float32)
        p = np.where(np.isfinite(raw), raw, 0.0)  # non-finite frames: not ok, drawn empty
        rot_j, ok_j = body_frame(jnp.asarray(p))
        rot, ok = np.asarray(rot_j), np.asarray(ok_j) & np.isfinite(raw).all(axis=(1, 2))
        centred = np.where(ok[:, None, None], p - p[:, J["HipCenter"] : J["HipCenter"] + 1], 0.0)
        self.points = np.einsum("tij,tkj->tki", rot, centred)  # (T, 20, 3) body frame
        self.ok = ok & np.isfinite(self.points).all(axis=(1, 2))
        if self.ok.any():
            pts = self.points[self.ok]
            lo, hi = pts.min(axis=(0, 1)), pts.max(axis=(0, 1))
            centre, half = (lo + hi) / 2.0, float((hi - lo).max()) / 2.0 * 1.1
            floor = float(pts[:, [J["FootLeft"], J["FootRight"]], 2].min())
        else:
            centre, half, floor = np.zeros(3), 1.0, -1.0
        half = max(half, 0.3)
        self.canvas = _Canvas(size, camera, centre, half)
        self.canvas.floor(floor, centre, half)

    def draw(self, t: int, label: str) -> np.ndarray:
        if not self.ok[t]:
            return self.canvas.draw([], [], None, label + "\n(no skeleton)")
        pts = self.points[t]
        if self.world:
            self.canvas.follow(self.offset + self.anchor[t] * [1.0, 1.0, 0.0], self.half)
        segments = [pts[[i, j]] for i, j in self.pairs]
        return self.canvas.draw(segments, self.colors, pts[J["Head"]], label)

    def close(self) -> None:
        self.canvas.close()


class _StickRobotPanel:
    """A robot as a stick figure from MuJoCo CPU kinematics (no OpenGL), matplotlib: body origins
    joined parent -> child, its feet and head marker (``robot.mjcf.figure``), in the cube of
    ``robot_box`` over ``angles`` (``(N, n_joints)``, the frames to be drawn); with ``roots``
    (``(N, 7)``, a whole-body motion's root poses of those frames) in the world, the view
    following the root over the floor (``robot_box`` with ``roots``)."""

    name = "matplotlib"

    def __init__(
        self,
        robot: Robot,
        size: tuple[int, int],
        camera: Camera,
        angles: np.ndarray | None = None,
        roots: np.ndarray | None = None,
    ):
        import mujoco

        self._mj = mujoco
        self.robot = robot
        figure = robot.require_mjcf().figure
        self.world = roots is not None
        self.model = robot.load_model("free" if self.world else "fixed")
        self.data = mujoco.MjData(self.model)
        m = self.model
        body = {m.body(b).name: b for b in range(m.nbody)}
        site = {m.site(s).name: s for s in range(m.nsite)}
        self.data.qpos[:] = robot_qpos(robot, m, robot.standing)
        mujoco.mj_kinematics(m, self.data)
        # the figure's site links (as the report's sketch draws them), or else parent -> child
        # body origins (bodies at their parent's origin draw nothing; figure.parents: re-hung)
        ends = mj_site_ids(m, [n for link in figure.links for n in link])
        self.link_pairs = list(zip(ends[::2], ends[1::2], strict=True))
        self.colors = [side_color(b) for _, b in figure.links]
        self.body_pairs: list[tuple[int, int]] = []
        if not self.link_pairs:
            parent = {b: int(m.body_parentid[b]) for b in range(1, m.nbody)}
            for child, new in figure.parents.items():
                parent[body[child]] = body[new]
            self.body_pairs = [
                (parent[b], b)
                for b in range(1, m.nbody)
                if parent[b] != 0 and np.linalg.norm(m.body_pos[b]) > 1e-9
            ]
        self.colors += [side_color(m.body(b).name) for _, b in self.body_pairs]
        # ankle -> sole lines where the links do not draw the feet themselves
        self.site_pairs = [] if self.link_pairs else [(body[b], site[s]) for b, s in figure.feet]
        self.colors += [side_color(m.site(s).name) for _, s in self.site_pairs]
        self.head_geom = (
            None
            if figure.head_geom is None
            else mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, figure.head_geom)
        )
        soles = [site[s] for _, s in figure.feet] or [b for _, b in self.link_pairs]
        lowest = self.data.site_xpos[soles, 2] if soles else self.data.xpos[1:, 2]
        floor = float(lowest.min())
        if roots is not None:
            assert angles is not None
            self.offset, self.half = robot_box(robot, m, angles, roots)
            self.canvas = _Canvas(size, camera, self.offset, self.half)
            return
        centre, half = robot_box(robot, m, angles)  # after the standing kinematics above
        self.canvas = _Canvas(size, camera, centre, half)
        self.canvas.floor(floor, centre, half)

    def draw(self, angles: np.ndarray, label: str, root: np.ndarray | None = None) -> np.ndarray:
        """One frame: ``(n_joints,)`` angles, and ``(7,)`` its root pose for a whole-body
        panel."""
        d = self.data
        d.qpos[:] = robot_qpos(self.robot, self.model, angles, root)
        if self.world:
            assert root is not None
            self.canvas.follow(self.offset + np.array([root[0], root[1], 0.0]), self.half)
        self._mj.mj_kinematics(self.model, d)
        segments = [d.site_xpos[[a, b]].copy() for a, b in self.link_pairs]
        segments += [d.xpos[[a, b]].copy() for a, b in self.body_pairs]
        segments += [np.stack([d.xpos[b], d.site_xpos[s]]) for b, s in self.site_pairs]
        head = None if self.head_geom is None else d.geom_xpos[self.head_geom].copy()
        return self.canvas.draw(segments, self.colors, head, label)

    def close(self) -> None:
        self.canvas.close()
