"""What the sharded Pallas path trips on (issue 61): ``jax.shard_map`` around Pallas (Triton)
kernels on several GPUs, from a one-line kernel up to ``project``'s own, each case in a process
of its own (a segmentation fault ends only its case).

    python -m benchmarks.experiments.pallas_shard_map [--cases a,b,...] [--devices 2]
        [--json OUT]

Cases (each compiled and run once under ``jax.jit(jax.shard_map(...))`` over a 1-D mesh of
``--devices`` GPUs, ``check_vma=False`` as ``api._sharded_batch``; ``*_one`` the same function
jitted on one GPU, the control):

- ``add`` / ``add_one``: ``y = x + 1``, a Pallas kernel of one block per program;
- ``barrier``: the same with ``plgpu.debug_barrier()`` in the kernel (the k-NN kernels' sync);
- ``scratch``: a second output written, synced, read back (the k-NN's block minima);
- ``int_out``: a second, int32 output; ``fori_store``: column slices stored in a ``fori_loop``;
  ``grid2d``: a 2-D grid over ``(C, R, 128)`` in squeezed blocks (the k-NN's layout);
  ``whole_block``: a second input, a table read whole by every program; ``gather``: that table
  read at indices computed in the kernel (the k-NN's second stage);
- ``asm``: the same through ``plgpu.elementwise_inline_asm`` (``ex2.approx``: the back-projection
  kernel's fast sigmoid);
- ``knn`` / ``knn_one``: ``ops.knn_pallas.knn_full`` on random landmarks (1 set of 4,096 in 9-D,
  8,192 rows per device, n = 10), the landmarks closed over as arrays on GPU 0; ``knn_numpy``:
  closed over as host arrays; ``knn_args``: passed in, replicated (as ``project`` passes the
  projector);
- ``knn_pruned``: ``ops.knn_pallas.knn`` with ``prune=True`` (its data-dependent fallback: a
  ``lax.cond`` / ``switch`` around a second ``pallas_call``);
- ``back_min`` / ``back_min_slow``: ``ops.backproj_pallas.back_min`` on a random bank (4,096
  kernels, hidden 64, 9 -> 12), with the fast sigmoid (inline PTX) and without.

Output: per case its exit code (``-11``: SIGSEGV) and its last stderr line; ``device``,
``jax_version``. Each child prints ``ok <max |sharded - one device|>`` when it finishes.
"""

from __future__ import annotations

import argparse
import functools
import subprocess
import sys

from benchmarks.harness import report

SIMPLE = ("add", "barrier", "asm", "scratch", "int_out", "fori_store", "grid2d", "gather",
          "whole_block")  # fmt: skip
CASES = ("add_one", *SIMPLE, "knn_one", "knn", "knn_numpy", "knn_args", "knn_pruned",
         "back_min", "back_min_slow")  # fmt: skip


def _simple(kind: str):  # noqa: ANN202, C901 - a traceable function of one (B, 128) array
    import jax
    import jax.numpy as jnp
    from jax.experimental import pallas as pl
    from jax.experimental.pallas import triton as plgpu

    def kernel(x_ref, o_ref, *more):  # noqa: ANN001
        x = x_ref[...]
        if kind == "barrier":
            plgpu.debug_barrier()
        if kind == "asm":
            [x] = plgpu.elementwise_inline_asm(
                "ex2.approx.ftz.f32 $0, $1;", args=[x], constraints="=f,f", pack=1,
                result_shape_dtypes=[jax.ShapeDtypeStruct(x.shape, x.dtype)],
            )  # fmt: skip
        if kind == "scratch":  # a second output written, then read back (the k-NN's minima)
            more[0][...] = x * 2.0
            plgpu.debug_barrier()
            x = more[0][...]
        if kind == "int_out":
            more[0][...] = x.astype(jnp.int32)
        if kind == "fori_store":  # dynamic column slices stored in a loop (the k-NN's tiles)

            def body(i, carry):  # noqa: ANN001, ANN202
                o_ref[:, pl.ds(i * 32, 32)] = x_ref[:, pl.ds(i * 32, 32)] + 1.0
                return carry

            jax.lax.fori_loop(0, 4, body, 0)
            return
        o_ref[...] = x + 1.0

    def f(x: jax.Array) -> jax.Array:
        spec = pl.BlockSpec((16, 128), lambda b: (b, 0))
        shapes = [jax.ShapeDtypeStruct(x.shape, jnp.float32)]
        if kind == "scratch":
            shapes.append(jax.ShapeDtypeStruct(x.shape, jnp.float32))
        if kind == "int_out":
            shapes.append(jax.ShapeDtypeStruct(x.shape, jnp.int32))
        if kind == "grid2d":  # (C, R, 128) in blocks of (squeezed, 16, 128), as the k-NN's
            c = 2
            xc = x.reshape(c, -1, 128)
            return pl.pallas_call(
                kernel,
                grid=(c, xc.shape[1] // 16),
                in_specs=[pl.BlockSpec((None, 16, 128), lambda ci, b: (ci, b, 0))],
                out_specs=pl.BlockSpec((None, 16, 128), lambda ci, b: (ci, b, 0)),
                out_shape=jax.ShapeDtypeStruct(xc.shape, jnp.float32),
                compiler_params=plgpu.CompilerParams(num_warps=4),
            )(xc).reshape(x.shape)
        if kind in ("gather", "whole_block"):  # a whole (2, 128) table, one block for all

            def two(x_ref, t_ref, o_ref):  # noqa: ANN001
                xv = x_ref[...]
                if kind == "gather":
                    idx = jnp.abs((xv * 7.0).astype(jnp.int32)) % 128
                    o_ref[...] = xv + t_ref[0, idx]
                else:
                    o_ref[...] = xv + t_ref[0, :][None, :]

            table = jnp.arange(256, dtype=jnp.float32).reshape(2, 128)
            return pl.pallas_call(
                two,
                grid=(x.shape[0] // 16,),
                in_specs=[spec, pl.BlockSpec((2, 128), lambda b: (0, 0))],
                out_specs=spec,
                out_shape=shapes[0],
                compiler_params=plgpu.CompilerParams(num_warps=4),
            )(x, table)
        outs = pl.pallas_call(
            kernel,
            grid=(x.shape[0] // 16,),
            in_specs=[spec],
            out_specs=[spec] * len(shapes),
            out_shape=shapes,
            compiler_params=plgpu.CompilerParams(num_warps=4),
        )(x)
        return outs[0]

    return f


def child(case: str, n_dev: int) -> int:
    """Run one case; print ``ok DIFF``."""
    import jax
    import jax.numpy as jnp
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    from jaxproj.projection.elm import ELMBank
    from jaxproj.projection.ops import backproj_pallas, knn_pallas

    rng = np.random.default_rng(0)
    devs = jax.devices()[:n_dev]
    mesh = Mesh(np.array(devs), ("b",))
    base = case.removesuffix("_one")
    if base in SIMPLE:
        x = rng.standard_normal((1024 * n_dev, 128)).astype(np.float32)
        fn, args, specs = _simple(base), (x,), (PartitionSpec("b"),)
    elif base.startswith("knn"):
        pts_np = rng.standard_normal((1, 4096, 9)).astype(np.float32)
        valid_np = np.ones((1, 4096), bool)
        x = rng.standard_normal((1, 8192 * n_dev, 9)).astype(np.float32)
        prune = base == "knn_pruned"
        if base == "knn_args":  # the landmarks an argument, replicated (as the projector is)

            def fn(pts: jax.Array, valid: jax.Array, xs: jax.Array) -> jax.Array:
                return knn_pallas.knn(pts, valid, xs, 10)[0]

            args = (pts_np, valid_np, x)
            specs = (PartitionSpec(), PartitionSpec(), PartitionSpec(None, "b"))
        else:  # closed over: committed to GPU 0 (``knn``) or host constants (``knn_numpy``)
            put = (lambda a: a) if base == "knn_numpy" else jnp.asarray
            pts, valid = put(pts_np), put(valid_np)

            def fn(xs: jax.Array) -> jax.Array:
                return knn_pallas.knn(pts, valid, xs, 10, prune=prune)[0]

            args, specs = (x,), (PartitionSpec(None, "b"),)
    else:
        k, hid, di, do = 4096, 64, 9, 12
        bank = ELMBank(
            w=rng.standard_normal((hid, di)).astype(np.float32),
            inv_scale=rng.uniform(0.5, 2, k).astype(np.float32),
            bias=rng.standard_normal((k, hid)).astype(np.float32),
            out=(0.1 * rng.standard_normal((k, do, hid))).astype(np.float32),
            offset=rng.standard_normal((k, do)).astype(np.float32),
            neighbours=np.zeros((k, 1), np.int32),
            n_kernels=k, hidden=hid, d_in=di, d_out=do, k=1,
        )  # fmt: skip
        rows = 8192 * n_dev
        r = rng.standard_normal((rows, di)).astype(np.float32)
        h = rng.standard_normal((rows, do)).astype(np.float32)
        idx = rng.integers(0, k, (rows, 10)).astype(np.int32)
        backproj_pallas.FAST_SIGMOID = base == "back_min"
        fn = functools.partial(backproj_pallas.back_min, bank, d_in=di, d_out=do, hidden=hid)
        args, specs = (r, h, idx), (PartitionSpec("b"),) * 3
    one = jax.jit(fn)(*(jax.device_put(a, devs[0]) for a in args))
    if case.endswith("_one"):
        jax.block_until_ready(one)
        print("ok 0.0", flush=True)
        return 0
    out_spec = PartitionSpec(None, "b") if base.startswith("knn") else PartitionSpec("b")
    sharded = jax.jit(
        jax.shard_map(fn, mesh=mesh, in_specs=specs, out_specs=out_spec, check_vma=False)
    )
    placed = [jax.device_put(a, NamedSharding(mesh, s)) for a, s in zip(args, specs, strict=True)]
    got = sharded(*placed)
    diff = float(np.max(np.abs(np.asarray(got, np.float64) - np.asarray(one, np.float64))))
    print(f"ok {diff}", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--devices", type=int, default=2)
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    if a.child:
        return child(a.child, a.devices)
    import jax

    out: dict = {"device": f"{len(jax.devices())} x {jax.devices()[0].device_kind}",
                 "jax_version": jax.__version__, "devices": a.devices, "cases": {}}  # fmt: skip
    for case in a.cases.split(","):
        run = subprocess.run(
            [sys.executable, "-m", "benchmarks.experiments.pallas_shard_map", "--child", case,
             "--devices", str(a.devices)], capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        said = (run.stdout.strip().splitlines() or [""])[-1]
        err = [ln for ln in run.stderr.strip().splitlines() if ln.strip()]
        out["cases"][case] = {"rc": run.returncode, "stdout": said,
                              "stderr_tail": err[-3:]}  # fmt: skip
        print(case, run.returncode, said, err[-1:] if run.returncode else "", flush=True)
    report(out, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
