"""How fast could the projection be on this machine at all? The speed targets against the
arithmetic the default engine's algorithm must do, at the rates this machine reaches.

Two numbers per target:

* **work per pose**, counted from the model's shapes (not measured): the hidden units every
  kernel evaluation needs (an affine map and a sigmoid each) and the multiply-adds (the shared
  ``W x`` products, the output layers, the landmark distances). The counts are lower bounds:
  they leave out every selection, gather, comparison, the full objective's gradients and its
  Newton systems.
* **the rates this machine reaches** for the two operations the work is made of, measured here
  and the best of each kept: float32 multiply-adds as XLA's fused elementwise chains reach them
  and as a large float32 matrix product (full precision) reaches them; hidden units
  ``sigmoid(a x + b)`` as XLA's fused chains reach them and, on a CPU, as NumPy's vectorised
  ``exp`` on cache-resident blocks reaches them, times the core count (perfect scaling
  assumed: a generous rate). Every probe is checked first against float64 NumPy.

The floor of a target is ``max(units / unit rate, multiply-adds / multiply-add rate)``: the
time per pose if the machine did nothing else and never waited at these rates. A target below
its floor cannot be met by JAX / XLA (or NumPy) code of this algorithm on this model here; on a
CPU, hand-vectorised native code might exceed the NumPy rate of the hidden units (see
``benchmarks/RESULTS.md`` for that margin).

    python -m benchmarks.experiments.arithmetic_floor [--model MODEL.npz | --landmarks 1644]
        [--device cpu|gpu] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.bench_projection import TRAIN_SUBJECTS, descriptors  # noqa: E402
from jaxproj.projection import api as engine  # noqa: E402
from jaxproj.projection.projector import ChainLayout  # noqa: E402
from jaxproj.timing import time_calls  # noqa: E402

CHAIN = 64
"""Operations per element of a probe (one fused elementwise kernel)."""


@dataclass(frozen=True)
class Work:
    """Per-pose work: hidden units (affine + sigmoid) and other multiply-adds."""

    units: float
    fmas: float


def relaxed_work(lay: ChainLayout, n_l: int, n_m: int) -> Work:
    """The relaxed projection of one pose, every chain: ``L`` forward and ``L * M`` backward
    kernel evaluations, the human search over ``K`` landmarks and ``L`` robot searches."""
    units = fmas = 0.0
    for m_in, n_out, k, h in zip(lay.inputs, lay.outputs, lay.landmarks, lay.hidden, strict=True):
        m, n = len(m_in), len(n_out)
        units += h * (n_l + n_l * n_m)
        fmas += h * m + n_l * n * h  # W h once; forward outputs
        fmas += n_l * h * n + n_l * n_m * m * h  # W r per candidate; backward outputs
        fmas += h * (n_l + n_l * n_m)  # the affine of every unit (beside its sigmoid)
        fmas += k * m + n_l * k * n  # distances: one multiply-add per coordinate
    return Work(units, fmas)


def full_work(lay: ChainLayout, n_l: int, n_m: int, evaluations: int) -> Work:
    """The full objective of one pose, every cluster of every chain: ``evaluations`` objective
    values per cluster (each ``M`` backward kernels at one point), forward passes only."""
    units = fmas = 0.0
    for m_in, n_out, h in zip(lay.inputs, lay.outputs, lay.hidden, strict=True):
        m, n = len(m_in), len(n_out)
        per_eval = n_m * h
        units += n_l * evaluations * per_eval
        fmas += n_l * evaluations * (h * n + n_m * m * h + per_eval)
    return Work(units, fmas)


def measure_rates(device: jax.Device, size: int, repeats: int) -> dict[str, float]:
    """Multiply-adds and hidden units per second (see the module doc), every probe's rate."""
    a, b = np.float32(0.999), np.float32(1e-3)

    def fma(x: jax.Array) -> jax.Array:
        for _ in range(CHAIN):
            x = x * a + b
        return x

    def unit(x: jax.Array) -> jax.Array:
        for _ in range(CHAIN):
            x = jax.nn.sigmoid(x * a + b)
        return x

    x = jax.device_put(np.random.default_rng(0).uniform(-2, 2, size).astype(np.float32), device)
    rates = {}
    for name, fn in (("fma_xla_chain", fma), ("unit_xla_chain", unit)):
        f = jax.jit(fn)
        got = np.asarray(f(x)[:4096], np.float64)
        y = np.asarray(x[:4096], np.float64)
        for _ in range(CHAIN):
            y = y * float(a) + float(b)
            if name.startswith("unit"):
                y = 1.0 / (1.0 + np.exp(-y))
        _check(name, float(np.max(np.abs(got - y))), 1e-4)
        jax.block_until_ready(f(x))  # compiled and warm
        rates[name] = size * CHAIN / time_calls(lambda f=f: f(x), min_repeats=repeats).median_s
    n = 8192 if device.platform != "cpu" else 2048
    rng = np.random.default_rng(1)
    ma, mb = (rng.standard_normal((n, n)).astype(np.float32) for _ in range(2))
    mm = jax.jit(lambda p, q: jnp.matmul(p, q, precision="highest"))
    pa, pb = jax.device_put(ma, device), jax.device_put(mb, device)
    got = np.asarray(mm(pa, pb)[:64], np.float64)
    _check("fma_matmul", float(np.max(np.abs(got - ma[:64].astype(np.float64) @ mb))), 1e-2)
    jax.block_until_ready(mm(pa, pb))  # compiled and warm
    rates["fma_matmul"] = n**3 / time_calls(lambda: mm(pa, pb), min_repeats=repeats).median_s
    if device.platform == "cpu":  # NumPy's SIMD exp on L2-sized blocks, one core, x cores
        blk = np.random.default_rng(2).uniform(-2, 2, 1 << 15).astype(np.float32)
        t = np.empty_like(blk)
        np.testing.assert_allclose(1 / (1 + np.exp(-blk)), 1 / (1 + np.exp(-blk.astype(float))),
                                   rtol=1e-6)  # fmt: skip
        reps = 200
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            for _ in range(reps):
                np.multiply(blk, a, out=t)
                t += b
                np.negative(t, out=t)
                np.exp(t, out=t)
                t += 1.0
                np.reciprocal(t, out=t)
            best = min(best, time.perf_counter() - t0)
        rates["unit_numpy_x_cores"] = len(blk) * reps / best * (os.cpu_count() or 1)
    return rates


def _check(name: str, err: float, tol: float) -> None:
    if not err <= tol:
        raise SystemExit(f"probe {name} is wrong: max error {err:.2e} > {tol:g}")


TARGETS = {
    # name: (objective, L, M, objective evaluations per cluster, seconds per pose)
    "gpu": [
        ("relaxed L = M = 10, >= 20 M poses/s", "relaxed", 10, 10, 0, 1 / 20e6),
        ("relaxed L = M = 50, >= 2 M poses/s", "relaxed", 50, 50, 0, 1 / 2e6),
        ("full, Adam 30 steps (not converged), >= 2 M poses/s", "full", 10, 10, 31, 1 / 2e6),
        ("full, converged (Newton 40: 17 trials a step), >= 2 M/s", "full", 10, 10, 680, 1 / 2e6),
    ],
    "cpu": [
        ("relaxed L = M = 10, <= 10 us per pose", "relaxed", 10, 10, 0, 10e-6),
        ("streaming one pose, median <= 50 us", "relaxed", 10, 10, 0, 50e-6),
        ("full, Adam 30 steps (not converged), <= 100 us", "full", 10, 10, 31, 100e-6),
        ("full, converged (Newton 40: 17 trials a step), <= 100 us", "full", 10, 10, 680, 100e-6),
    ],
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="a saved model (default: build one)")
    ap.add_argument("--landmarks", type=int, default=1644)
    ap.add_argument("--shapes-from", default=None, help="the chain shapes of an earlier --json")
    ap.add_argument("--device", choices=("cpu", "gpu"), default=None)
    ap.add_argument("--size", type=int, default=None, help="probe elements (default per device)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    dev = jax.devices(args.device)[0] if args.device else jax.devices()[0]
    kind = "cpu" if dev.platform == "cpu" else "gpu"
    if args.shapes_from:  # no model needed (e.g. on a machine without the training data)
        chains = json.loads(Path(args.shapes_from).read_text())["chains"]
        lay = ChainLayout(
            names=tuple(c["name"] for c in chains),
            inputs=tuple(tuple(range(c["m"])) for c in chains),
            outputs=tuple(tuple(range(c["n"])) for c in chains),
            landmarks=tuple(c["K"] for c in chains),
            hidden=tuple(c["hidden"] for c in chains),
            k=tuple(c["k"] for c in chains),
        )
    else:
        if args.model:
            model = engine.load(args.model)
        else:
            cfg = engine.BuildConfig(chains="upper", landmarks=args.landmarks)
            model = engine.build(descriptors(TRAIN_SUBJECTS), cfg)
        lay = model.projector.layout
    landmarks = dict(zip(lay.names, lay.landmarks, strict=True))
    size = args.size or (1 << 26 if kind == "gpu" else 1 << 22)
    rates = measure_rates(dev, size, args.repeats)
    fma_rate = max(v for k, v in rates.items() if k.startswith("fma"))
    unit_rate = max(v for k, v in rates.items() if k.startswith("unit"))
    print(f"{dev.device_kind} ({dev.platform}), jax {jax.__version__}; model {landmarks}, "
          f"hidden {lay.hidden}")  # fmt: skip
    print("measured: " + ", ".join(f"{k} {v / 1e9:,.1f} G/s" for k, v in rates.items()))
    rows = []
    for name, objective, n_l, n_m, evals, target_s in TARGETS[kind]:
        if objective == "relaxed":
            w = relaxed_work(lay, n_l, n_m)
        else:
            w = full_work(lay, n_l, n_m, evals)
        floor = max(w.units / unit_rate, w.fmas / fma_rate)
        rows.append(dict(target=name, units=w.units, fmas=w.fmas, floor_s=floor,
                         target_s=target_s, floor_over_target=floor / target_s))  # fmt: skip
        verdict = "below the floor" if floor > target_s else "above the floor"
        print(f"{name}: {w.units / 1e3:,.0f} K units + {w.fmas / 1e6:,.2f} M multiply-adds per "
              f"pose -> floor {floor * 1e6:,.3f} us ({1 / floor / 1e6:,.3f} M poses/s); target "
              f"{target_s * 1e6:,.3f} us: {verdict} (x{floor / target_s:,.2f})")  # fmt: skip
    if args.json:
        out = dict(device=dev.device_kind, platform=dev.platform, jax=jax.__version__,
                   landmarks=landmarks, rates=rates, rows=rows)  # fmt: skip
        out["chains"] = [
            dict(name=name, m=len(i), n=len(o), K=k, hidden=h, k=kk)
            for name, i, o, k, h, kk in zip(
                lay.names, lay.inputs, lay.outputs, lay.landmarks, lay.hidden, lay.k, strict=True
            )
        ]
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
