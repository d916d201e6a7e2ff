"""See the robot move: a ``Motion`` rendered to frames, an MP4 / GIF video, or a notebook clip.

Each frame holds two panels side by side, each ``size = (width, height)`` pixels: the human
skeleton (when ``motion.positions`` is given; a matplotlib 3-D stick figure) on the left and the
NAO playing ``motion.angles`` on the right. Both are seen from the same ``Camera`` direction in
their own body frame (x forward, y left, z up): the human in the body frame built from the
skeleton itself (``jaxproj.human.skeleton.body_frame``, hips at the origin; the frame the descriptor and
the IK use), the robot in its torso frame. Left limbs are orange, right limbs blue (the MJCF's
colours).

Backends of the robot panel (``render_frames(..., backend=)``):

- ``"mujoco"``: MuJoCo's offscreen OpenGL renderer (``mujoco.Renderer``) of the bundled MJCF,
  torso fixed, seen by a free camera. It needs an OpenGL context, chosen by the environment
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
their delays). Writes are atomic. The default playback rate is the motion's frame rate divided by
the stride.
"""

from __future__ import annotations

import base64
import gc
import math
import os
import sys
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np

from jaxproj._internal.atomic import atomic_write
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import BONES, J
from jaxproj.io.motion_files import Motion, load_motion
from jaxproj.robots.nao_h25 import robot

Backend = Literal["auto", "mujoco", "matplotlib"]
BACKENDS: tuple[str, ...] = ("auto", "mujoco", "matplotlib")
"""Accepted values of ``backend=``."""

VIDEO_FORMATS: tuple[str, ...] = (".mp4", ".gif")
"""Extensions ``save_video`` writes."""

DEFAULT_SIZE: tuple[int, int] = (480, 360)
"""(width, height) of one panel, pixels."""

LEFT_COLOR = (0.95, 0.6, 0.2)
RIGHT_COLOR = (0.2, 0.6, 0.95)
CENTRE_COLOR = (0.25, 0.25, 0.3)

_DPI = 100
_MIN_SIDE, _MAX_SIDE = 32, 4096

# the robot panel's fixed box (torso frame, m): the NAO spans z -0.333 (soles, standing
# straight) .. +0.33 (hands up), |x|, |y| < 0.33 with the arms out
_ROBOT_CENTRE = np.array([0.0, 0.0, -0.02])
_ROBOT_HALF = 0.34


class RenderError(ConfigError):
    """MuJoCo's OpenGL renderer cannot be created here; the message says what to set instead."""


@dataclass(frozen=True)
class Camera:
    """Where both panels are seen from, in the body / torso frame (x forward, y left, z up).

    Attributes:
      azimuth: degrees; direction of the viewer around the vertical axis, from straight in front
        (0, on +x) towards the figure's left (+90, on +y). The default, 30, sees the figure from
        the front, a little from its left side (its left arm appears on the viewer's right).
      elevation: degrees above the horizontal (-90 < elevation < 90).
      distance: m, camera to ``lookat`` (MuJoCo panel; the matplotlib panels fit a fixed box).
      lookat: the point looked at, torso frame, m (MuJoCo panel).
    """

    azimuth: float = 30.0
    elevation: float = 12.0
    distance: float = 1.1
    lookat: tuple[float, float, float] = (0.0, 0.0, -0.02)

    def __post_init__(self) -> None:
        try:
            lookat = tuple(float(v) for v in self.lookat)
            values = (float(self.azimuth), float(self.elevation), float(self.distance), *lookat)
        except (TypeError, ValueError):
            values, lookat = (math.nan,), ()
        if len(lookat) != 3 or not all(math.isfinite(v) for v in values):
            raise ConfigError(f"camera values must be finite numbers, lookat 3 of them: {self}")
        object.__setattr__(self, "lookat", lookat)
        if not -90.0 < self.elevation < 90.0:
            raise ConfigError(
                f"camera elevation must lie in (-90, 90) degrees, got {self.elevation}"
            )
        if self.distance <= 0:
            raise ConfigError(f"camera distance must be > 0 m, got {self.distance}")


# --- checks ---------------------------------------------------------------------------------


def _check_options(backend: str, size: object, stride: object, camera: object) -> tuple:
    if backend not in BACKENDS:
        raise ConfigError(f"backend must be one of {BACKENDS}, got {backend!r}")
    try:
        width, height = (int(v) for v in size)  # type: ignore[union-attr]
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
        raise ConfigError(f"camera must be a jaxproj.viz.render.Camera, got {type(camera).__name__}")
    return (width, height), int(stride), camera


def _check_motion(motion: object) -> Motion:
    if not isinstance(motion, Motion):
        raise ConfigError(f"motion must be a jaxproj.io.motion_files.Motion, got {type(motion).__name__}")
    return motion


def check_video_path(out: str | os.PathLike[str]) -> str:
    """The lower-case extension of ``out`` if ``save_video`` writes it, else ConfigError."""
    out = Path(out)
    ext = out.suffix.lower()
    if ext not in VIDEO_FORMATS:
        raise ConfigError(
            f"{out}: unsupported video extension {out.suffix!r}; use one of "
            f"{', '.join(VIDEO_FORMATS)}"
        )
    return ext


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
        ax = self.fig.add_axes((0.0, 0.0, 1.0, 0.93), projection="3d")
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


def _side_color(name: str) -> tuple[float, float, float]:
    if "Left" in name or name.startswith(("L", "l_")):
        return LEFT_COLOR
    if "Right" in name or name.startswith(("R", "r_")):
        return RIGHT_COLOR
    return CENTRE_COLOR


class _HumanPanel:
    """The Kinect skeleton in its own body frame (hips at 0), matplotlib."""

    def __init__(self, positions: np.ndarray, size: tuple[int, int], camera: Camera):
        import jax.numpy as jnp

        from jaxproj.human.skeleton import body_frame

        raw = np.asarray(positions, dtype=np.float32)
        p = np.where(np.isfinite(raw), raw, 0.0)  # non-finite frames: not ok, drawn empty
        rot, ok = body_frame(jnp.asarray(p))
        rot, ok = np.asarray(rot), np.asarray(ok) & np.isfinite(raw).all(axis=(1, 2))
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
        self.pairs = [(J[a], J[b]) for a, b in BONES]
        self.colors = [_side_color(b) for _, b in BONES]

    def draw(self, t: int, label: str) -> np.ndarray:
        if not self.ok[t]:
            return self.canvas.draw([], [], None, label + "\n(no skeleton)")
        pts = self.points[t]
        segments = [pts[[i, j]] for i, j in self.pairs]
        return self.canvas.draw(segments, self.colors, pts[J["Head"]], label)

    def close(self) -> None:
        self.canvas.close()


class _StickRobotPanel:
    """The NAO as a stick figure from MuJoCo CPU kinematics (no OpenGL), matplotlib."""

    name = "matplotlib"

    def __init__(self, size: tuple[int, int], camera: Camera):
        import mujoco

        self._mj = mujoco
        self.model = robot.load_model("fixed")
        self.data = mujoco.MjData(self.model)
        m = self.model
        body = {m.body(b).name: b for b in range(m.nbody)}
        site = {m.site(s).name: s for s in range(m.nsite)}
        self.data.qpos[:] = robot.config_to_qpos(m, robot.STANDING_POSTURE)
        mujoco.mj_kinematics(m, self.data)
        # parent -> child body origins; bodies at their parent's origin draw nothing
        # (the shoulders hang from the neck, as the skeleton's from ShoulderCenter)
        parent = {b: int(m.body_parentid[b]) for b in range(1, m.nbody)}
        parent[body["LShoulder"]] = parent[body["RShoulder"]] = body["Neck"]
        self.body_pairs = [
            (parent[b], b)
            for b in range(1, m.nbody)
            if parent[b] != 0 and np.linalg.norm(m.body_pos[b]) > 1e-9
        ]
        self.site_pairs = [(body["l_ankle"], site["l_sole"]), (body["r_ankle"], site["r_sole"])]
        self.colors = [_side_color(m.body(b).name) for _, b in self.body_pairs]
        self.colors += [LEFT_COLOR, RIGHT_COLOR]
        self.head_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "head_geom")
        floor = float(self.data.site_xpos[[site["l_sole"], site["r_sole"]], 2].min())
        self.canvas = _Canvas(size, camera, _ROBOT_CENTRE, _ROBOT_HALF)
        self.canvas.floor(floor, _ROBOT_CENTRE, _ROBOT_HALF)

    def draw(self, angles: np.ndarray, label: str) -> np.ndarray:
        d = self.data
        d.qpos[:] = robot.config_to_qpos(self.model, angles)
        self._mj.mj_kinematics(self.model, d)
        segments = [d.xpos[[a, b]].copy() for a, b in self.body_pairs]
        segments += [np.stack([d.xpos[b], d.site_xpos[s]]) for b, s in self.site_pairs]
        return self.canvas.draw(segments, self.colors, d.geom_xpos[self.head_geom].copy(), label)

    def close(self) -> None:
        self.canvas.close()


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


class _MujocoPanel:
    """The NAO rendered by MuJoCo's OpenGL renderer, torso fixed, free camera."""

    name = "mujoco"

    def __init__(self, size: tuple[int, int], camera: Camera):
        import mujoco

        self._mj = mujoco
        width, height = size
        self.model = robot.load_model("fixed")
        vis = self.model.vis.global_
        vis.offwidth, vis.offheight = max(vis.offwidth, width), max(vis.offheight, height)
        self.renderer = _create_renderer(self.model, width, height)
        self.data = mujoco.MjData(self.model)
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = camera.lookat
        cam.distance = camera.distance
        cam.azimuth = camera.azimuth + 180.0  # MuJoCo: the direction the camera looks along
        cam.elevation = -camera.elevation
        self.camera = cam

    def draw(self, angles: np.ndarray, label: str) -> np.ndarray:
        del label  # no text on OpenGL images
        self.data.qpos[:] = robot.config_to_qpos(self.model, angles)
        self._mj.mj_forward(self.model, self.data)
        self.renderer.update_scene(self.data, camera=self.camera)
        return np.ascontiguousarray(self.renderer.render())

    def close(self) -> None:
        self.renderer.close()


def _robot_panel(
    backend: str, size: tuple[int, int], camera: Camera
) -> _MujocoPanel | _StickRobotPanel:
    if backend == "matplotlib":
        return _StickRobotPanel(size, camera)
    try:
        return _MujocoPanel(size, camera)
    except RenderError:
        if backend == "mujoco":
            raise
        print(
            f"jaxproj: no OpenGL for MuJoCo rendering ({_gl_hint()}): drawing the robot with the "
            "matplotlib backend instead (for MuJoCo images set MUJOCO_GL=egl or osmesa)",
            file=sys.stderr,
            flush=True,
        )
        return _StickRobotPanel(size, camera)


# --- frames ---------------------------------------------------------------------------------


class _Frames:
    """The frames of a motion, produced one at a time (``iter``), and the backend used."""

    def __init__(
        self,
        motion: Motion,
        backend: str,
        size: tuple[int, int],
        stride: int,
        camera: Camera,
    ):
        self.motion = motion
        self.index = np.arange(0, motion.n_frames, stride)
        self.robot = _robot_panel(backend, size, camera)
        self.backend = self.robot.name
        self.human = None
        if motion.positions is not None:
            try:
                self.human = _HumanPanel(motion.positions, size, camera)
            except BaseException:
                self.robot.close()  # an OpenGL context is freed now, never at exit
                raise

    def __len__(self) -> int:
        return len(self.index)

    def __iter__(self) -> Iterator[np.ndarray]:
        m = self.motion
        try:
            for t in self.index:
                t = int(t)
                held = "" if m.valid[t] else "\ninvalid input: pose held"
                clock = f"t={m.times[t] - m.times[0]:.2f}s #{t}"
                robot_img = self.robot.draw(m.angles[t], f"NAO {clock}{held}")
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
    return np.stack(list(_Frames(motion, backend, size, stride, camera)))


# --- videos ---------------------------------------------------------------------------------


def _require_ffmpeg() -> None:
    try:
        import imageio_ffmpeg
    except ImportError:
        raise ConfigError(
            "writing .mp4 needs the imageio-ffmpeg package: pip install imageio-ffmpeg (or "
            '"jaxproj[video]"), or write a .gif'
        ) from None
    try:
        imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as e:
        raise ConfigError(
            f"imageio-ffmpeg finds no ffmpeg executable ({e}); write a .gif"
        ) from None


def _checked(frames: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
    """The frames, each checked to be ``(H, W, 3)`` uint8 of one shape; at least one."""
    shape = None
    for i, frame in enumerate(frames):
        f = np.asarray(frame)
        if f.dtype != np.uint8 or f.ndim != 3 or f.shape[2] != 3:
            raise ConfigError(f"frame {i} must be (H, W, 3) uint8, got {f.dtype} {f.shape}")
        if shape is None:
            shape = f.shape
        elif f.shape != shape:
            raise ConfigError(f"frame {i} has shape {f.shape}, frame 0 {shape}")
        yield f
    if shape is None:
        raise ConfigError("no frames to write")


def _even(frame: np.ndarray) -> np.ndarray:
    """H.264 (yuv420p) needs even sides: repeat the last row / column where one is odd."""
    h, w = frame.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return frame
    return np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")


def _write_mp4(tmp: Path, frames: Iterable[np.ndarray], fps: float) -> None:
    """H.264 MP4 through the ffmpeg binary of imageio-ffmpeg, raw RGB frames on its stdin.

    The pipe is opened here rather than by imageio's writer, which starts ffmpeg with a
    ``preexec_fn``: that forks the interpreter, and a fork after JAX has started warns (JAX is
    multithreaded). A plain ``Popen`` does not fork the interpreter.
    """
    import subprocess

    import imageio_ffmpeg

    it = _checked(frames)
    first = _even(next(it))
    h, w = first.shape[:2]
    cmd = [
        imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-hide_banner", "-loglevel", "error",
        "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}", "-framerate", repr(fps),
        "-i", "-", "-an", "-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "20",
        "-movflags", "+faststart", str(tmp),
    ]  # fmt: skip
    proc = subprocess.Popen(
        cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    assert proc.stdin is not None and proc.stderr is not None
    try:
        try:
            proc.stdin.write(first.tobytes())
            for frame in it:
                proc.stdin.write(_even(frame).tobytes())
            proc.stdin.close()
        except BrokenPipeError:
            pass  # ffmpeg stopped early: its exit status and message tell why
        err = proc.stderr.read().decode(errors="replace").strip()
        code = proc.wait()
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    finally:
        for pipe in (proc.stdin, proc.stderr):
            if not pipe.closed:
                pipe.close()
    if code != 0:
        last = err.splitlines()[-1] if err else "no message"
        raise OSError(f"ffmpeg failed with exit status {code}: {last}")


def _gif_bytes(frames: Iterable[np.ndarray], fps: float) -> bytes:
    import imageio.v3 as iio

    stack = np.stack(list(_checked(frames)))
    delay_ms = 10 * max(1, round(100.0 / fps))  # GIF delays are whole centiseconds
    return iio.imwrite(
        "<bytes>", stack, extension=".gif", plugin="pillow", duration=delay_ms, loop=0
    )


def save_video(
    frames: np.ndarray | Iterable[np.ndarray], out: str | os.PathLike[str], fps: float
) -> Path:
    """Write frames as a video, atomically (a failed write leaves nothing behind).

    Args:
      frames: ``(N, H, W, 3)`` uint8, or an iterable of ``(H, W, 3)`` uint8 frames (streamed to
        MP4, gathered for GIF).
      out: ``.mp4`` (H.264, yuv420p; an odd height or width is padded by one repeated row /
        column; needs ``imageio-ffmpeg``) or ``.gif`` (Pillow, looping; the delay is rounded to
        whole centiseconds).
      fps: playback frames per second (> 0).

    Returns:
      ``out`` as a ``Path``.

    Raises:
      ConfigError: an unsupported extension, a bad ``fps``, bad frames, or ``.mp4`` without
        ``imageio-ffmpeg``.
      InputError: the file cannot be written.
    """
    out = Path(out)
    ext = check_video_path(out)
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be a finite number > 0, got {fps}")
    if ext == ".mp4":
        _require_ffmpeg()
        return atomic_write(out, lambda tmp: _write_mp4(tmp, frames, fps))
    return atomic_write(out, lambda tmp: tmp.write_bytes(_gif_bytes(frames, fps)))


class Rendered(NamedTuple):
    """What ``render_to_file`` wrote."""

    path: Path
    """The video file."""
    frames: int
    """Frames written."""
    backend: str
    """Robot panel backend used: ``"mujoco"`` or ``"matplotlib"``."""
    fps: float
    """Playback rate, frames per second."""


def render_to_file(
    motion: Motion,
    out: str | os.PathLike[str],
    *,
    fps: float | None = None,
    backend: Backend = "auto",
    size: tuple[int, int] = DEFAULT_SIZE,
    stride: int = 1,
    camera: Camera | None = None,
) -> Rendered:
    """``render_motion`` for a ``Motion``, telling what it did (the ``jaxproj render`` command).

    Returns:
      ``Rendered(path, frames, backend, fps)``.
    """
    out = Path(out)
    _check_motion(motion)
    if check_video_path(out) == ".mp4":
        _require_ffmpeg()
    size, stride, camera = _check_options(backend, size, stride, camera)
    rate = motion.fps / stride if fps is None else float(fps)
    if not (math.isfinite(rate) and rate > 0):
        raise ConfigError(f"fps must be a finite number > 0, got {fps}")
    frames = _Frames(motion, backend, size, stride, camera)
    try:
        path = save_video(frames, out, rate)
    finally:
        frames.close()
    return Rendered(path, len(frames), frames.backend, rate)


def render_motion(
    motion: Motion | str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    fps: float | None = None,
    backend: Backend = "auto",
    size: tuple[int, int] = DEFAULT_SIZE,
    stride: int = 1,
    camera: Camera | None = None,
) -> Path:
    """Render a motion (or a motion file, read with ``load_motion``) to an MP4 / GIF video.

    Args:
      motion: a ``Motion`` or a ``.npz`` / ``.csv`` / ``.json`` motion file.
      out: ``.mp4`` or ``.gif`` (see ``save_video``).
      fps: playback rate; default the motion's frame rate (``Motion.fps``) divided by ``stride``,
        so the video plays in real time.
      backend, size, stride, camera: as in ``render_frames``.

    Returns:
      ``out`` as a ``Path``. Frames are streamed to MP4 (constant memory), gathered for GIF.

    Raises:
      ConfigError: a bad option or extension (before anything is read or rendered).
      RenderError: ``backend="mujoco"`` and no OpenGL. InputError: a bad motion file, or the
        video cannot be written.
    """
    check_video_path(out)
    m = motion if isinstance(motion, Motion) else load_motion(motion)
    kw = {"fps": fps, "backend": backend, "size": size, "stride": stride, "camera": camera}
    return render_to_file(m, out, **kw).path


def show(motion: Motion, *, fps: float | None = None, **kwargs: Any) -> Any:
    """A clip of the motion for a Jupyter notebook.

    Args:
      motion: the motion.
      fps: playback rate (default as ``render_motion``).
      **kwargs: ``backend``, ``size``, ``stride``, ``camera`` of ``render_frames``.

    Returns:
      ``IPython.display.HTML`` holding an inline looping GIF when IPython is installed (a
      notebook displays it), else the ``(N, H, W, 3)`` uint8 frames.
    """
    frames = render_frames(motion, **kwargs)
    try:
        from IPython.display import HTML
    except ImportError:
        return frames
    rate = motion.fps / int(kwargs.get("stride", 1)) if fps is None else float(fps)
    data = base64.b64encode(_gif_bytes(frames, rate)).decode("ascii")
    return HTML(f'<img src="data:image/gif;base64,{data}" alt="jaxproj motion"/>')
