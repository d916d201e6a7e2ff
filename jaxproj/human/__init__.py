"""jaxproj.human: the human side as data (``skeletons``: the ``Skeleton`` spec, the canonical
bones, the registry) and the descriptor computed from it (``skeleton``, ``descriptors``)."""
