"""Rendering (jaxproj.viz.render): frames from both backends, the no-OpenGL fallback, videos, the
notebook helper and the `jaxproj render` command. CPU only, small motions and sizes."""

import base64
import gc
import json
import os
import subprocess
import sys
import textwrap
import types
import warnings

import imageio.v2 as iio2
import imageio.v3 as iio
import numpy as np
import pytest

from jaxproj import robots
from jaxproj.cli import main
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import J
from jaxproj.io.motion_files import Motion, save_motion
from jaxproj.robots.nao_h25 import robot
from jaxproj.viz import render
from jaxproj.viz.panels import _StickRobotPanel
from jaxproj.viz.render import RenderError, render_frames, render_motion, save_video, show

SIZE = (120, 90)  # one panel, (width, height)
LABEL_ROWS = 20  # the text line at the top of a matplotlib panel


def _skeleton(arm_up: float = 0.0) -> np.ndarray:
    """(20, 3) a person facing the sensor (Kinect frame: y up, facing -z); ``arm_up`` raises
    the left forearm (m)."""
    p = {
        "HipCenter": (0.0, 0.0, 2.0), "Spine": (0.0, 0.1, 2.0),
        "ShoulderCenter": (0.0, 0.45, 2.0), "Head": (0.0, 0.65, 2.0),
        "ShoulderLeft": (-0.18, 0.42, 2.0), "ElbowLeft": (-0.22, 0.15, 2.0),
        "WristLeft": (-0.24, -0.08 + arm_up, 2.0 - arm_up / 2),
        "HandLeft": (-0.25, -0.15 + arm_up, 2.0),
        "ShoulderRight": (0.18, 0.42, 2.0), "ElbowRight": (0.22, 0.15, 2.0),
        "WristRight": (0.24, -0.08, 2.0), "HandRight": (0.25, -0.15, 2.0),
        "HipLeft": (-0.1, -0.05, 2.0), "KneeLeft": (-0.1, -0.45, 2.0),
        "AnkleLeft": (-0.1, -0.85, 2.0), "FootLeft": (-0.1, -0.9, 1.92),
        "HipRight": (0.1, -0.05, 2.0), "KneeRight": (0.1, -0.45, 2.0),
        "AnkleRight": (0.1, -0.85, 2.0), "FootRight": (0.1, -0.9, 1.92),
    }  # fmt: skip
    out = np.zeros((20, 3), np.float32)
    for name, xyz in p.items():
        out[J[name]] = xyz
    return out


def _arm_up() -> np.ndarray:
    q = robot.STANDING_POSTURE.copy()
    q[robot.IDX["LShoulderPitch"]] = -1.4  # left arm raised forward-up
    q[robot.IDX["LShoulderRoll"]] = 0.3
    return q


def _motion(angles: list[np.ndarray], positions: bool = True, fps: float = 15.0) -> Motion:
    n = len(angles)
    pos = None
    if positions:
        pos = np.stack([_skeleton(0.3 * i) for i in range(n)])
    return Motion(np.stack(angles), np.arange(n) / fps, np.ones(n, bool), pos, {"method": "ik"})


def _ink(img: np.ndarray) -> int:
    """Pixels that are not (near) white: what was drawn on a matplotlib panel."""
    return int((img.astype(int).sum(axis=-1) < 3 * 230).sum())


def _changed(a: np.ndarray, b: np.ndarray) -> int:
    return int((np.abs(a.astype(int) - b.astype(int)).sum(axis=-1) > 30).sum())


def test_matplotlib_frames_have_both_panels(capsys):
    stand = robot.STANDING_POSTURE
    m = _motion([stand, stand, _arm_up(), _arm_up(), stand])
    frames = render_frames(m, backend="matplotlib", size=SIZE)
    w, h = SIZE
    assert frames.shape == (5, h, 2 * w, 3) and frames.dtype == np.uint8
    human, nao = frames[:, :, :w], frames[:, :, w:]
    for t in range(5):
        assert _ink(human[t, LABEL_ROWS:]) > 150  # a skeleton is drawn
        assert _ink(nao[t, LABEL_ROWS:]) > 150  # and a robot
    # the robot panel follows the angles: same angles, same picture (below the clock line) ...
    assert _changed(nao[0, LABEL_ROWS:], nao[1, LABEL_ROWS:]) == 0
    assert _changed(nao[2, LABEL_ROWS:], nao[3, LABEL_ROWS:]) == 0
    # ... arm up vs arm down differ, and the human panel follows the positions
    assert _changed(nao[1, LABEL_ROWS:], nao[2, LABEL_ROWS:]) > 40
    assert _changed(human[0, LABEL_ROWS:], human[1, LABEL_ROWS:]) > 10
    assert capsys.readouterr().err == ""  # matplotlib asked for: no fallback message


def test_without_positions_only_the_robot_and_stride():
    m = _motion([robot.STANDING_POSTURE] * 5, positions=False)
    frames = render_frames(m, backend="matplotlib", size=SIZE, stride=2)
    assert frames.shape == (3, SIZE[1], SIZE[0], 3)  # frames 0, 2, 4; one panel


def test_bad_options():
    m = _motion([robot.STANDING_POSTURE], positions=False)
    for kw, match in (
        ({"backend": "vulkan"}, "backend"),
        ({"size": (10, 10)}, "size"),
        ({"size": (120.5, 90)}, "size"),
        ({"stride": 0}, "stride"),
        ({"camera": "front"}, "Camera"),
    ):
        with pytest.raises(ConfigError, match=match):
            render_frames(m, **kw)
    with pytest.raises(ConfigError, match="elevation"):
        render.Camera(elevation=90.0)


def _no_gl(*args, **kwargs):
    raise RenderError("MuJoCo cannot create an OpenGL context for rendering (test): fix it")


def test_auto_falls_back_to_matplotlib_with_one_stderr_line(monkeypatch, capsys):
    monkeypatch.setattr(render, "_create_renderer", _no_gl)
    m = _motion([robot.STANDING_POSTURE, _arm_up()], positions=False)
    frames = render_frames(m, backend="auto", size=SIZE)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no OpenGL" in err and "matplotlib" in err
    assert "MUJOCO_GL=egl" in err
    np.testing.assert_array_equal(frames, render_frames(m, backend="matplotlib", size=SIZE))
    with pytest.raises(RenderError, match="OpenGL"):
        render_frames(m, backend="mujoco", size=SIZE)


def _gl_expected_missing() -> bool:
    """GLFW (MuJoCo's default) cannot open a context without a display."""
    env = os.environ
    return not env.get("MUJOCO_GL") and not env.get("DISPLAY") and not env.get("WAYLAND_DISPLAY")


def _check_mujoco_frames(frames: np.ndarray) -> None:
    """Real MuJoCo images: not blank, and the raised arm shows."""
    assert frames.shape == (2, SIZE[1], SIZE[0], 3) and frames.dtype == np.uint8
    for f in frames:
        lit = (f.astype(int).sum(axis=-1) > 60).sum()  # the background is black
        assert lit > 0.03 * f.shape[0] * f.shape[1]
    assert _changed(frames[0], frames[1]) > 40


def test_real_mujoco_renderer_renders_or_says_what_is_missing():
    """No mock: MuJoCo's renderer under this process's MUJOCO_GL. It must render real pixels,
    or (and only where no OpenGL can exist: GLFW without a display) raise the clear error."""
    m = _motion([robot.STANDING_POSTURE, _arm_up()], positions=False)
    try:
        frames = render_frames(m, backend="mujoco", size=SIZE)
    except RenderError as e:
        msg = str(e)
        assert "MUJOCO_GL" in msg and "backend='matplotlib'" in msg and "\n" not in msg
        assert os.environ.get("MUJOCO_GL") or "needs a display" in msg
        return
    assert not _gl_expected_missing(), "GLFW rendered without a display?"
    _check_mujoco_frames(frames)


_EGL_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    try:
        from jaxproj.viz import render
        from jaxproj.robots.nao_h25 import robot
        from jaxproj.io.motion_files import Motion
    except Exception as e:  # mujoco could not load EGL at import
        print(json.dumps({"status": "import", "msg": repr(e)})); sys.exit()
    q = robot.STANDING_POSTURE.copy()
    up = q.copy(); up[robot.IDX["LShoulderPitch"]] = -1.4; up[robot.IDX["LShoulderRoll"]] = 0.3
    m = Motion(np.stack([q, up]), np.arange(2) / 15, np.ones(2, bool))
    try:
        f = render.render_frames(m, backend="mujoco", size=(120, 90))
    except render.RenderError as e:
        print(json.dumps({"status": "render_error", "msg": str(e)})); sys.exit()
    np.save(sys.argv[1], f)
    print(json.dumps({"status": "ok"}))
    """
)


def test_mujoco_renderer_with_egl_in_a_fresh_process(tmp_path):
    """MUJOCO_GL is read when mujoco is imported: try EGL (NVIDIA or Mesa) in a new process."""
    env = {**os.environ, "MUJOCO_GL": "egl", "PYOPENGL_PLATFORM": "egl"}
    out = tmp_path / "frames.npy"
    proc = subprocess.run(
        [sys.executable, "-c", _EGL_SCRIPT, str(out)],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    if result["status"] == "import":
        pytest.skip(f"mujoco cannot load EGL on this machine: {result['msg']}")
    if result["status"] == "render_error":
        assert "MUJOCO_GL=egl" in result["msg"] and "backend='matplotlib'" in result["msg"]
        return
    assert result["status"] == "ok"
    _check_mujoco_frames(np.load(out))
    assert "Exception ignored" not in proc.stderr  # the GL context was freed, not left to exit


def _frames(n: int = 6, h: int = 48, w: int = 64) -> np.ndarray:
    """Distinct, compressible frames: a bright square moving over a dark gradient."""
    f = np.zeros((n, h, w, 3), np.uint8)
    f[..., 2] = np.linspace(0, 120, w, dtype=np.uint8)
    for i in range(n):
        f[i, 8:24, 4 + 6 * i : 20 + 6 * i] = (250, 200, 40)
    return f


def _read_mp4(path) -> tuple[int, tuple[int, ...], float]:
    """(frames, frame shape, fps) through imageio's ffmpeg reader, which leaves its pipes to
    the garbage collector when closed (ResourceWarning, an error under pytest): ignored here."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        with iio2.get_reader(path, format="FFMPEG") as r:
            n = r.count_frames()
            first = r.get_data(0)
            fps = r.get_meta_data()["fps"]
        gc.collect()
    return n, first.shape, fps


@pytest.fixture
def no_sigint_fork(monkeypatch):
    """imageio's ffmpeg *reader* starts ffmpeg with a preexec_fn, a fork that JAX warns about
    (and pytest makes warnings errors); the library's own writer never forks."""
    monkeypatch.setenv("IMAGEIO_FFMPEG_NO_PREVENT_SIGINT", "1")


def test_save_video_gif_and_mp4_read_back(tmp_path, no_sigint_fork):
    frames = _frames()
    gif = save_video(frames, tmp_path / "a.gif", fps=10)
    back = iio.imread(gif, index=None)
    assert back.shape == frames.shape
    assert iio.immeta(gif)["duration"] == 100
    np.testing.assert_allclose(back[2, 16, 10], frames[2, 16, 10], atol=12)  # the square
    (tmp_path / "sub").mkdir()  # writers create no folder (jaxproj._internal.atomic)
    mp4 = save_video(iter(list(frames)), tmp_path / "sub" / "a.mp4", fps=7.5)  # streamed
    n, shape, fps = _read_mp4(mp4)
    assert (n, shape, fps) == (6, (48, 64, 3), 7.5)
    # H.264 wants even sides: an odd frame is padded by one row / column
    odd = save_video(_frames(3, 47, 63), tmp_path / "odd.mp4", fps=5)
    assert _read_mp4(odd)[:2] == (3, (48, 64, 3))
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.gif", "a.mp4", "odd.mp4", "sub"]


@pytest.mark.parametrize("ext", ["gif", "mp4"])
def test_save_video_is_atomic(tmp_path, ext):
    def broken():
        yield from _frames(2)
        raise RuntimeError("renderer died")

    with pytest.raises(RuntimeError, match="renderer died"):
        save_video(broken(), tmp_path / f"v.{ext}", fps=10)
    assert os.listdir(tmp_path) == []
    with pytest.raises(ConfigError, match="uint8"):
        save_video(_frames(2).astype(np.float32), tmp_path / f"v.{ext}", fps=10)
    with pytest.raises(ConfigError, match="no frames"):
        save_video(np.zeros((0, 8, 8, 3), np.uint8), tmp_path / f"v.{ext}", fps=10)
    assert os.listdir(tmp_path) == []


def test_save_video_errors(tmp_path, monkeypatch):
    with pytest.raises(ConfigError, match=r"\.mp4, \.gif"):
        save_video(_frames(2), tmp_path / "v.avi", fps=10)
    with pytest.raises(ConfigError, match="fps"):
        save_video(_frames(2), tmp_path / "v.gif", fps=0)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ConfigError, match="is not a folder"):  # writers create no folder
        save_video(_frames(2), blocker / "v.gif", fps=10)
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # not installed
    with pytest.raises(ConfigError, match="pip install imageio-ffmpeg"):
        save_video(_frames(2), tmp_path / "v.mp4", fps=10)


def test_render_motion_plays_in_real_time(tmp_path, no_sigint_fork):
    m = _motion([robot.STANDING_POSTURE, _arm_up()] * 3, fps=30.0)
    path = save_motion(tmp_path / "m.npz", m)
    out = render_motion(path, tmp_path / "m.mp4", backend="matplotlib", size=SIZE, stride=2)
    assert _read_mp4(out) == (3, (SIZE[1], 2 * SIZE[0], 3), 15.0)  # 30 fps / stride 2
    # --fps sets the clock, not the speed: 15 ticks/s over 5/30 s show frames 0, 2, 4
    res = render.render_to_file(m, tmp_path / "m.gif", backend="matplotlib", size=SIZE, fps=15)
    assert (res.frames, res.backend, res.fps, res.human) == (3, "matplotlib", 15.0, True)
    assert iio.imread(res.path, index=None).shape == (3, SIZE[1], 2 * SIZE[0], 3)
    assert _gif_delays(res.path) == [70, 60, 70]  # 1/15 s each, rounded at the boundaries
    assert res.seconds == pytest.approx(0.2)


def _gif_delays(path) -> list[int]:
    """Each frame's delay (ms) as stored in the GIF."""
    from PIL import Image

    with Image.open(path) as im:
        out = []
        for i in range(im.n_frames):
            im.seek(i)
            out.append(int(im.info["duration"]))
    return out


GAP_TIMES = np.array([0.0, 0.1, 0.2, 1.0, 1.1])
"""A 10 fps recording with a 0.8 s gap (the tracker lost the person): 1.1 s long."""


def test_playback_holds_a_gap_on_its_last_frame():
    p = render.playback(GAP_TIMES + 3.0, fps=10.0)  # times may start anywhere
    assert p.frames.tolist() == [0, 1, 2, 3, 4] and p.holds.tolist() == [1, 1, 8, 1, 1]
    assert (p.ticks, p.seconds, p.longest_hold_s) == (12, pytest.approx(1.2), pytest.approx(0.8))
    # a slower clock: the latest frame at or before each tick; frames between ticks are skipped
    p = render.playback(GAP_TIMES, fps=5.0)  # ticks at 0, 0.2, .. 1.0
    assert p.frames.tolist() == [0, 2, 3] and p.holds.tolist() == [1, 4, 1]
    # uniform times at rate / stride: every stride-th frame once
    p = render.playback(np.arange(7) / 30.0, fps=15.0, stride=2)
    assert p.frames.tolist() == [0, 2, 4, 6] and p.holds.tolist() == [1, 1, 1, 1]
    # a file's rounding (times 1e-9 s late) does not drop a frame
    p = render.playback(np.arange(4) / 15.0 + np.array([0, 1e-9, 1e-9, 1e-9]), fps=15.0)
    assert p.frames.tolist() == [0, 1, 2, 3]
    with pytest.raises(ConfigError, match="fps"):
        render.playback(GAP_TIMES, fps=0.0)


def test_gif_delays_round_at_the_boundaries():
    # 7.5 fps: 13.33 cs a frame; rounding each delay (13 cs) would lose 1 cs every 3 frames
    assert render.gif_delays_ms([1, 1, 1], 7.5) == [130, 140, 130]  # 0.4 s, as 3 / 7.5
    assert sum(render.gif_delays_ms([1] * 742, 7.5)) == round(742 / 7.5 * 100) * 10


def test_video_of_a_motion_with_a_gap_lasts_the_recording(tmp_path, no_sigint_fork):
    q = [robot.STANDING_POSTURE, _arm_up()] * 2 + [robot.STANDING_POSTURE]
    m = Motion(np.stack(q), GAP_TIMES, np.ones(5, bool), None, {"method": "ik"})
    assert m.fps == pytest.approx(10.0)  # the median step
    res = render.render_to_file(m, tmp_path / "g.gif", backend="matplotlib", size=SIZE)
    assert (res.frames, res.fps, res.human) == (5, m.fps, False)
    assert _gif_delays(res.path) == [100, 100, 800, 100, 100]  # frame 2 held over the gap
    assert sum(_gif_delays(res.path)) == 1200  # 1.1 s of recording + the last frame's 0.1 s
    assert res.longest_hold_s == pytest.approx(0.8) and "longest gap held 0.80 s" in (
        res.describe()
    )
    mp4 = render.render_to_file(m, tmp_path / "g.mp4", backend="matplotlib", size=SIZE)
    n, _, fps = _read_mp4(mp4.path)
    assert (n, fps) == (12, pytest.approx(10.0))  # 1.2 s at 10 fps: frame 2 shown 8 times


def test_gif_rate_is_capped_for_real_time(tmp_path):
    m = _motion([robot.STANDING_POSTURE, _arm_up()] * 6 + [robot.STANDING_POSTURE],
                positions=False, fps=120.0)  # 13 frames, 0.1 s  # fmt: skip
    res = render.render_to_file(m, tmp_path / "fast.gif", backend="matplotlib", size=SIZE)
    assert res.fps == render.MAX_GIF_FPS  # not 120: browsers play 1 cs delays as 10 cs
    assert res.frames == 6 and res.seconds == pytest.approx(0.12)  # ticks at 0, 0.02, .. 0.1
    assert _gif_delays(res.path) == [20] * 6
    with pytest.raises(ConfigError, match="at most 50 frames/s"):
        render.render_to_file(m, tmp_path / "x.gif", backend="matplotlib", size=SIZE, fps=60)
    assert not (tmp_path / "x.gif").exists()


def test_show_without_and_with_ipython(monkeypatch):
    m = _motion([robot.STANDING_POSTURE, _arm_up()], positions=False)
    # IPython absent: both names unimportable (an earlier test may have imported the real
    # IPython.display, which a bare sys.modules["IPython"] = None would not hide)
    monkeypatch.setitem(sys.modules, "IPython", None)
    monkeypatch.setitem(sys.modules, "IPython.display", None)
    frames = show(m, backend="matplotlib", size=SIZE)
    assert isinstance(frames, np.ndarray) and frames.shape == (2, SIZE[1], SIZE[0], 3)

    class HTML:
        def __init__(self, data):
            self.data = data

    display = types.ModuleType("IPython.display")
    display.HTML = HTML
    monkeypatch.setitem(sys.modules, "IPython", types.ModuleType("IPython"))
    monkeypatch.setitem(sys.modules, "IPython.display", display)
    clip = show(m, backend="matplotlib", size=SIZE)
    prefix = '<img src="data:image/gif;base64,'
    assert isinstance(clip, HTML) and clip.data.startswith(prefix)
    gif = base64.b64decode(clip.data[len(prefix) :].split('"')[0])
    assert gif[:6] == b"GIF89a"


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as e:  # a usage error: argparse exits (one line, status 2)
        code = int(e.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_render(tmp_path, capsys, no_sigint_fork):
    m = _motion([robot.STANDING_POSTURE, _arm_up(), robot.STANDING_POSTURE])
    src = save_motion(tmp_path / "wave.npz", m)
    out = tmp_path / "videos" / "wave.gif"
    out.parent.mkdir()  # the command creates no folder (tests/integration/test_cli.py)
    code, stdout, err = _cli(
        capsys, "render", str(src), "--out", str(out), "--backend", "matplotlib", "--size", "120x90"
    )
    assert code == 0, err
    assert stdout.count("\n") == 1 and "3 frames" in stdout and "backend=matplotlib" in stdout
    assert str(out) in stdout and "human skeleton (left) and NAO (right)" in stdout
    assert "real time: 0.20 s at 15 fps" in stdout
    assert iio.imread(out, index=None).shape == (3, 90, 240, 3)
    # a NAOqi JSON (no human positions) to MP4, every second frame
    js = save_motion(tmp_path / "wave.json", m)
    mp4 = tmp_path / "wave.mp4"
    code, stdout, _ = _cli(
        capsys, "render", str(js), "--out", str(mp4), "--backend", "matplotlib",
        "--size", "64x48", "--stride", "2",
    )  # fmt: skip
    assert code == 0 and "2 motion frames drawn" in stdout
    assert "the NAO only (the motion holds no human positions" in stdout  # what it drew
    assert "human skeleton" not in stdout
    assert _read_mp4(mp4)[:2] == (2, (48, 64, 3))


def _robot_ink_box(img: np.ndarray) -> tuple[int, int, int, int]:
    """(top, bottom, left, right) pixel rows / columns of a robot's lines on a matplotlib panel
    (darker than the faint floor square)."""
    ink = img.astype(int).sum(axis=-1) < 3 * 170
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    assert rows.size and cols.size, "nothing drawn"
    return int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1])


@pytest.mark.parametrize("name", robots.names())
def test_every_robot_stands_whole_in_its_panel(name):
    """The robot panel is framed on the robot's own geometry (panels.robot_box): standing and
    in two random configurations within its limits, every robot (a 0.6 m NAO, a 1.3 m G1) is
    inside the picture, touching no edge, and standing it fills a good part of its height."""
    r = robots.get(name)
    rng = np.random.default_rng(3)
    q = np.stack([r.standing, *rng.uniform(r.lower, r.upper, (2, r.n_joints))]).astype(np.float32)
    w, h = 120, 160
    panel = _StickRobotPanel(r, (w, h), render.Camera(), q)
    try:
        for k, pose in enumerate(q):
            top, bottom, left, right = _robot_ink_box(panel.draw(pose, ""))
            assert 0 < top and bottom < h - 1 and 0 < left and right < w - 1, (k, top, bottom)
            if k == 0:
                assert bottom - top > 0.4 * h  # standing: not a speck in a corner
    finally:
        panel.close()
    # the video's frames: the person beside the robot, the robot's pixels below its caption
    m = Motion(q[:2], np.arange(2) / 15.0, np.ones(2, bool),
               np.stack([_skeleton(), _skeleton(0.3)]), robot=r)  # fmt: skip
    frames = render_frames(m, backend="matplotlib", size=(w, h))
    assert frames.shape == (2, h, 2 * w, 3)
    assert _changed(frames[0, LABEL_ROWS:, w:], frames[1, LABEL_ROWS:, w:]) > 40


def test_cli_renders_a_g1_motion_from_npz_and_csv(tmp_path, capsys, no_sigint_fork):
    """`jaxproj render` takes the robot from the file's joint names (no robot named above
    jaxproj.robots): a G1 NPZ (with the person) and its CSV (the robot alone)."""
    g1 = robots.get("unitree_g1")
    q = np.tile(g1.standing, (2, 1))
    q[1, g1.index("left_shoulder_pitch_joint")] = -2.0
    m = Motion(q, np.arange(2) / 15.0, np.ones(2, bool), np.stack([_skeleton(), _skeleton(0.3)]),
               robot=g1)  # fmt: skip
    for ext, who in ((".npz", "human skeleton (left) and G1 (right)"), (".csv", "the G1 only")):
        src = save_motion(tmp_path / f"g1{ext}", m)
        out = tmp_path / f"g1{ext}.gif"
        code, stdout, err = _cli(capsys, "render", str(src), "--out", str(out), "--backend",
                                 "matplotlib", "--size", "64x64")  # fmt: skip
        assert code == 0, err
        assert who in stdout and "2 motion frames drawn" in stdout


@pytest.mark.parametrize(
    "args, problem",
    [
        (("missing.npz", "--out", "v.gif"), "missing.npz: no such file"),
        (("wave.npz", "--out", "v.avi"), "unsupported video extension '.avi'"),
        (("wave.txt", "--out", "v.gif"), "unsupported motion file extension '.txt'"),
        (("wave.npz", "--out", "v.gif", "--size", "8x8"), "each side 32..4096 pixels"),
    ],
)
def test_cli_render_errors(tmp_path, capsys, monkeypatch, args, problem):
    monkeypatch.chdir(tmp_path)
    save_motion("wave.npz", _motion([robot.STANDING_POSTURE], positions=False))
    code, stdout, err = _cli(capsys, "render", *args, "--backend", "matplotlib")
    assert code == 2 and stdout == ""
    # a usage error (argparse) names the subcommand: "jaxproj render: error: argument ..."
    assert err.startswith(("jaxproj: error: ", "jaxproj render: error: "))
    assert err.count("\n") == 1 and problem in err
    assert sorted(os.listdir(tmp_path)) == ["wave.npz"]


def test_gif_of_identical_frames_is_one_frame_held(tmp_path):
    """A still motion: Pillow would merge the identical frames itself and then fail on the list
    of delays (Pillow 13); they are merged first, their delays summed (10 fps: 4 ticks, 400 ms)."""
    still = np.full((3, 16, 16, 3), 40, np.uint8)
    out = save_video(still, tmp_path / "still.gif", 10.0, holds=[1, 2, 1])
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == 1
    assert iio.immeta(out, index=0)["duration"] == 400
    moving = still.copy()
    moving[1] += 1  # distinct frames stay apart
    out = save_video(moving, tmp_path / "moving.gif", 10.0, holds=[1, 2, 1])
    assert iio.imread(out, index=None).shape[0] == 3


def _light_grey(img: np.ndarray) -> np.ndarray:
    """The floor lines' pixels of a matplotlib panel (light grey, neither ink nor white)."""
    s = img.astype(int)
    return (np.ptp(s, axis=-1) < 12) & (s.min(axis=-1) > 170) & (s.max(axis=-1) < 235)


def test_a_whole_body_motion_is_drawn_on_the_floor_following_its_root(
    tmp_path, capsys, no_sigint_fork
):
    """A motion with a root (``--root world``): the robot stands on the floor in the world and
    the view follows its root, so between two frames whose roots are 0.25 m apart (the same
    joint angles) the robot's pixels stay where they are and the floor's lines move under it;
    the person is drawn in the same world; the MuJoCo panel's model (free joint and a floor
    plane) compiles without OpenGL."""
    import mujoco

    from jaxproj.viz.panels import robot_qpos

    g1 = robots.get("unitree_g1")
    model = g1.load_model("free")
    data = mujoco.MjData(model)
    data.qpos[:] = robot_qpos(g1, model, g1.standing)
    mujoco.mj_kinematics(model, data)
    soles = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s) for _, s in g1.mjcf.figure.feet]
    height = -float(data.site_xpos[soles, 2].min())  # the root's height standing on the floor
    q = np.tile(g1.standing, (3, 1)).astype(np.float32)
    root_pos = np.array([[0.0, 0.0, height], [0.25, 0.0, height], [0.25, 0.0, height]],
                        np.float32)  # fmt: skip
    root_rot = np.tile(np.float32([0, 0, 0, 1]), (3, 1))
    person = np.stack([_skeleton(), _skeleton(), _skeleton(0.3)])
    m = Motion(q, np.arange(3) / 15.0, np.ones(3, bool), person, robot=g1, root_pos=root_pos,
               root_rot=root_rot, contacts=np.ones((3, 2), bool))  # fmt: skip
    w, h = 120, 160
    frames = render_frames(m, backend="matplotlib", size=(w, h))
    assert frames.shape == (3, h, 2 * w, 3)
    robot0, robot1 = frames[0, LABEL_ROWS:, w:], frames[1, LABEL_ROWS:, w:]
    top, bottom, left, right = _robot_ink_box(robot0)
    assert 0 < top and bottom < h - LABEL_ROWS - 1 and 0 < left and right < w - 1
    assert bottom - top > 0.4 * h  # the whole robot, not a speck
    moved = np.subtract(_robot_ink_box(robot1), (top, bottom, left, right))
    assert np.abs(moved).max() <= 2, moved  # the view follows the root (unfollowed: ~20 px)
    floor0, floor1 = _light_grey(robot0), _light_grey(robot1)
    assert floor0.sum() > 50 and (floor0 != floor1).sum() > 20  # the floor moved under it
    person0 = frames[0, LABEL_ROWS:, :w]
    assert _ink(person0) > 100 and _light_grey(person0).sum() > 50  # the person, on a floor
    assert _changed(frames[1, :, :w], frames[2, :, :w]) > 10  # the person's arm, not the floor
    src = save_motion(tmp_path / "wb.npz", m)  # and through `jaxproj render`, from the file
    code, stdout, err = _cli(capsys, "render", str(src), "--out", str(tmp_path / "wb.gif"),
                             "--backend", "matplotlib", "--size", "64x64")  # fmt: skip
    assert code == 0, err
    assert "whole body: the root in the world, over the floor" in stdout
    floor = render.floor_model(g1)
    assert floor.nq == model.nq and floor.ngeom == model.ngeom + 1
    plane = floor.geom("jaxproj_floor")
    assert plane.type[0] == mujoco.mjtGeom.mjGEOM_PLANE and plane.contype[0] == 0
