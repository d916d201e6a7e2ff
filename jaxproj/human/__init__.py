"""jaxproj.human: the human side as data (``skeletons``: the ``Skeleton`` spec, the canonical
bones, the registry; ``layouts``: the skeletons of today's capture formats, registered here) and
the descriptor computed from it (``skeleton``, ``descriptors``)."""

from jaxproj.human import layouts as layouts  # registers Kinect v2, Azure Kinect, SMPL, ...
