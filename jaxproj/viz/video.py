"""Frames -> a video file: ``.mp4`` (H.264 through imageio's ffmpeg plugin, needs the
``imageio-ffmpeg`` package) or ``.gif`` (imageio's Pillow plugin), written atomically
(``save_video``; re-exported by ``jaxproj.viz.render``)."""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from jaxproj._internal.atomic import atomic_write
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

    def write_gif(tmp: Path) -> None:
        tmp.write_bytes(_gif_bytes(frames, fps))

    return atomic_write(out, write_gif)
