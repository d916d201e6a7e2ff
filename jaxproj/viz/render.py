"""See the robot move: a ``Motion`` rendered to frames, an MP4 / GIF video, or a notebook clip.

Each frame holds two panels side by side, each ``size = (width, height)`` pixels: the human
skeleton (when ``motion.positions`` is given; a matplotlib 3-D stick figure) on the left and the
motion's robot (``motion.robot``) playing ``motion.angles`` on the right. Both are
seen from the same ``Camera`` direction in their own body frame (x forward, y left, z up): the
human in the body frame built from the skeleton itself (``jaxproj.human.skeleton.body_frame``,
hips at the origin), the robot with its root body welded where its MJCF puts it, each framed on
its figure over the frames drawn (``panels.robot_box``: any robot whole in the picture). Left
limbs are orange, right limbs blue (the MJCF's colours).

A whole-body motion (``Motion.root_pos`` / ``root_rot``: ``retarget --root world``) is drawn in
its world instead: the robot on its free joint at the root pose of each frame, over a floor at
z = 0 (MuJoCo: a 0.5 m checker plane, ``floor_model``; matplotlib: lines 0.5 m apart), the
person beside it in the same world frame (``whole_body.world_frame``: floor at z = 0, x the
first heading, robot metres); each panel's view follows its figure's root (hips) over the floor
(``panels.robot_box`` with the roots), so a walk is seen as the floor passing under the feet.

Backends of the robot panel (``render_frames(..., backend=)``):

- ``"mujoco"``: MuJoCo's offscreen OpenGL renderer (``mujoco.Renderer``) of the bundled MJCF,
  root body fixed, seen by a free camera. It needs an OpenGL context, chosen by the environment
  variable ``MUJOCO_GL`` *before* ``mujoco`` is first imported (jaxproj never sets it):
  ``MUJOCO_GL=egl`` (headless, NVIDIA driver or Mesa EGL), ``MUJOCO_GL=osmesa`` (software,
  libOSMesa) or the default GLFW, which needs a display. Without one ``RenderError`` says so.
- ``"matplotlib"``: no OpenGL: the robot as a 3-D stick figure, body origins from MuJoCo's CPU
  forward kinematics (``mj_kinematics``) joined parent -> child, plus soles and head.
- ``"auto"`` (default): ``"mujoco"`` if its renderer can be created, else one line on stderr and
  ``"matplotlib"``.

Videos (``save_video``): ``.mp4`` (H.264 through imageio's ffmpeg plugin, needs the
``imageio-ffmpeg`` package: ``pip install "jaxproj[video]"``) or ``.gif`` (imageio's Pillow
plugin; GIF delays are whole centiseconds, and Pillow merges identical consecutive frames, adding
their delays). Writes are atomic. A video plays in real time, by the motion's ``times``
(``playback``): its clock ticks at ``fps`` (default the motion's median frame rate divided by the
stride; at most ``MAX_GIF_FPS`` for a GIF), each tick shows the latest frame at or before it, so
a gap in the recording (frames the tracker dropped) is held on its last frame for as long as it
lasted rather than skipped.

The panels live in ``jaxproj.viz.panels`` (matplotlib) and here (MuJoCo), the video writers in
``jaxproj.viz.video``; this module re-exports their public names.

Size: about 590 lines: the two back-ends (MuJoCo, matplotlib), their shared framing and
the writers are one unit a reader checks together; the panels themselves live in
``viz.panels``.
"""

from __future__ import annotations

import base64
import gc
import math
import os
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal, NamedTuple, TypedDict, Unpack

import numpy as np

from jaxproj._internal.atomic import check_output
from jaxproj._internal.mujoco_gl import gl_failure
from jaxproj.errors import ConfigError
from jaxproj.io.motion_files import Motion, load_motion
from jaxproj.robots import Robot
from jaxproj.viz.panels import (
    CENTRE_COLOR,
    LEFT_COLOR,
    RIGHT_COLOR,
    Camera,
    _HumanPanel,
    _StickRobotPanel,
    robot_box,
    robot_label,
    robot_qpos,
)
from jaxproj.viz.video import (
    MAX_GIF_FPS,
    VIDEO_FORMATS,
    Playback,
    _gif_bytes,
    _require_ffmpeg,
    check_gif_fps,
    check_video_path,
    gif_delays_ms,
    playback,
    save_video,
)

Backend = Literal["auto", "mujoco", "matplotlib"]
BACKENDS: tuple[str, ...] = ("auto", "mujoco", "matplotlib")
"""Accepted values of ``backend=``."""

DEFAULT_SIZE: tuple[int, int] = (480, 360)
"""(width, height) of one panel, pixels."""

_MIN_SIDE, _MAX_SIDE = 32, 4096


class RenderError(ConfigError):
    """MuJoCo's OpenGL renderer cannot be created here; the message says what to set instead."""


# --- checks ---------------------------------------------------------------------------------


def _check_options(backend: str, size: object, stride: object, camera: object) -> tuple:
    if backend not in BACKENDS:
        raise ConfigError(f"backend must be one of {BACKENDS}, got {backend!r}")
    try:
        width, height = (int(v) for v in size)  # type: ignore[attr-defined]
        ok = tuple(size) == (width, height)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        ok = False
    if not ok or not all(_MIN_SIDE <= v <= _MAX_SIDE for v in (width, height)):
        raise ConfigError(
            f"size must be (width, height), whole pixels in {_MIN_SIDE}..{_MAX_SIDE}, got {size!r}"
        )
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise ConfigError(f"stride must be a whole number >= 1, got {stride!r}")
    camera = Camera() if camera is None else camera
    if not isinstance(camera, Camera):
        kind = type(camera).__name__
        raise ConfigError(f"camera must be a jaxproj.viz.render.Camera, got {kind}")
    return (width, height), int(stride), camera


def _check_motion(motion: object) -> Motion:
    if not isinstance(motion, Motion):
        kind = type(motion).__name__
        raise ConfigError(f"motion must be a jaxproj.io.motion_files.Motion, got {kind}")
    return motion


# --- MuJoCo panel ---------------------------------------------------------------------------


def _gl_hint() -> str:
    gl = os.environ.get("MUJOCO_GL", "")
    if not gl:
        return "MUJOCO_GL is unset, so MuJoCo uses GLFW, which needs a display"
    return f"MUJOCO_GL={gl}"


_GL_FIX = (
    "set MUJOCO_GL=egl before Python starts on a machine with an NVIDIA driver or Mesa EGL, or "
    "MUJOCO_GL=osmesa with libOSMesa installed; or use backend='matplotlib'"
)


_gl_failure: list[str] = []
"""The first renderer-creation failure of this process (MUJOCO_GL is read once, when mujoco is
imported, so a failure is final; and a second GLFW attempt can abort the process)."""


def _create_renderer(model: Any, width: int, height: int) -> Any:
    """``mujoco.Renderer(model, height, width)``, or RenderError saying what is missing.

    GLFW reports its failures as Python warnings from a C callback; they are captured here (and
    quoted in the error) rather than left to escape. After one failure, later calls raise the
    same RenderError without trying again.
    """
    import mujoco

    if not _gl_failure and gl_failure() is not None:  # MUJOCO_GL's back-end did not even load
        _gl_failure.append(f"MuJoCo cannot render: {gl_failure()}: {_GL_FIX}")
    if _gl_failure:
        raise RenderError(_gl_failure[0])
    problem = ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if not hasattr(mujoco, "Renderer"):
                # mujoco swallows the ImportError of its GL backend (e.g. PyOpenGL missing, or a
                # MUJOCO_GL backend whose library is absent): import it again to say which
                import mujoco.rendering.classic.gl_context  # noqa: F401
            return mujoco.Renderer(model, height=height, width=width)
        except Exception as e:  # mujoco.FatalError, RuntimeError (EGL), ImportError, ...
            problem = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
        # the half-built renderer dies with the traceback: let it go while warnings are captured
        gc.collect()
    notes = "; ".join(dict.fromkeys(str(w.message) for w in caught))
    detail = f"{problem} [{notes}]" if notes else problem
    _gl_failure.append(
        f"MuJoCo cannot create an OpenGL context for rendering ({_gl_hint()}; {detail}): {_GL_FIX}"
    )
    raise RenderError(_gl_failure[0])


def floor_model(robot: Robot) -> Any:
    """``robot``'s MJCF with its free joint (the whole-body mount) and a floor at z = 0: an
    infinite plane with a 0.5 m checker, for drawing only (it collides with nothing)."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.require_mjcf().path))
    spec.add_texture(name="jaxproj_floor", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.82, 0.82, 0.82],
                     rgb2=[0.66, 0.66, 0.66], width=64, height=64)  # fmt: skip
    mat = spec.add_material(name="jaxproj_floor", texrepeat=[1.0, 1.0], texuniform=True)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "jaxproj_floor"
    spec.worldbody.add_geom(name="jaxproj_floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[0.0, 0.0, 0.05], material="jaxproj_floor", contype=0,
                            conaffinity=0)  # fmt: skip
    spec.worldbody.add_light(name="jaxproj_sun", pos=[0.0, 0.0, 4.0], dir=[0.3, 0.2, -1.0],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, castshadow=False,
                             diffuse=[0.6, 0.6, 0.6])  # fmt: skip
    return spec.compile()


class _MujocoPanel:
    """A robot rendered by MuJoCo's OpenGL renderer, root body fixed, free camera (framed on
    ``robot_box`` over ``angles`` unless the camera says where); with ``roots`` (``(N, 7)``, a
    whole-body motion's root poses of those frames), on a floor in the world, the camera
    following the root (``robot_box`` with ``roots``)."""

    name = "mujoco"

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
        width, height = size
        self.world = roots is not None
        self.model = floor_model(robot) if self.world else robot.load_model("fixed")
        vis = self.model.vis.global_
        vis.offwidth, vis.offheight = max(vis.offwidth, width), max(vis.offheight, height)
        self.renderer = _create_renderer(self.model, width, height)
        self.data = mujoco.MjData(self.model)
        if roots is not None:
            assert angles is not None
            centre, half = robot_box(robot, self.model, angles, roots)
            self.offset = centre
        else:
            centre, half = robot_box(robot, self.model, angles)
        self.follow = self.world and camera.lookat is None
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = centre if camera.lookat is None else camera.lookat
        fit = half / math.sin(math.radians(float(vis.fovy)) / 2.0)  # the cube's sphere fills it
        cam.distance = fit if camera.distance is None else camera.distance
        cam.azimuth = camera.azimuth + 180.0  # MuJoCo: the direction the camera looks along
        cam.elevation = -camera.elevation
        self.camera = cam

    def draw(self, angles: np.ndarray, label: str, root: np.ndarray | None = None) -> np.ndarray:
        """One frame: ``(n_joints,)`` angles, and ``(7,)`` its root pose for a whole-body
        panel."""
        del label  # no text on OpenGL images
        self.data.qpos[:] = robot_qpos(self.robot, self.model, angles, root)
        if self.follow:
            assert root is not None
            self.camera.lookat[:] = self.offset + np.array([root[0], root[1], 0.0])
        self._mj.mj_forward(self.model, self.data)
        self.renderer.update_scene(self.data, camera=self.camera)
        return np.ascontiguousarray(self.renderer.render())

    def close(self) -> None:
        self.renderer.close()


def _robot_panel(
    robot: Robot,
    backend: str,
    size: tuple[int, int],
    camera: Camera,
    angles: np.ndarray | None = None,
    roots: np.ndarray | None = None,
) -> _MujocoPanel | _StickRobotPanel:
    """The robot panel of ``backend``, framed on ``robot`` in ``angles`` ``(N, n_joints)``
    (and, for a whole-body motion, their ``(N, 7)`` root poses ``roots``)."""
    if backend == "matplotlib":
        return _StickRobotPanel(robot, size, camera, angles, roots)
    try:
        return _MujocoPanel(robot, size, camera, angles, roots)
    except RenderError:
        if backend == "mujoco":
            raise
        print(
            f"jaxproj: no OpenGL for MuJoCo rendering ({_gl_hint()}): drawing the robot with the "
            "matplotlib backend instead (for MuJoCo images set MUJOCO_GL=egl or osmesa)",
            file=sys.stderr,
            flush=True,
        )
        return _StickRobotPanel(robot, size, camera, angles, roots)


# --- frames ---------------------------------------------------------------------------------


class _Frames:
    """The frames of a motion, produced one at a time (``iter``), and the backend used.

    ``index``: the motion frames to draw, in order."""

    def __init__(
        self,
        motion: Motion,
        backend: str,
        size: tuple[int, int],
        index: np.ndarray,
        camera: Camera,
    ):
        self.motion = motion
        self.index = np.asarray(index)
        self.roots = None
        if motion.root_pos is not None and motion.root_rot is not None:  # whole-body
            self.roots = np.concatenate([motion.root_pos, motion.root_rot], axis=1)
        drawn = None if self.roots is None else self.roots[self.index]
        self.robot = _robot_panel(motion.robot, backend, size, camera, motion.angles[self.index],
                                  drawn)  # fmt: skip
        self.label = robot_label(motion.robot)
        self.backend = self.robot.name
        self.human = None
        if motion.positions is not None:
            try:
                world = None if self.roots is None else _person_in_world(motion)
                self.human = _HumanPanel(motion.positions, size, camera, world)
            except BaseException:
                self.robot.close()  # an OpenGL context is freed now, never at exit
                raise

    def __len__(self) -> int:
        return len(self.index)

    def __iter__(self) -> Iterator[np.ndarray]:
        m = self.motion
        try:
            for i in self.index:
                t = int(i)
                held = "" if m.valid[t] else "\ninvalid input: pose held"
                clock = f"t={m.times[t] - m.times[0]:.2f}s #{t}"
                root = None if self.roots is None else self.roots[t]
                robot_img = self.robot.draw(m.angles[t], f"{self.label} {clock}{held}", root)
                if self.human is None:
                    yield robot_img
                else:
                    human_img = self.human.draw(t, "human")
                    yield np.concatenate([human_img, robot_img], axis=1)
        finally:
            self.close()

    def close(self) -> None:
        self.robot.close()
        if self.human is not None:
            self.human.close()


def _person_in_world(motion: Motion) -> np.ndarray:
    """A whole-body motion's person in the world frame its root was placed in (the recording's
    ``whole_body.world_frame``: floor at z = 0, x the first heading, robot metres)."""
    from jaxproj.motion.whole_body import world_frame

    assert motion.positions is not None
    p = np.asarray(motion.positions, np.float64)
    ok = motion.valid & np.isfinite(p).all(axis=(1, 2))
    out = world_frame(p, ok, motion.robot).to_world(p)
    return np.where(ok[:, None, None], out, np.nan)


def render_frames(
    motion: Motion,
    *,
    backend: Backend = "auto",
    size: tuple[int, int] = DEFAULT_SIZE,
    stride: int = 1,
    camera: Camera | None = None,
) -> np.ndarray:
    """Render a motion to RGB frames.

    Args:
      motion: the motion (``motion.positions``, when present, adds the human panel).
      backend: ``"auto"`` (MuJoCo if an OpenGL context can be made, else one line on stderr and
        matplotlib), ``"mujoco"`` or ``"matplotlib"`` (module docstring).
      size: ``(width, height)`` of each panel, pixels (32..4096).
      stride: render every ``stride``-th frame (frames ``0, stride, 2 * stride, ...``).
      camera: the viewpoint of both panels (default ``Camera()``).

    Returns:
      ``(N, height, W, 3)`` uint8 with ``N = ceil(T / stride)`` and ``W = 2 * width`` with a
      human panel (left), else ``width``.

    Raises:
      ConfigError: a bad option. RenderError (a ConfigError): ``backend="mujoco"`` and no OpenGL.
    """
    _check_motion(motion)
    size, stride, camera = _check_options(backend, size, stride, camera)
    index = np.arange(0, motion.n_frames, stride)
    return np.stack(list(_Frames(motion, backend, size, index, camera)))


class Rendered(NamedTuple):
    """What ``render_to_file`` wrote."""

    path: Path
    """The video file."""
    frames: int
    """Motion frames drawn (each once; ``playback``)."""
    backend: str
    """Robot panel backend used: ``"mujoco"`` or ``"matplotlib"``."""
    fps: float
    """The video's clock, frames per second."""
    seconds: float = 0.0
    """How long the video plays (real time: the motion's span plus one frame)."""
    longest_hold_s: float = 0.0
    """The longest time one frame stays on screen (a gap in the recording is held)."""
    human: bool = False
    """Whether the human skeleton was drawn (the motion holds ``positions``) beside the robot."""
    robot: str = "robot"
    """How the robot was named (``robot.mjcf.figure.label``)."""
    world: bool = False
    """Whether the motion was drawn in its world (a whole-body motion: root and floor)."""

    def describe(self) -> str:
        """What the video shows, in words (``jaxproj render`` prints it)."""
        who = (
            f"human skeleton (left) and {self.robot} (right) side by side"
            if self.human
            else f"the {self.robot} only (the motion holds no human positions: only an NPZ "
            "with `positions` has them)"
        )
        gap = (
            f", longest gap held {self.longest_hold_s:.2f} s"
            if self.longest_hold_s > 1.5 / self.fps
            else ""
        )
        world = "; whole body: the root in the world, over the floor" if self.world else ""
        return (
            f"{who}{world}; real time: {self.seconds:.2f} s at {self.fps:g} fps, {self.frames} "
            f"motion frames drawn{gap}; backend={self.backend}"
        )


class RenderOptions(TypedDict, total=False):
    """The keyword options of ``render_to_file`` / ``render_motion`` (see ``render_frames``)."""

    fps: float | None
    backend: Backend
    size: tuple[int, int]
    stride: int
    camera: Camera | None
    overwrite: bool


def render_to_file(
    motion: Motion,
    out: str | os.PathLike[str],
    *,
    fps: float | None = None,
    backend: Backend = "auto",
    size: tuple[int, int] = DEFAULT_SIZE,
    stride: int = 1,
    camera: Camera | None = None,
    overwrite: bool = True,
) -> Rendered:
    """``render_motion`` for a ``Motion``, telling what it did (the ``jaxproj render`` command);
    ``overwrite=False``: an existing ``out`` is a ConfigError, before anything is drawn.

    Returns:
      ``Rendered(path, frames, backend, fps, seconds, longest_hold_s, human)``.
    """
    out = Path(out)
    _check_motion(motion)
    ext = check_video_path(out)
    check_output(out, overwrite=overwrite)
    if ext == ".mp4":
        _require_ffmpeg()
    size, stride, camera = _check_options(backend, size, stride, camera)
    sched = playback(motion.times, _rate(motion, stride, fps, ext), stride)
    frames = _Frames(motion, backend, size, sched.frames, camera)
    try:
        path = save_video(frames, out, sched.fps, sched.holds, overwrite=overwrite)
    finally:
        frames.close()
    return Rendered(path, len(frames), frames.backend, sched.fps, sched.seconds,
                    sched.longest_hold_s, frames.human is not None, frames.label,
                    frames.roots is not None)  # fmt: skip


def _rate(motion: Motion, stride: int, fps: float | None, ext: str) -> float:
    """The video's clock: ``fps``, or the motion's rate / stride (at most ``MAX_GIF_FPS`` for a
    GIF); ConfigError for a bad one."""
    if fps is None:
        rate = motion.fps / stride
        return min(rate, MAX_GIF_FPS) if ext == ".gif" else rate
    rate = float(fps)
    if not (math.isfinite(rate) and rate > 0):
        raise ConfigError(f"fps must be a finite number > 0, got {fps}")
    if ext == ".gif":
        check_gif_fps(rate)
    return rate


def render_motion(
    motion: Motion | str | os.PathLike[str],
    out: str | os.PathLike[str],
    **options: Unpack[RenderOptions],
) -> Path:
    """Render a motion (or a motion file, read with ``load_motion``) to an MP4 / GIF video.

    Args:
      motion: a ``Motion`` or a ``.npz`` / ``.csv`` / ``.json`` motion file.
      out: ``.mp4`` or ``.gif`` (see ``save_video``).
      **options: ``RenderOptions``, as in ``render_to_file``: ``fps``, the video's clock,
        default the motion's frame rate (``Motion.fps``) divided by ``stride`` (at most
        ``MAX_GIF_FPS`` for a GIF); the video plays in real time by the motion's ``times`` at
        any ``fps`` (``playback``: a gap is held on its last frame); ``backend``, ``size``,
        ``stride``, ``camera`` as in ``render_frames``; ``overwrite`` as in
        ``render_to_file`` (``out`` naming the motion file is refused even with it).

    Returns:
      ``out`` as a ``Path``. Frames are streamed to MP4 (constant memory), gathered for GIF.

    Raises:
      ConfigError: a bad option or extension, an existing ``out`` with ``overwrite=False``,
        ``out`` the motion file (before anything is read or rendered).
      RenderError: ``backend="mujoco"`` and no OpenGL. InputError: a bad motion file, or the
        video cannot be written.
    """
    check_video_path(out)
    source = None if isinstance(motion, Motion) else motion
    check_output(out, overwrite=options.get("overwrite", True), inputs={"the motion file": source})
    m = motion if isinstance(motion, Motion) else load_motion(motion)
    return render_to_file(m, out, **options).path


def show(motion: Motion, *, fps: float | None = None, **kwargs: Any) -> Any:
    """A clip of the motion for a Jupyter notebook.

    Args:
      motion: the motion.
      fps: the clip's clock (default as ``render_motion`` for a GIF); it plays in real time.
      **kwargs: ``backend``, ``size``, ``stride``, ``camera`` of ``render_frames``.

    Returns:
      ``IPython.display.HTML`` holding an inline looping GIF when IPython is installed (a
      notebook displays it), else the ``(N, H, W, 3)`` uint8 frames of ``render_frames``.
    """
    unknown = set(kwargs) - {"backend", "size", "stride", "camera"}
    if unknown:
        raise TypeError(f"show() got unexpected keyword arguments {sorted(unknown)}")
    try:
        from IPython.display import HTML
    except ImportError:
        return render_frames(motion, **kwargs)
    _check_motion(motion)
    size, stride, camera = _check_options(
        kwargs.get("backend", "auto"), kwargs.get("size", DEFAULT_SIZE),
        kwargs.get("stride", 1), kwargs.get("camera"),
    )  # fmt: skip
    sched = playback(motion.times, _rate(motion, stride, fps, ".gif"), stride)
    frames = list(_Frames(motion, kwargs.get("backend", "auto"), size, sched.frames, camera))
    data = base64.b64encode(_gif_bytes(frames, sched.fps, sched.holds)).decode("ascii")
    return HTML(f'<img src="data:image/gif;base64,{data}" alt="jaxproj motion"/>')


__all__ = [
    "BACKENDS",
    "MAX_GIF_FPS",
    "CENTRE_COLOR",
    "DEFAULT_SIZE",
    "LEFT_COLOR",
    "Playback",
    "RIGHT_COLOR",
    "VIDEO_FORMATS",
    "Backend",
    "Camera",
    "RenderError",
    "RenderOptions",
    "Rendered",
    "check_video_path",
    "floor_model",
    "gif_delays_ms",
    "playback",
    "render_frames",
    "render_motion",
    "render_to_file",
    "save_video",
    "show",
]
