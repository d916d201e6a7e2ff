"""jaxproj.io: skeleton recordings in, robot motions out, and the bundled datasets.

- ``read`` (``readers.read_skeleton``): any registered format -> ``Recording`` (``(T, 20, 3)``
  positions, a time axis); ``recording`` holds ``Recording`` and the time-axis rules.
- The format registry (``formats``): ``FORMATS`` (one ``Format`` record per format: name,
  description, suffixes, sniff, read), ``format_names()``, ``detect`` (one detection for a file
  and for the files of a folder), ``recording_format``; one module per format under ``formats/``
  (``msr``, ``utkinect``, ``table`` for csv / npz, the ``bvh`` package), sharing ``text``.
- ``datasets``: the bundled MSR Action3D and UTKinect-Action3D data and folders of recordings
  (loading in ``bundled`` and ``folders``, the archive converter in ``bundling``).
- ``motion_files``: robot motion files (NPZ / CSV / a robot's own export).
"""

from jaxproj.io.formats import FORMATS, detect, format_names, get_format, recording_format
from jaxproj.io.formats.base import Format
from jaxproj.io.readers import read_skeleton as read
from jaxproj.io.recording import Recording

__all__ = [
    "FORMATS",
    "Format",
    "Recording",
    "detect",
    "format_names",
    "get_format",
    "read",
    "recording_format",
]
