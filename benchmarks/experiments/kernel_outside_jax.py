"""The projection's Pallas kernels outside JAX (issue 61): each kernel's Triton module captured
from JAX's lowering, then compiled and run by Triton's own launcher in a process without JAX,
where Nsight Compute can profile it (``ncu`` crashes on a JAX process).

    python -m benchmarks.experiments.kernel_outside_jax dump DIR [--kernel knn_full|back_min]
        [--landmarks 10617] [--rows 65536] [--dim 9] [--d-out 9] [--hidden 192] [--m 10]
    python3 benchmarks/experiments/kernel_outside_jax.py run DIR [--kernel ...] [--warps 4,8]
        [--repeats 50]
    ncu --clock-control none -k regex:knn -c 2 --set full \
        python3 benchmarks/experiments/kernel_outside_jax.py run DIR --warps 4

``dump`` (any machine, a CPU one too: the program is lowered for CUDA without a GPU) writes, for
``--kernel`` on random data:

- ``knn_full`` (``ops.knn_pallas.knn_full``, n = 10): ``--landmarks`` landmarks in ``--dim``
  coordinates (one set; the default robot's right arm holds 10,617), ``--rows`` query rows;
- ``back_min`` (``ops.backproj_pallas.back_min``): a bank of ``--landmarks`` backward kernels
  (``--hidden`` units, ``--dim`` -> ``--d-out``; the default model's chains have 192 units),
  ``--rows`` candidates, each judged by ``--m`` kernels;

into ``DIR``: ``KERNEL.ttir`` (the Triton IR that JAX hands to XLA, the custom call's ``ir``,
printed with the Triton dialect registered), ``KERNEL.json`` (grid, warps, stages, operand
shapes in the kernel's argument order) and ``KERNEL_in{i}.npy`` (the operands as the wrapper
made them: padding, transposes). On a GPU it also writes ``KERNEL_ref{i}.npy``, the kernel's
outputs computed by JAX, and times the wrapper under ``jax.jit`` (``jax_median_ms``: the kernel
plus the wrapper's padding, the comparison point).

``run`` (a CUDA GPU with PyTorch and Triton, no JAX needed) compiles the IR with Triton for each
``--warps`` (TTIR has no layout yet, so the warp count is free; JAX compiles with 4), reports
Triton's registers and spills per thread, launches it on the operands, checks it (``knn_full``:
the first 256 rows' squared distances against a NumPy float64 brute force; both: against
``KERNEL_ref*.npy`` where present) and times it (``triton.testing.do_bench``, median ms, ns per
row). Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

N = 10
CHECK_ROWS = 256
KERNELS = ("knn_full", "back_min")


def _function(kernel: str, a: argparse.Namespace) -> tuple[Any, tuple]:
    """The traceable wrapper of ``kernel`` and its random arguments."""
    import numpy as np

    from benchmarks.experiments.pallas_shard_map import random_bank
    from jaxproj.projection.ops import backproj_pallas, knn_pallas

    rng = np.random.default_rng(0)
    if kernel == "knn_full":
        pts = rng.standard_normal((1, a.landmarks, a.dim)).astype(np.float32)
        ok = np.ones((1, a.landmarks), bool)
        x = rng.standard_normal((1, a.rows, a.dim)).astype(np.float32)
        return (lambda p, v, q: knn_pallas.knn_full(p, v, q, N)), (pts, ok, x)
    k, hid, di, do = a.landmarks, a.hidden, a.dim, a.d_out
    bank = random_bank(rng, k, hid, di, do)
    r = rng.standard_normal((a.rows, di)).astype(np.float32)
    h = rng.standard_normal((a.rows, do)).astype(np.float32)
    idx = rng.integers(0, k, (a.rows, a.m)).astype(np.int32)

    def fn(r_: Any, h_: Any, i_: Any) -> Any:
        return backproj_pallas.back_min(bank, r_, h_, i_, d_in=di, d_out=do, hidden=hid)

    return fn, (r, h, idx)


def dump(folder: Path, kernel: str, a: argparse.Namespace) -> dict:
    """Capture ``kernel``'s Triton IR and operands into ``folder`` (module doc)."""
    import jax
    import numpy as np
    from jax._src.lib.mlir import ir
    from jax._src.pallas.triton import lowering as pallas_triton
    from jax.experimental import pallas as pl

    fn, args = _function(kernel, a)
    low = jax.jit(fn).trace(*args).lower(lowering_platforms=("cuda",))
    calls: list = []

    def walk(op: Any) -> None:
        for region in op.regions:
            for block in region.blocks:
                for inner in block.operations:
                    if inner.name == "stablehlo.custom_call":
                        calls.append(inner)
                    walk(inner)

    for op in low.compiler_ir("stablehlo").body.operations:
        walk(op)
    [call] = [c for c in calls if "triton" in str(c.attributes["call_target_name"])]
    cfg = call.attributes["mhlo.backend_config"]
    raw = ir.StringAttr(cfg["ir"]).value_bytes
    # parsed and printed with the dialects registered (Pallas' own context): the ops' custom
    # forms, which another Triton's parser reads (the generic form's properties it does not)
    with pallas_triton._new_ir_context():
        text = str(ir.Module.parse(raw))

    def num(key: str) -> int:
        return int(str(cfg[key]).split(":")[0])

    # the operands as the wrapper makes them: the kernel call replaced by a recorder
    seen: list = []
    spec: list = []  # the kernel and pallas_call's arguments
    real = pl.pallas_call

    def recorder(kern: Any, *, out_shape: Any, **kw: Any) -> Any:
        spec.append((kern, dict(out_shape=out_shape, **kw)))

        def call_(*xs: Any) -> Any:
            seen.extend(np.asarray(x) for x in xs)
            shapes = out_shape if isinstance(out_shape, list | tuple) else [out_shape]
            zeros = [np.zeros(s.shape, s.dtype) for s in shapes]
            return zeros if isinstance(out_shape, list | tuple) else zeros[0]

        return call_

    pl.pallas_call = recorder  # the module both kernels' wrappers call it through
    try:
        fn(*args)
    finally:
        pl.pallas_call = real
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{kernel}.ttir").write_text(text)
    for i, x in enumerate(seen):
        np.save(folder / f"{kernel}_in{i}.npy", x)
    outs = [t.split(">")[0] for t in str(call.results.types).split("tensor<")[1:]]
    meta: dict = {
        "kernel": kernel,
        "grid": [num("grid_x"), num("grid_y"), num("grid_z")],
        "num_warps": num("num_warps"),
        "num_stages": num("num_stages"),
        "inputs": [{"shape": list(x.shape), "dtype": str(x.dtype)} for x in seen],
        "outputs_hlo": outs,
        "rows": a.rows,
        "jax_version": jax.__version__,
        **{k: getattr(a, k) for k in ("landmarks", "dim", "d_out", "hidden", "m")},
    }
    if jax.default_backend() == "gpu":  # the kernel's own outputs, and its time inside JAX
        [(kern, kw)] = spec  # the kernel alone, and with the wrapper's padding
        refs, ms = _kernel_only(real(kern, **kw), [jax.device_put(x) for x in seen])
        for i, r in enumerate(refs):
            np.save(folder / f"{kernel}_ref{i}.npy", r)
        meta["jax_median_ms"] = ms
        meta["jax_wrapper_median_ms"] = _kernel_only(fn, list(args))[1]
    (folder / f"{kernel}.json").write_text(json.dumps(meta, indent=1))
    return meta


def _kernel_only(call: Any, operands: list) -> tuple[list, float]:
    """``call`` (the wrapper's ``pallas_call``) applied to the recorded operands under
    ``jax.jit``: its outputs (NumPy) and time per call, ms (median of 7 rounds of 20 calls)."""
    import jax
    import numpy as np

    call = jax.jit(call)
    outs = jax.block_until_ready(call(*operands))
    times = []
    for _ in range(7):  # calls queued back to back, as the projection makes them
        t0 = time.perf_counter()
        for _ in range(20):
            last = call(*operands)
        jax.block_until_ready(last)
        times.append((time.perf_counter() - t0) / 20)
    leaves = outs if isinstance(outs, list | tuple) else [outs]
    return [np.asarray(x) for x in leaves], 1e3 * float(np.median(times))


def _outputs(meta: dict) -> list[tuple[tuple[int, ...], str]]:
    """``(shape, dtype)`` of each output from the HLO types (``1x8192x16xi32``)."""
    kinds = {"f32": "float32", "i32": "int32"}
    res = []
    for t in meta["outputs_hlo"]:
        *dims, ty = t.split("x")
        res.append((tuple(int(d) for d in dims), kinds[ty]))
    return res


def run(folder: Path, kernel: str, warps: list[int], repeats: int) -> dict:
    """Compile and launch the captured kernel with Triton, once per warp count (module doc)."""
    import numpy as np
    import torch
    import triton
    from triton.backends.compiler import GPUTarget
    from triton.testing import do_bench

    meta = json.loads((folder / f"{kernel}.json").read_text())
    major, minor = torch.cuda.get_device_capability()
    ins = [torch.from_numpy(np.load(folder / f"{kernel}_in{i}.npy")).cuda()
           for i in range(len(meta["inputs"]))]  # fmt: skip
    refs = sorted(folder.glob(f"{kernel}_ref*.npy"))
    dt = {"float32": torch.float32, "int32": torch.int32}
    grid = tuple(meta["grid"])
    variants = []
    for w in warps:
        compiled = triton.compile(
            str(folder / f"{kernel}.ttir"),
            target=GPUTarget("cuda", major * 10 + minor, 32),
            options={"num_warps": w, "num_stages": meta["num_stages"]},
        )
        compiled._init_handles()
        outs = [torch.empty(s, dtype=dt[d], device="cuda") for s, d in _outputs(meta)]

        def launch(c: Any = compiled, o: list = outs) -> None:
            c[grid](*ins, *o)

        launch()
        torch.cuda.synchronize()
        v: dict = {"num_warps": w, "registers": compiled.n_regs, "spills": compiled.n_spills,
                   "shared_bytes": compiled.metadata.shared}  # fmt: skip
        if kernel == "knn_full":  # the n nearest squared distances against float64
            x = ins[0][0, :CHECK_ROWS].double().cpu().numpy()
            pts = ins[2][0].double().cpu().numpy().T  # (kp, d), padding far away
            d2 = ((x[:, None, :] - pts[None]) ** 2).sum(-1)
            want = np.sort(d2, axis=1)[:, :N]
            got = outs[1][0, :CHECK_ROWS, :N].double().cpu().numpy()
            v["max_rel_diff_d2"] = float(np.max(np.abs(got - want) / np.maximum(want, 1e-6)))
        if refs:  # against JAX's own run of the kernel (k-NN: the distances, not the order)
            which = 1 if kernel == "knn_full" else 0
            want = np.load(refs[which]).astype(np.float64)
            got = outs[which].double().cpu().numpy()
            if kernel == "knn_full":  # the n slots in use (the rest hold +inf)
                want, got = want[..., :N], got[..., :N]
            v["max_abs_diff_vs_jax"] = float(np.max(np.abs(got - want)))
        ms = float(do_bench(launch, warmup=5, rep=repeats))
        v.update(median_ms=ms, ns_per_row=ms * 1e6 / meta["rows"])
        variants.append(v)
    keep = ("kernel", "grid", "num_warps", "num_stages", "rows", "landmarks", "dim", "d_out",
            "hidden", "m", "jax_version", "jax_median_ms", "jax_wrapper_median_ms")  # fmt: skip
    return {
        "device": torch.cuda.get_device_name(),
        "triton": triton.__version__,
        **{k: meta[k] for k in keep if k in meta},
        "variants": variants,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("dump", "run"))
    ap.add_argument("folder")
    ap.add_argument("--kernel", default="knn_full", choices=KERNELS)
    ap.add_argument("--landmarks", type=int, default=10617)
    ap.add_argument("--rows", type=int, default=65536)
    ap.add_argument("--dim", type=int, default=9)
    ap.add_argument("--d-out", type=int, default=9)
    ap.add_argument("--hidden", type=int, default=192)
    ap.add_argument("--m", type=int, default=10)
    ap.add_argument("--warps", default="4", help="run: warp counts to compile, comma-separated")
    ap.add_argument("--repeats", type=int, default=50, help="run: do_bench's time budget (ms)")
    a = ap.parse_args(argv)
    folder = Path(a.folder)
    if a.mode == "dump":
        out = dump(folder, a.kernel, a)
    else:
        out = run(folder, a.kernel, [int(w) for w in a.warps.split(",")], a.repeats)
    print(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
