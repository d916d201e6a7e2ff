"""Frames -> a video file: ``.mp4`` (H.264 through imageio's ffmpeg plugin, needs the
``imageio-ffmpeg`` package) or ``.gif`` (imageio's Pillow plugin), written atomically
(``save_video``), and a motion's real-time schedule on the video's clock (``playback``);
re-exported by ``jaxproj.viz.render``."""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from jaxproj._internal.atomic import atomic_write, check_output
from jaxproj.errors import ConfigError

VIDEO_FORMATS: tuple[str, ...] = (".mp4", ".gif")
"""Extensions ``save_video`` writes."""


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


MAX_GIF_FPS = 50.0
"""The highest rate a GIF plays at in real time: its delays are whole centiseconds, and browsers
play a delay under 2 cs as 10 cs."""


def _check_holds(holds: Sequence[int] | np.ndarray | None) -> np.ndarray | None:
    if holds is None:
        return None
    h = np.asarray(holds)
    if h.ndim != 1 or h.dtype.kind not in "iu" or (h < 1).any():
        raise ConfigError(f"holds must be whole numbers >= 1, one per frame, got {holds!r}")
    return h.astype(np.int64)


def _repeated(frames: Iterable[np.ndarray], holds: np.ndarray | None) -> Iterator[np.ndarray]:
    """Each frame ``holds[i]`` times (the frames as they are without ``holds``)."""
    if holds is None:
        yield from frames
        return
    n = 0
    for frame, hold in zip(frames, holds, strict=False):
        n += 1
        for _ in range(int(hold)):
            yield frame
    if n != len(holds):
        raise ConfigError(f"{n} frames for {len(holds)} holds")


def gif_delays_ms(holds: Sequence[int] | np.ndarray, fps: float) -> list[int]:
    """Each frame's GIF delay (ms, whole centiseconds) for a frame shown ``holds[i]`` ticks of
    ``1 / fps`` s: the ticks' boundaries are rounded to centiseconds, not each delay, so the
    rounding never adds up (a frame ends within 5 ms of its real time)."""
    ends = np.cumsum(np.asarray(holds, np.int64))
    cs = np.round(100.0 * np.concatenate([[0], ends]) / fps).astype(np.int64)
    return [int(10 * d) for d in np.diff(cs)]


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


def check_gif_fps(fps: float) -> None:
    """ConfigError where a GIF cannot play ``fps`` frames/s in real time."""
    if fps > MAX_GIF_FPS:
        raise ConfigError(
            f"a GIF plays at most {MAX_GIF_FPS:g} frames/s in real time (its delays are whole "
            f"centiseconds, and browsers play delays under 2 cs as 10 cs), got fps {fps:g}: "
            "lower fps, raise stride, or write an .mp4"
        )


def _gif_bytes(
    frames: Iterable[np.ndarray], fps: float, holds: Sequence[int] | np.ndarray | None = None
) -> bytes:
    """A looping GIF, each frame ``holds[i]`` ticks of ``1 / fps`` (default 1), as per-frame
    delays (``gif_delays_ms``: no frame is stored twice)."""
    import imageio.v3 as iio

    check_gif_fps(fps)
    stack = np.stack(list(_checked(frames)))
    h = np.ones(len(stack), np.int64) if holds is None else np.asarray(holds, np.int64)
    if len(h) != len(stack):
        raise ConfigError(f"{len(stack)} frames for {len(h)} holds")
    delays = list(gif_delays_ms(h, fps))
    # Pillow merges consecutive identical frames (summing their delays) and then fails on a list
    # of delays when one frame is left (Pillow 13: "list / int"): merge them here first
    keep = [0] + [i for i in range(1, len(stack)) if not np.array_equal(stack[i], stack[i - 1])]
    merged = [sum(delays[a:b]) for a, b in zip(keep, [*keep[1:], len(stack)], strict=True)]
    duration: int | list[int] = merged[0] if len(keep) == 1 else merged
    return iio.imwrite(
        "<bytes>", stack[keep], extension=".gif", plugin="pillow", duration=duration, loop=0
    )


def save_video(
    frames: np.ndarray | Iterable[np.ndarray],
    out: str | os.PathLike[str],
    fps: float,
    holds: Sequence[int] | np.ndarray | None = None,
    *,
    overwrite: bool = True,
) -> Path:
    """Write frames as a video, atomically (a failed write leaves nothing behind).

    Args:
      frames: ``(N, H, W, 3)`` uint8, or an iterable of ``(H, W, 3)`` uint8 frames (streamed to
        MP4, gathered for GIF).
      out: ``.mp4`` (H.264, yuv420p; an odd height or width is padded by one repeated row /
        column; needs ``imageio-ffmpeg``) or ``.gif`` (Pillow, looping; at most ``MAX_GIF_FPS``;
        delays in whole centiseconds, rounded at the ticks' boundaries: ``gif_delays_ms``).
      fps: playback frames per second (> 0): the video's clock.
      holds: how many ticks of ``1 / fps`` each frame is shown (whole numbers >= 1, one per
        frame; default 1 each): an MP4 repeats the frame, a GIF lengthens its delay. A motion's
        real-time schedule (``jaxproj.viz.render.playback``) holds a frame across a gap.
      overwrite: replace an existing ``out`` (default); ``False``: ConfigError, before any
        frame is drawn.

    Returns:
      ``out`` as a ``Path``.

    Raises:
      ConfigError: an unsupported extension, a bad ``fps`` (a ``.gif`` over ``MAX_GIF_FPS``),
        bad ``holds``, bad frames, ``.mp4`` without ``imageio-ffmpeg``, an existing ``out``
        with ``overwrite=False``.
      InputError: the file cannot be written.
    """
    out = Path(out)
    ext = check_video_path(out)
    check_output(out, overwrite=overwrite)
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be a finite number > 0, got {fps}")
    h = _check_holds(holds)
    if ext == ".gif":
        check_gif_fps(fps)  # before any frame is drawn
    if ext == ".mp4":
        _require_ffmpeg()
        return atomic_write(
            out, lambda tmp: _write_mp4(tmp, _repeated(frames, h), fps), overwrite=overwrite
        )

    def write_gif(tmp: Path) -> None:
        tmp.write_bytes(_gif_bytes(frames, fps, h))

    return atomic_write(out, write_gif, overwrite=overwrite)


TICK_TOLERANCE = 0.01
"""``playback``: a frame stamped up to this fraction of a tick after a tick is shown at it."""


class Playback(NamedTuple):
    """A motion's real-time schedule on a video clock (``playback``)."""

    frames: np.ndarray
    """``(N,)`` the motion frames shown, in order (each once)."""
    holds: np.ndarray
    """``(N,)`` how many ticks of ``1 / fps`` each is shown (>= 1)."""
    fps: float
    """The clock, ticks per second."""
    longest_hold_s: float
    """The longest time one frame stays on screen (a gap in the recording, or ``1 / fps``)."""

    @property
    def ticks(self) -> int:
        """Frames of the video (an MP4's frame count)."""
        return int(self.holds.sum())

    @property
    def seconds(self) -> float:
        """How long the video plays: ``ticks / fps``."""
        return self.ticks / self.fps


def playback(times: np.ndarray, fps: float, stride: int = 1) -> Playback:
    """The real-time schedule of frames stamped ``times`` on a clock of ``fps`` ticks/s.

    Tick ``k`` (at ``times[0] + k / fps``, ``k = 0 .. floor(span * fps)``) shows the latest of
    the frames ``0, stride, 2 * stride, ...`` at or before it (within ``TICK_TOLERANCE`` of a
    tick, so that times rounded in a file still fall on their tick):
    the video lasts the recording's span plus one tick, a gap is held on its last frame, and a
    frame no tick falls on is not shown. Uniform times at ``fps = rate / stride`` show every
    ``stride``-th frame once.

    Raises:
      ConfigError: ``fps`` not a finite number > 0, or ``times`` empty.
    """
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be a finite number > 0, got {fps}")
    t_all = np.asarray(times, np.float64)
    if t_all.ndim != 1 or len(t_all) == 0:
        raise ConfigError(f"times must be a non-empty (T,) array, got shape {t_all.shape}")
    index = np.arange(0, len(t_all), int(stride))
    t = t_all[index] - t_all[index[0]]
    n_ticks = int(math.floor(t[-1] * fps + TICK_TOLERANCE)) + 1
    clock = np.arange(n_ticks, dtype=np.float64) / fps
    shown = np.searchsorted(t, clock + TICK_TOLERANCE / fps, side="right") - 1  # t[0] = 0
    starts = np.flatnonzero(np.r_[True, shown[1:] != shown[:-1]])
    holds = np.diff(np.r_[starts, n_ticks])
    return Playback(index[shown[starts]], holds, fps, float(holds.max()) / fps)
