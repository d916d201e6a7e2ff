"""What the accuracy benchmarks share: the held-out splits and the default model.

Not part of the ``jaxproj`` package; the scripts next to it import it as ``benchmarks.heldout``.
"""

from __future__ import annotations

import sys
import time

from jaxproj.io import datasets
from jaxproj.projection import api as engine


def splits() -> dict[str, list]:
    """People the default model never saw: MSR Action3D subjects 2,4,6,8,10 (arm actions) and
    the UTKinect-Action3D upper-body segments (5 other people, another room)."""
    msr = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    utk = datasets.utkinect_action3d(actions=datasets.UTK_UPPER_BODY_ACTIONS)
    return {"msr_held_out_arm": msr, "utkinect_upper_body": utk}


def default_model(path: str | None = None, save: str | None = None) -> engine.Model:
    """The model at ``path``, or the default one (``BuildConfig()`` on MSR training subjects
    1,3,5,7,9; ~1 min on 2 CPU cores), written to ``save`` when given; its landmarks and the
    time taken go to stderr."""
    t0 = time.perf_counter()
    if path:
        model = engine.load(path)
    else:
        train = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS))
        model = engine.build(train, engine.BuildConfig())
        if save:
            engine.save(model, save)
    print(f"model: {model.landmarks} landmarks ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return model
