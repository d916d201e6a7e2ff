"""What the accuracy benchmarks share: the held-out splits and the default model.

Not part of the ``jaxproj`` package; the scripts next to it import it as ``benchmarks.heldout``.
"""

from __future__ import annotations

import sys
import time

from jaxproj.io import datasets
from jaxproj.projection import api as engine


def splits(utkinect_people: tuple[int, ...] = datasets.UTK_TRAIN_SUBJECTS) -> dict[str, list]:
    """People a model trained on ``datasets.training_sequences(utkinect_people)`` never saw:
    MSR Action3D subjects 2,4,6,8,10 (arm actions) and the upper-body segments of the
    UTKinect-Action3D people not in ``utkinect_people`` (another room; default 7 and 9). Pass
    the model's ``config.utkinect_people``."""
    msr = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    utk = datasets.utkinect_held_out(utkinect_people)
    return {"msr_held_out_arm": msr, "utkinect_upper_body": utk}


def default_model(path: str | None = None, save: str | None = None) -> engine.Model:
    """The model at ``path``, or the default one (``BuildConfig()`` on the default training
    set, ``datasets.training_sequences``: MSR training subjects 1,3,5,7,9 and UTKinect people
    3, 4, 6; ~2 min on 2 CPU cores), written to ``save`` when given; its landmarks and the
    time taken go to stderr. Until 0.2.0 the default model trained on MSR alone."""
    t0 = time.perf_counter()
    if path:
        model = engine.load(path)
    else:
        cfg = engine.BuildConfig()
        train = datasets.valid_descriptors(datasets.training_sequences(cfg.utkinect_people))
        model = engine.build(train, cfg)
        if save:
            engine.save(model, save)
    print(f"model: {model.landmarks} landmarks ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return model
