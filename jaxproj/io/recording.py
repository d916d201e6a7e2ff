"""``Recording``: one skeleton recording (``(T, 20, 3)`` positions and a time axis), and the
time-axis rules every format follows.

Time axis: every ``Recording`` carries ``times`` ``(T,)`` float64 seconds from the recording's
first frame and ``time_source``, which says where they came from:

- UTKinect: the frame numbers at the dataset's nominal 30 frames/s (``UTK_FPS``), so frames the
  tracker dropped leave gaps (``"frame numbers at 30 fps"``);
- MSR Action3D: the files hold no timing; frames are assumed ``MSR_FPS`` = 15 frames/s apart (the
  rate the dataset's skeleton sequences are usually quoted at; an assumption, ``"assumed 15
  fps"``);
- NPZ: the file's ``times`` or ``fps`` when present (``"file"``), otherwise like CSV;
- CSV: no timing in the format; frames are assumed ``KINECT_FPS`` = 30 frames/s apart (the
  Kinect v1 sensor's rate, ``"assumed 30 fps"``);
- BVH: the file's ``Frame Time`` (``"BVH Frame Time ..."``);
- MediaPipe JSON / CSV: a JSON's ``fps``, a CSV's ``frame`` column at ``KINECT_FPS``, otherwise
  frames ``1 / KINECT_FPS`` apart (``jaxproj.io.formats.mediapipe``);
- ``read_skeleton(..., fps=F)`` (the CLI's ``--fps``) overrides all of these with ``t / F``,
  except for BVH, which states its own rate: there ``fps=F`` resamples the clip to ``F`` frames
  per second (``resample``: linear interpolation of the joint positions).

Bounds on the time axis (beyond them a file is corrupt, and the float32 time steps of smoothing
and of the feasibility filter would overflow): frame rates (``fps=``, an NPZ's ``fps``) within
``FPS_RANGE`` (1e-3 to 1e6 frames/s), an NPZ's ``times`` steps of at least ``MIN_STEP_S``
(1 us), a time axis of at most ``MAX_DURATION_S`` (1e9 s), UTKinect frame numbers integers of
magnitude at most 2**53.

Non-finite values and all-zero frames (skeleton lost) are *not* errors: the frame is kept, marked
``False`` in ``Recording.valid`` and its positions are set to 0 (``make_recording``).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass

import numpy as np

from jaxproj.errors import ConfigError, InputError

MSR_FPS = 15.0
"""Frame rate assumed for MSR Action3D skeleton files (frames/s): the files carry no timing."""
KINECT_FPS = 30.0
"""Frame rate assumed for CSV (and NPZ without timing): the Kinect v1 sensor's rate, frames/s."""
UTK_FPS = 30.0
"""Nominal capture rate of UTKinect-Action3D (frames/s): ``times = frame_numbers / UTK_FPS``."""
FPS_RANGE = (1e-3, 1e6)
"""Frame rates (frames/s) accepted from ``fps=`` (``--fps``) and an NPZ's ``fps``."""
MIN_STEP_S = 1e-6
"""Smallest step (s) between the ``times`` of consecutive frames that an NPZ may give."""
MAX_DURATION_S = 1e9
"""Longest time axis (s, ~32 years) a recording may have: beyond it the frame numbers or times
are corrupt (and would overflow the float32 time steps of smoothing and the feasibility
filter)."""
MAX_RESAMPLED_FRAMES = 1_000_000
"""Most frames ``resample`` makes (``ConfigError`` beyond: a rate far too high for the clip)."""


@dataclass(frozen=True)
class Recording:
    """One skeleton recording.

    Attributes:
      positions: ``(T, 20, 3)`` float32 joint positions in metres, Kinect SDK joint order; rows of
        invalid frames are 0.
      valid: ``(T,)`` bool, ``False`` where the frame was all zeros, had a non-finite value, or was
        marked invalid in the file (npz ``valid``).
      source: the path the recording was read from.
      format: the format it was read as (``"msr"``, ``"utkinect"``, ``"npz"``, ``"csv"`` or
        ``"bvh"``).
      times: ``(T,)`` float64 seconds since the first frame, strictly increasing (see the module
        docstring for where they come from).
      time_source: how ``times`` were obtained, in words (e.g. ``"assumed 15 fps"``).
      nominal_fps: the rate a one-frame recording reports as ``fps`` (``None``: the format's
        assumed rate; a BVH's ``1 / Frame Time``).
      skeleton: the registered skeleton the file recorded (``jaxproj.human.skeletons``;
        ``"kinect_v1"`` for the Kinect v1 formats and BVH). ``positions`` are always Kinect v1's
        20 joints, made from that skeleton's through the canonical bones
        (``skeletons.to_kinect_v1``); the bones it lacks (``Skeleton.bones``) were filled and
        must not be read (``retarget`` refuses a model or robot that reads them).
      skeleton_from: how ``skeleton`` was chosen: ``"format"`` (the format has one skeleton),
        ``"file"`` (named in the file: an NPZ's ``skeleton`` key), ``"option"``
        (``read_skeleton(skeleton=)``, the CLI's ``--skeleton``) or ``"count"`` (guessed from
        an NPZ's / NPY's joint count; ``read_skeleton`` then checks the bones look like a
        person's, ``jaxproj.io.plausible``).
      notes: what the reader assumed or changed that the user should hear of (an assumed frame
        rate, units converted, a skeleton guessed), one sentence each; the CLI prints them.
      invalid_reason: why the reader marked frames of the file invalid, in words, where it knows
        more than "lost tracking or non-finite values" (MediaPipe: whose visibility was below
        the threshold, in how many frames); ``None``: nothing more to say. The CLI's messages
        about invalid frames quote it.
    """

    positions: np.ndarray
    valid: np.ndarray
    source: str
    format: str
    times: np.ndarray
    time_source: str
    nominal_fps: float | None = None
    skeleton: str = "kinect_v1"
    skeleton_from: str = "format"
    notes: tuple[str, ...] = ()
    invalid_reason: str | None = None

    @property
    def fps(self) -> float:
        """Median frame rate, frames/s (``1 / median(diff(times))``; the nominal rate of a
        one-frame recording)."""
        if len(self.times) < 2:
            return float(self._nominal_fps)
        return float(1.0 / np.median(np.diff(self.times)))

    @property
    def _nominal_fps(self) -> float:
        if self.nominal_fps is not None:
            return self.nominal_fps
        return {"msr": MSR_FPS, "utkinect": UTK_FPS}.get(self.format, KINECT_FPS)


def check_fps(fps: float) -> None:
    """``ConfigError`` unless ``fps`` is a frame rate within ``FPS_RANGE``."""
    if not (np.isfinite(fps) and FPS_RANGE[0] <= fps <= FPS_RANGE[1]):
        raise ConfigError(
            f"fps must be a frame rate in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}] frames per "
            f"second, got {fps}"
        )


def make_recording(
    positions: np.ndarray,
    valid: np.ndarray | None,
    source: str,
    format: str,
    skeleton: str = "kinect_v1",
) -> Recording:
    """Cast to float32, mark all-zero / non-finite (/ file-invalid) frames and zero them.

    Args:
      positions: ``(T, 20, 3)`` numbers, SDK joint order.
      valid: ``(T,)`` bool mask from the file, or ``None``.
      source: the file.
      format: the format's name.
      skeleton: the skeleton the file recorded (``Recording.skeleton``).

    Returns:
      ``Recording`` with ``times`` the frame indices (``time_source`` ``"frame index"``); the
      caller replaces them with the format's time axis.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        pos = np.asarray(positions).astype(np.float32)
    ok = np.isfinite(pos).all(axis=(1, 2)) & (pos != 0).any(axis=(1, 2))
    if valid is not None:
        ok &= valid
    pos[~ok] = 0.0
    times = np.arange(len(pos), dtype=np.float64)
    return Recording(pos, ok, source, format, times, "frame index", skeleton=skeleton)


def timed_recording(
    path: str | os.PathLike[str],
    format: str,
    positions: np.ndarray,
    valid: np.ndarray | None,
    times: np.ndarray | None,
    source: str,
    fps: float | None,
    assumed_fps: float,
    skeleton: str = "kinect_v1",
) -> Recording:
    """The ``Recording`` of a format without its own resampling (every one but BVH).

    Args:
      path: the file.
      format: the format's name.
      positions: ``(T, 20, 3)`` numbers, SDK joint order.
      valid: ``(T,)`` bool mask from the file, or ``None``.
      times: ``(T,)`` seconds from the file (or ``None``: frames ``1 / assumed_fps`` apart).
      source: where ``times`` come from, in words.
      fps: the caller's rate (``read_skeleton(fps=)``, checked): replaces ``times``.
      assumed_fps: the format's rate when neither the file nor the caller gives one.
      skeleton: the skeleton the file recorded (``Recording.skeleton``); ``positions`` are
        already laid out as Kinect v1 (``skeletons.to_kinect_v1``).

    Raises:
      InputError: a time axis longer than ``MAX_DURATION_S``.
    """
    if fps is not None:
        times, source = None, f"given {fps:g} fps"
    if times is None:
        rate = fps or assumed_fps
        times = np.arange(len(positions), dtype=np.float64) / rate
    times = np.asarray(times, np.float64)
    if times[-1] - times[0] > MAX_DURATION_S:
        raise InputError(
            path,
            f"the time axis spans {times[-1] - times[0]:g} s (more than {MAX_DURATION_S:g} s): "
            "corrupt frame numbers or times",
        )
    rec = make_recording(positions, valid, str(path), format, skeleton)
    return dataclasses.replace(rec, times=times, time_source=source)


def resample(rec: Recording, fps: float, max_gap: float | None = None) -> Recording:
    """The recording on a uniform grid of ``fps`` frames per second (linear interpolation).

    The grid is ``k / fps`` for every ``k`` with ``k / fps`` within the recording's time span
    (at least one frame). Each new frame interpolates joint positions linearly between the two
    recorded frames around it; it is invalid (zeros) if either of them is, or, with
    ``max_gap``, if they lie more than ``max_gap`` s apart (a gap in the recording is not
    bridged by made-up poses: ``retarget`` fills invalid frames by its own rule). A new frame
    within 1e-6 of a step from a recorded frame is that frame (its validity alone). Positions of a
    rotating bone shorten slightly between frames (by ``1 - cos(a / 2)`` for a turn ``a`` in one
    frame step; a 10 degree step: 0.4 %); the descriptor uses directions only.

    Args:
      rec: any ``Recording`` (``(T, 20, 3)`` positions).
      fps: the new rate, frames/s, within ``FPS_RANGE``.
      max_gap: seconds; ``None``: no limit.

    Returns:
      A ``Recording`` with ``(N, 20, 3)`` positions, ``times = arange(N) / fps`` and
      ``time_source`` extended by ``", resampled to <fps> fps (linear)"``.
    """
    check_fps(fps)
    t = np.asarray(rec.times, np.float64)
    span = float(t[-1] - t[0])
    n = int(np.floor(span * fps * (1.0 + 1e-12) + 1e-9)) + 1
    if n > MAX_RESAMPLED_FRAMES:
        raise ConfigError(
            f"resampling {span:g} s to {fps:g} fps would make {n} frames (more than "
            f"{MAX_RESAMPLED_FRAMES}): choose a lower rate"
        )
    grid = np.arange(n, dtype=np.float64) / fps
    hi = np.clip(np.searchsorted(t - t[0], grid, side="left"), 0, len(t) - 1)
    lo = np.maximum(hi - 1, 0)
    step = t[hi] - t[lo]
    w = np.where(step > 0, (grid - (t[lo] - t[0])) / np.where(step > 0, step, 1.0), 1.0)
    w = np.clip(w, 0.0, 1.0)
    w = np.where(np.abs(w - np.round(w)) < 1e-6, np.round(w), w)  # on a recorded frame
    pos = rec.positions.astype(np.float64)
    out = (1.0 - w)[:, None, None] * pos[lo] + w[:, None, None] * pos[hi]
    exact_lo, exact_hi = w <= 0.0, w >= 1.0
    valid = (rec.valid[lo] | exact_hi) & (rec.valid[hi] | exact_lo)
    if max_gap is not None:
        valid &= exact_lo | exact_hi | (step <= max_gap)
    out = out.astype(np.float32)
    out[~valid] = 0.0
    source = f"{rec.time_source}, resampled to {fps:g} fps (linear)"
    return dataclasses.replace(
        rec, positions=out, valid=valid, times=grid, time_source=source, nominal_fps=float(fps)
    )
