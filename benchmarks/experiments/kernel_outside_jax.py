"""The k-NN kernel outside JAX (issue 61): its Triton module captured from JAX's lowering, then
compiled and run by Triton's own launcher in a process without JAX, where Nsight Compute can
profile it (``ncu`` crashes on a JAX process).

    python -m benchmarks.experiments.kernel_outside_jax dump DIR [--landmarks 10617]
        [--rows 65536] [--dim 9]
    python3 benchmarks/experiments/kernel_outside_jax.py run DIR [--repeats 50]
    ncu --clock-control none -k knn_full \
        python3 benchmarks/experiments/kernel_outside_jax.py run DIR

``dump`` (any machine, a CPU one too: the program is lowered for CUDA without a GPU) writes, for
``knn_pallas.knn_full`` on random landmarks (``--landmarks`` in ``--dim`` coordinates, one set;
the default robot's right arm holds 10,617) and ``--rows`` query rows, n = 10:

- ``knn_full.ttir``: the kernel's Triton IR as JAX hands it to XLA (the custom call's ``ir``);
- ``knn_full.json``: its grid, warps, stages and the shapes and dtypes of its operands and
  outputs, in the kernel's argument order;
- ``knn_full_in{i}.npy``: the operands, as the wrapper (padding, transposes) made them.

``run`` (a CUDA GPU with PyTorch and Triton, no JAX needed) compiles the IR with Triton, launches
it on the operands, checks the first 256 rows' ``n`` squared distances against a NumPy float64
brute force, and times it (``triton.testing.do_bench``, median ms; ns per row). Prints one JSON
object.

Not yet run on a GPU (written 2026-11-30 without device time): the IR comes from jaxlib's
Triton (MLIR 23) and the device's Triton may not parse every op of it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

N = 10
CHECK_ROWS = 256


def dump(folder: Path, landmarks: int, rows: int, dim: int) -> dict:
    """Capture ``knn_full``'s kernel and operands into ``folder`` (module doc)."""
    import jax
    import numpy as np
    from jax._src.lib.mlir import ir

    from jaxproj.projection.ops import knn_pallas

    rng = np.random.default_rng(0)
    pts = rng.standard_normal((1, landmarks, dim)).astype(np.float32)
    ok = np.ones((1, landmarks), bool)
    x = rng.standard_normal((1, rows, dim)).astype(np.float32)
    low = (
        jax.jit(lambda p, v, a: knn_pallas.knn_full(p, v, a, N))
        .trace(pts, ok, x)
        .lower(lowering_platforms=("cuda",))
    )
    calls: list = []

    def walk(op) -> None:  # noqa: ANN001
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
    with ir.Context() as ctx:
        ctx.allow_unregistered_dialects = True
        text = str(ir.Module.parse(raw))

    def num(key: str) -> int:
        return int(str(cfg[key]).split(":")[0])

    # the operands as the wrapper makes them: the kernel call replaced by a recorder
    seen: list = []
    real = knn_pallas.pl.pallas_call

    def recorder(kernel, *, out_shape, **kw):  # noqa: ANN001, ANN202
        def call_(*args):  # noqa: ANN002, ANN202
            seen.extend(np.asarray(a) for a in args)
            return [np.zeros(s.shape, s.dtype) for s in out_shape]

        return call_

    knn_pallas.pl.pallas_call = recorder
    try:
        knn_pallas.knn_full(pts, ok, x, N)
    finally:
        knn_pallas.pl.pallas_call = real
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "knn_full.ttir").write_text(text)
    for i, a in enumerate(seen):
        np.save(folder / f"knn_full_in{i}.npy", a)
    outs = [t for t in str(call.results.types).split("tensor<")[1:]]
    meta = {
        "kernel": "knn_full",
        "grid": [num("grid_x"), num("grid_y"), num("grid_z")],
        "num_warps": num("num_warps"),
        "num_stages": num("num_stages"),
        "inputs": [{"shape": list(a.shape), "dtype": str(a.dtype)} for a in seen],
        "outputs_hlo": [o.split(">")[0] for o in outs],
        "landmarks": landmarks,
        "rows": rows,
        "dim": dim,
        "n": N,
        "jax_version": jax.__version__,
    }
    (folder / "knn_full.json").write_text(json.dumps(meta, indent=1))
    return meta


def _outputs(meta: dict) -> list[tuple[tuple[int, ...], str]]:
    """``(shape, dtype)`` of each output from the HLO types (``1x8192x16xi32``)."""
    kinds = {"f32": "float32", "i32": "int32"}
    res = []
    for t in meta["outputs_hlo"]:
        *dims, ty = t.split("x")
        res.append((tuple(int(d) for d in dims), kinds[ty]))
    return res


def run(folder: Path, repeats: int) -> dict:
    """Compile and launch the captured kernel with Triton (module doc)."""
    import numpy as np
    import torch
    import triton
    from triton.backends.compiler import GPUTarget
    from triton.testing import do_bench

    meta = json.loads((folder / "knn_full.json").read_text())
    major, minor = torch.cuda.get_device_capability()
    kernel = triton.compile(
        str(folder / "knn_full.ttir"),
        target=GPUTarget("cuda", major * 10 + minor, 32),
        options={"num_warps": meta["num_warps"], "num_stages": meta["num_stages"]},
    )
    ins = [torch.from_numpy(np.load(folder / f"knn_full_in{i}.npy")).cuda()
           for i in range(len(meta["inputs"]))]  # fmt: skip
    dt = {"float32": torch.float32, "int32": torch.int32}
    outs = [torch.empty(s, dtype=dt[d], device="cuda") for s, d in _outputs(meta)]
    grid = tuple(meta["grid"])

    def launch() -> None:
        kernel[grid](*ins, *outs)

    launch()
    torch.cuda.synchronize()
    # the check: the n nearest squared distances of the first rows against float64
    x = ins[0][0, :CHECK_ROWS].double().cpu().numpy()
    pts = ins[2][0].double().cpu().numpy().T  # (kp, d), padding far away
    d2 = ((x[:, None, :] - pts[None]) ** 2).sum(-1)
    want = np.sort(d2, axis=1)[:, : meta["n"]]
    got = outs[1][0, :CHECK_ROWS, : meta["n"]].double().cpu().numpy()
    rel = float(np.max(np.abs(got - want) / np.maximum(want, 1e-6)))
    ms = float(do_bench(launch, warmup=5, rep=repeats))
    return {
        "device": torch.cuda.get_device_name(),
        "triton": triton.__version__,
        "grid": grid,
        "max_rel_diff_d2": rel,
        "median_ms": ms,
        "ns_per_row": ms * 1e6 / meta["rows"],
        **{k: meta[k] for k in ("landmarks", "rows", "dim", "n", "jax_version")},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("dump", "run"))
    ap.add_argument("folder")
    ap.add_argument("--landmarks", type=int, default=10617)
    ap.add_argument("--rows", type=int, default=65536)
    ap.add_argument("--dim", type=int, default=9)
    ap.add_argument("--repeats", type=int, default=50, help="run: do_bench's time budget (ms)")
    a = ap.parse_args(argv)
    folder = Path(a.folder)
    if a.mode == "dump":
        out = dump(folder, a.landmarks, a.rows, a.dim)
    else:
        out = run(folder, a.repeats)
    print(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
