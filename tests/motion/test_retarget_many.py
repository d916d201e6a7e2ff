"""``retarget_many``: many motions packed into few compiled calls, each one's answer
``retarget``'s for it alone (up to float rounding), each one's error in its place."""

from __future__ import annotations

import numpy as np
import pytest

from jaxproj.errors import ConfigError, NoValidFrameError
from jaxproj.io import datasets
from jaxproj.motion.feasible import FeasibleConfig
from jaxproj.motion.retarget import retarget, retarget_many

ROUNDING = 2e-6
"""rad: how far a packed motion's angles may be from the same motion's alone (measured on the
default robot's IK: at most 8.5e-7 over twelve MSR Action3D motions, feasibility filter on)."""


def test_packed_motions_answer_as_each_alone_and_fail_in_their_place() -> None:
    seqs = datasets.msr_action3d(subjects=[1])[:4]
    long = np.concatenate([seqs[0].positions, seqs[1].positions])  # another length bucket
    positions = [s.positions for s in seqs] + [long, seqs[0].positions, np.zeros((5, 20))]
    valid = [s.valid for s in seqs] + [None, np.zeros(len(seqs[0].valid), bool), None]
    kw = {"feasible": FeasibleConfig()}
    # two motions a call at most: 64-frame buckets pack by two, the last alone
    got = retarget_many(positions, valid, pack_frames=128, **kw)
    assert len(got) == len(positions)
    assert isinstance(got[5], NoValidFrameError) and isinstance(got[6], ConfigError)
    for i in range(5):
        alone = retarget(positions[i], valid[i], **kw)
        res = got[i]
        assert not isinstance(res, Exception)
        assert res.angles.shape == alone.angles.shape
        assert np.abs(res.angles - alone.angles).max() <= ROUNDING
        assert np.array_equal(res.valid, alone.valid) and np.array_equal(res.times, alone.times)
        assert res.confidence is not None and alone.confidence is not None
        assert np.array_equal(res.confidence, alone.confidence)
    again = retarget_many(positions, valid, pack_frames=128, **kw)  # deterministic
    for a, b in zip(got[:5], again[:5], strict=True):
        assert not isinstance(a, Exception) and not isinstance(b, Exception)
        assert np.array_equal(a.angles, b.angles)


def test_coarse_packing_compiles_one_program_a_bucket_and_answers_the_same(
    count_compiles,
) -> None:
    seqs = datasets.msr_action3d(subjects=[1])[:4]
    long = np.concatenate([seqs[0].positions, seqs[1].positions])
    positions = [s.positions for s in seqs] + [long]
    valid = [s.valid for s in seqs] + [None]
    assert {len(p) for p in positions[:4]} <= set(range(33, 65)) and 64 < len(long) <= 112
    # fine, 192 frames a call: the four 64-frame motions in calls of 3 and 1 (4 rows and 1
    # row), the long one in a 112-frame bucket; coarse: 4 rows both times, a 128-frame bucket
    with count_compiles() as n:
        got = retarget_many(positions, valid, pack_frames=192, packing="coarse")
    assert n["motions"] == 2, n
    for i, res in enumerate(got):
        alone = retarget(positions[i], valid[i])
        assert not isinstance(res, Exception)
        assert np.abs(res.angles - alone.angles).max() <= ROUNDING
        assert np.array_equal(res.valid, alone.valid)
    with pytest.raises(ConfigError, match="packing must be one of"):
        retarget_many(positions, packing="tight")  # type: ignore[arg-type]


def test_per_motion_sequences_must_match_and_the_pack_must_hold_a_frame() -> None:
    x = [np.zeros((3, 20, 3), np.float32)] * 2
    with pytest.raises(ConfigError, match="valid has 1 entries for 2 motions"):
        retarget_many(x, [None])
    with pytest.raises(ConfigError, match="pack_frames must be >= 1"):
        retarget_many(x, pack_frames=0)
