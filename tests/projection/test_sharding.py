"""Sharded projection over several devices, and the multi-process split / gather.

Both run in fresh processes: the device count of a JAX process is fixed when it starts (four
host devices forced with ``XLA_FLAGS``), and ``jax.distributed`` needs processes of its own.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import jax
import pytest

from jaxproj.errors import ConfigError
from jaxproj.projection import api as engine
from jaxproj.projection import distributed

SCRIPTS = Path(__file__).resolve().parent / "scripts"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["JAX_PLATFORMS"] = "cpu"
    env.pop("XLA_FLAGS", None)
    return env


@pytest.fixture(scope="module")
def sharded() -> dict:
    out = subprocess.run(
        [sys.executable, str(SCRIPTS / "sharding_check.py")],
        capture_output=True, text=True, env=_env(), timeout=600, check=False,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout)


def test_per_device_programs_equal_one_device(sharded: dict) -> None:
    """The default spread: each device runs the one-device program on its quarter."""
    assert len(sharded["devices"]) == 4
    for objective in ("relaxed", "full"):
        rec = sharded[objective]["per_device"]
        assert rec["shape"] == [203, 10]  # the last batch's padding cut off
    assert sharded["relaxed"]["per_device"]["bit_identical"]
    # full (3 fixed Adam steps): a quarter batch vmapped may fuse otherwise (float32 ulps)
    assert sharded["full"]["per_device"]["max_abs_diff"] < 1e-4
    # the projector is copied to each device once, and the copies go with the projector
    assert sharded["copies"] == {"after_calls": 4, "reused": True, "after_del": 0}
    assert sharded["fillers"] == {"after_calls": 1, "after_del": 0}  # made once per projector


def test_sharded_projection_equals_one_device(sharded: dict) -> None:
    assert len(sharded["devices"]) == 4
    for objective in ("relaxed", "full"):
        assert sharded[objective]["shape"] == [203, 10]  # the last batch's padding cut off
    # relaxed: the same picks; the deviations are summed per chain over each device's quarter
    # of the batch, which XLA vectorises otherwise than the whole (last bit, as the two-level
    # batches in test_projection.py)
    assert sharded["relaxed"]["angles_identical"]
    assert sharded["relaxed"]["value_max_rel_diff"] <= 1e-6
    # full (3 fixed Adam steps, sharding_check.py): each device vmaps a quarter of the batch,
    # so XLA fuses differently (float32 ulps)
    assert sharded["full"]["max_abs_diff"] < 1e-4


@pytest.mark.parametrize("objective", ["relaxed", "full"])
def test_each_device_computes_its_quarter_with_no_collective(sharded: dict, objective) -> None:
    rec = sharded[objective]
    assert rec["collectives"] == []  # no all-gather of the queries, nothing communicated
    # no zero-sized array: XLA's GPU partitioner (Shardy, jax 0.11.2) segfaults compiling a
    # shard_map that holds one (``benchmarks/experiments/pallas_shard_map.py``, ``empty_*``)
    assert rec["zero_sized"] == []
    ratio = rec["flops_four"] / rec["flops_one"]
    assert 0.2 <= ratio <= 0.3, ratio  # XLA's per-device count: ~1/4 of one device's


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_two_processes_split_and_gather(tmp_path: Path) -> None:
    port, out = str(_free_port()), tmp_path / "mh.json"
    cmd = [sys.executable, str(SCRIPTS / "multihost_check.py")]
    procs = [
        subprocess.Popen(
            [*cmd, str(i), port, str(out)],
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for i in range(2)
    ]
    errs = [p.communicate(timeout=600)[1] for p in procs]
    assert all(p.returncode == 0 for p in procs), "\n".join(e[-2000:] for e in errs)
    res = json.loads(out.read_text())
    assert res["process_count"] == 2 and res["share"] == [0, 101]
    assert res["shape"] == [201, 10]
    assert res["bit_identical"], res


def test_process_share_covers_the_corpus_once() -> None:
    for n, c in ((0, 3), (7, 3), (201, 2), (5, 8)):
        shares = [distributed.process_share(n, i, c) for i in range(c)]
        assert [s.start for s in shares] == sorted(s.start for s in shares)
        covered = [i for s in shares for i in range(s.start, s.stop)]
        assert covered == list(range(n))
        sizes = [s.stop - s.start for s in shares]
        assert max(sizes) - min(sizes) <= 1
    with pytest.raises(ConfigError):
        distributed.process_share(5, 2, 2)


def test_resolve_devices() -> None:
    assert engine.resolve_devices(None) is None
    assert engine.resolve_devices(1) is None and engine.resolve_devices("1") is None
    assert engine.resolve_devices("all") in (None, jax.devices())
    with pytest.raises(ConfigError, match="JAX device"):
        engine.resolve_devices(len(jax.devices()) + 1)
    with pytest.raises(ConfigError, match="'all'"):
        engine.resolve_devices("many")
    with pytest.raises(ConfigError, match="twice"):
        engine.placement([jax.devices()[0]] * 2, 64)
