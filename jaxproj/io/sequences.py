"""``MotionSequence``: one recorded sequence of the bundled datasets or of a folder, and its
time axis (``sequence_times``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jaxproj.io.recording import MSR_FPS


@dataclass(frozen=True)
class MotionSequence:
    """One recorded sequence: MSR Action3D, a UTKinect-Action3D segment / recording, or a file.

    Attributes:
      name: ``"aXX_sYY_eZZ"`` (MSR), ``"sXX_eYY_<action>"`` / ``"sXX_eYY"`` (UTKinect segment /
        whole recording) or the file stem (folder).
      action: 1-based action number (MSR: ``ACTION_NAMES[action - 1]``; UTKinect:
        ``UTK_ACTION_NAMES[action - 1]``); 0 when unknown (whole UTKinect recording, folder file).
      subject: 1-based subject number (1..10).
      take: 1-based execution number (MSR 1..3, UTKinect 1..2).
      positions: ``(T, 20, 3)`` float32 metres, Kinect SDK joint order; invalid frames are 0.
      confidence: ``(T, 20)`` float32 per-joint tracking confidence in [0, 1] (SDK order; all 1
        where the source has none).
      valid: ``(T,)`` bool, frame is not all zeros and all finite.
      frame_numbers: ``(T,)`` int64 source frame numbers, strictly increasing (UTKinect, whose
        frame numbers jump over untracked frames); ``None`` where frames are consecutive (MSR).
      times: ``(T,)`` float64 seconds: ``frame_numbers / UTK_FPS`` (UTKinect, approximate), the
        reader's time axis (folder files, see ``jaxproj.io.readers``); ``None`` for MSR Action3D
        (``sequence_times`` then assumes ``recording.MSR_FPS``).
    """

    name: str
    action: int
    subject: int
    take: int
    positions: np.ndarray
    confidence: np.ndarray
    valid: np.ndarray
    frame_numbers: np.ndarray | None = None
    times: np.ndarray | None = None


def sequence_times(seq: MotionSequence) -> np.ndarray:
    """``(T,)`` float64 seconds of each frame of ``seq``, from its first frame.

    ``seq.times`` when the sequence has them (UTKinect; folder files: the reader's time axis),
    otherwise frames ``1 / readers.MSR_FPS`` apart (MSR Action3D has no timing; 15 frames/s is
    an assumption, see ``jaxproj.io.readers``).
    """
    if seq.times is not None:
        t = np.asarray(seq.times, np.float64)
        return t - t[0]
    return np.arange(len(seq.valid), dtype=np.float64) / MSR_FPS
