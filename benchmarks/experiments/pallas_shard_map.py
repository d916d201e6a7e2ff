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
- ``knn_stage0`` .. ``knn_stage3``: ``knn_full`` with its kernel cut short (the same call, grid,
  blocks and outputs): 0 writes zeros only (the blocks and the wrapper's padding alone), 1 the
  block minima (the tiled distance pass, its scratch output, the barrier), 2 with the ``n``
  rounds choosing blocks, 3 with the distances recomputed at the chosen blocks' landmarks
  (the gather); the full kernel adds the second ``n`` rounds;
- ``zero`` / ``zero_one``: ``knn_full``'s call (the same grid, blocks, outputs and padding)
  around a kernel that writes zeros; one part of the call changed at a time: ``zero_nowrap``
  (the padded inputs made outside and passed in), ``zero_no4d`` / ``zero_nopf`` (without the 4-D
  landmark block / the whole one), ``zero_nobm`` (without the scratch output), ``zero_c2`` (2
  landmark sets), ``zero_padx`` (only the query rows padded inside, by a scatter covering its
  whole target, as ``knn_full`` padded them before 2026-11-30: the crash), ``zero_padp`` /
  ``zero_jnppad`` (only the landmarks padded inside, by a scatter / ``jnp.pad``),
  ``zero_transpose`` (only transposed inside), ``zero_scale`` (one elementwise op before the
  call), ``zero_padrows`` (the rows padded by a real block more);
- ``back_min`` / ``back_min_slow``: ``ops.backproj_pallas.back_min`` on a random bank (4,096
  kernels, hidden 64, 9 -> 12), with the fast sigmoid (inline PTX) and without;
- no Pallas at all: ``empty_sum`` (``x + jnp.sum(e)``, ``e`` a closed-over ``(0, 128)``
  array), ``empty_arg`` (``e`` passed in, replicated), ``empty_concat``
  (``jnp.concatenate([x, e]) + 1``), ``scatter_plain`` (the old whole-cover row padding before
  a multiply): on 2 H200s (jax 0.11.2) every one crashes, so the cause is a zero-sized array in
  the program under XLA's Shardy pass; run with ``JAX_USE_SHARDY_PARTITIONER=false`` they pass;
- ``rollout_one`` / ``rollout_closed`` / ``rollout_args``: the MJX rollout step
  (``rollout_physics._simulate_jit``, the default robot, 64 motions x 15 frames per device), its
  model closed over or passed in replicated (an MJX model holds zero-sized fields).

Output: per case its exit code (``-11``: SIGSEGV) and its last stderr line; ``device``,
``jax_version``. Each child prints ``compiled`` once the sharded program is compiled (so that a
crash is placed at compiling or at running; before it, ``one device ok`` once the one-device
control has run) and ``ok <max |sharded - one device|>`` when it finishes. ``--timeout`` bounds
each case (s).
"""

from __future__ import annotations

import argparse
import functools
import subprocess
import sys
from typing import Any

from benchmarks.harness import report

SIMPLE = ("add", "barrier", "asm", "scratch", "int_out", "fori_store", "grid2d", "gather",
          "whole_block")  # fmt: skip
STAGES = ("knn_stage0", "knn_stage1", "knn_stage2", "knn_stage3")
ZERO = ("zero", "zero_nowrap", "zero_no4d", "zero_nopf", "zero_nobm", "zero_c2", "zero_padx",
        "zero_padp", "zero_transpose", "zero_jnppad", "zero_scale", "zero_padrows")  # fmt: skip


def _zero(kind: str, c: int):  # noqa: ANN202 - knn_full's call, a kernel writing zeros
    import jax
    import jax.numpy as jnp
    from jax.experimental import pallas as pl
    from jax.experimental.pallas import triton as plgpu

    rows, slots, block, nb = 16, 16, 16, 256
    kp, d = nb * block, 9
    four, pf, bm = kind != "zero_no4d", kind != "zero_nopf", kind != "zero_nobm"

    def kernel(x_ref, *refs):  # noqa: ANN001
        outs = refs[four + pf :]
        outs[0][...] = jnp.zeros((rows, slots), jnp.int32)
        outs[1][...] = x_ref[:, :1] + jnp.zeros((rows, slots), jnp.float32)
        if bm:
            outs[2][...] = jnp.zeros((rows, nb), jnp.float32)

    def call(xp: jax.Array, pt: jax.Array) -> jax.Array:
        r = xp.shape[1]
        ins = [pl.BlockSpec((None, rows, d), lambda ci, b: (ci, b, 0))]
        args = [xp]
        if four:
            ins.append(pl.BlockSpec((None, d, nb, block), lambda ci, b: (ci, 0, 0, 0)))
            args.append(pt.reshape(c, d, nb, block))
        if pf:
            ins.append(pl.BlockSpec((None, d, kp), lambda ci, b: (ci, 0, 0)))
            args.append(pt)
        outs = [pl.BlockSpec((None, rows, slots), lambda ci, b: (ci, b, 0))] * 2
        shapes = [jax.ShapeDtypeStruct((c, r, slots), jnp.int32),
                  jax.ShapeDtypeStruct((c, r, slots), jnp.float32)]  # fmt: skip
        if bm:
            outs.append(pl.BlockSpec((None, rows, nb), lambda ci, b: (ci, b, 0)))
            shapes.append(jax.ShapeDtypeStruct((c, r, nb), jnp.float32))
        got = pl.pallas_call(kernel, grid=(c, r // rows), in_specs=ins, out_specs=outs,
                             out_shape=shapes,
                             compiler_params=plgpu.CompilerParams(num_warps=4))(*args)  # fmt: skip
        return got[1]

    if kind == "zero_nowrap":  # the padded arrays made outside, passed in
        return call, d

    def wrapped(x: jax.Array, pts: jax.Array) -> jax.Array:  # as knn_full pads (or a part)
        if kind in ("zero_padx", "zero_scale", "zero_padrows"):  # pts come padded, transposed
            pt = pts
        elif kind == "zero_transpose":  # pts come padded, (C, kp, d): transposed here
            pt = pts.transpose(0, 2, 1)
        elif kind == "zero_jnppad":
            pt = jnp.pad(pts.transpose(0, 2, 1), ((0, 0), (0, 0), (0, kp - pts.shape[1])),
                         constant_values=1e18)  # fmt: skip
        else:
            pt = (
                jnp.full((c, d, kp), 1e18, jnp.float32)
                .at[:, :, : pts.shape[1]]
                .set(pts.transpose(0, 2, 1))
            )
        if kind == "zero_scale":  # one elementwise op before the call
            return call(x * 2.0, pt)
        if kind in ("zero_padp", "zero_transpose", "zero_jnppad"):
            return call(x, pt)
        if kind == "zero_padrows":  # rows padded to a whole block more (a real padding)
            xp = jnp.zeros((c, x.shape[1] + rows, d), jnp.float32).at[:, :-rows].set(x)
            return call(xp, pt)[:, :-rows]
        xp = jnp.zeros(x.shape[:2] + (d,), jnp.float32).at[:, :, : x.shape[2]].set(x)
        return call(xp, pt)

    return wrapped, d


EMPTY = ("empty_concat", "empty_sum", "empty_arg", "scatter_plain")
ROLLOUT = ("rollout_one", "rollout_closed", "rollout_args")
CASES = ("add_one", *SIMPLE, "knn_one", "knn", "knn_numpy", "knn_args", "knn_pruned", *STAGES,
         *ZERO, "back_min", "back_min_slow", *EMPTY, *ROLLOUT)  # fmt: skip


def _cut_kernel(
    x_ref, p_ref, pf_ref, idx_ref, d_ref, bm_ref, *, stop: int, n: int, d: int, nb: int,
    nt: int, block: int, tb: int, sync: bool,
):  # fmt: skip  # noqa: ANN001 - knn_pallas._kernel up to stage ``stop`` (module doc)
    import jax
    import jax.numpy as jnp

    from jaxproj.projection.ops import knn_pallas as kp

    rows, slots_n = kp.ROWS, kp.SLOTS
    if stop == 0:
        idx_ref[...] = jnp.zeros((rows, slots_n), jnp.int32)
        d_ref[...] = x_ref[:, :1] + jnp.zeros((rows, slots_n), jnp.float32)
        bm_ref[...] = jnp.zeros((rows, nb), jnp.float32)
        return
    xs = [x_ref[:, j] for j in range(d)]

    def minima(s):  # noqa: ANN001, ANN202
        d2 = jnp.zeros((rows, tb, block), jnp.float32)
        for j in range(d):
            diff = xs[j][:, None, None] - p_ref[j, kp.pl.ds(s, tb), :][None]
            d2 = d2 + diff * diff
        return jnp.min(d2, axis=2)

    kp._tiles(bm_ref, tb, nt, nb // tb, minima, kp.EMPTY)
    kp._barrier(sync)
    bm = bm_ref[...]
    if stop == 1:
        idx_ref[...] = jnp.zeros((rows, slots_n), jnp.int32)
        d_ref[...] = bm[:, :slots_n]
        return
    cols = jax.lax.broadcasted_iota(jnp.int32, (rows, nb), 1)
    slots = jax.lax.broadcasted_iota(jnp.int32, (rows, slots_n), 1)
    blk = jnp.zeros((rows, slots_n), jnp.int32)
    for r in range(n):
        m = jnp.min(bm, axis=1)
        pos = jnp.min(jnp.where(bm == m[:, None], cols, nb), axis=1)
        pos = jnp.minimum(pos, nb - 1)
        blk = jnp.where(slots == r, pos[:, None], blk)
        bm = jnp.where(cols == pos[:, None], jnp.inf, bm)
    if stop == 2:
        idx_ref[...] = blk
        d_ref[...] = jnp.zeros((rows, slots_n), jnp.float32)
        return
    member = jax.lax.broadcasted_iota(jnp.int32, (rows, slots_n, block), 2)
    pidx = blk[:, :, None] * block + member
    d2 = kp._gathered_d2(xs, pf_ref, pidx)
    idx_ref[...] = blk
    d_ref[...] = jnp.min(d2, axis=2)


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


def random_bank(rng: Any, k: int, hidden: int, d_in: int, d_out: int) -> Any:
    """An ``ELMBank`` of ``k`` random kernels (``hidden`` units, ``d_in`` -> ``d_out``)."""
    import numpy as np

    from jaxproj.projection.elm import ELMBank

    return ELMBank(
        w=rng.standard_normal((hidden, d_in)).astype(np.float32),
        inv_scale=rng.uniform(0.5, 2, k).astype(np.float32),
        bias=rng.standard_normal((k, hidden)).astype(np.float32),
        out=(0.1 * rng.standard_normal((k, d_out, hidden))).astype(np.float32),
        offset=rng.standard_normal((k, d_out)).astype(np.float32),
        neighbours=np.zeros((k, 1), np.int32),
        n_kernels=k, hidden=hidden, d_in=d_in, d_out=d_out, k=1,
    )  # fmt: skip


def child(case: str, n_dev: int) -> int:
    """Run one case; print ``ok DIFF``."""
    import jax
    import jax.numpy as jnp
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    from jaxproj.projection.ops import backproj_pallas, knn_pallas

    rng = np.random.default_rng(0)
    devs = jax.devices()[:n_dev]
    if case in STAGES:  # knn_full's call with its kernel cut short (``_cut_kernel``)
        knn_pallas._kernel = functools.partial(_cut_kernel, stop=int(case[-1]))
        case = "knn"
    mesh = Mesh(np.array(devs), ("b",))
    base = case.removesuffix("_one")
    if base in SIMPLE:
        x = rng.standard_normal((1024 * n_dev, 128)).astype(np.float32)
        fn, args, specs = _simple(base), (x,), (PartitionSpec("b"),)
    elif base in EMPTY:  # no Pallas: zero-sized arrays and a whole-cover scatter
        x = rng.standard_normal((1024 * n_dev, 128)).astype(np.float32)
        e = np.zeros((0, 128), np.float32)
        args, specs = (x,), (PartitionSpec("b"),)
        if base == "empty_concat":  # a zero-sized constant that simplification drops

            def fn(x_: jax.Array) -> jax.Array:
                return jnp.concatenate([x_, e]) + 1

        elif base == "empty_sum":

            def fn(x_: jax.Array) -> jax.Array:
                return x_ + jnp.sum(e)

        elif base == "empty_arg":  # passed in, replicated

            def fn(x_: jax.Array, e_: jax.Array) -> jax.Array:  # type: ignore[misc]
                return x_ + jnp.sum(e_)

            args, specs = (x, e), (PartitionSpec("b"), PartitionSpec())
        else:  # scatter_plain: knn_full's old row padding, whole cover, before a plain op

            def fn(x_: jax.Array) -> jax.Array:
                return jnp.zeros_like(x_).at[:, : x_.shape[1]].set(x_) * 2
    elif base in ZERO:
        c = 2 if base == "zero_c2" else 1
        fn, d = _zero(base, c)
        x = rng.standard_normal((c, 8192 * n_dev, d)).astype(np.float32)
        pts = rng.standard_normal((c, 4000, d)).astype(np.float32)
        if base in ("zero_nowrap", "zero_padx", "zero_scale", "zero_padrows"):  # (C, d, kp)
            pts = np.full((c, d, 4096), 1e18, np.float32)
        if base == "zero_transpose":  # padded, (C, kp, d)
            pts = np.full((c, 4096, d), 1e18, np.float32)
        args = (x, pts)
        specs = (PartitionSpec(None, "b"), PartitionSpec())
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
    elif base.startswith("rollout"):  # no Pallas: the MJX rollout step (diary 2026-11-22)
        from jaxproj.eval.rollout_model import RolloutConfig, _setup
        from jaxproj.eval.rollout_physics import _simulate_jit
        from jaxproj.robots import get

        robot = get(None)
        setup, sub = _setup(RolloutConfig(), "whole", robot)
        mid = (np.asarray(robot.lower) + np.asarray(robot.upper)) / 2
        q = mid + 0.1 * rng.standard_normal((64 * n_dev, 15, robot.n_joints))
        q = np.clip(q, robot.lower, robot.upper).astype(np.float32)
        lengths = np.full(len(q), 15, np.int32)
        if base == "rollout_args":  # the model an argument, replicated: zero-sized parameters

            def fn(s, q_, n_):  # noqa: ANN001, ANN202
                return _simulate_jit(s, q_, n_, sub)

            args = (setup, q, lengths)
            specs = (PartitionSpec(), PartitionSpec("b"), PartitionSpec("b"))
        else:  # closed over: its zero-sized arrays become constants of the shard_map body

            def fn(q_, n_):  # noqa: ANN001, ANN202
                return _simulate_jit(setup, q_, n_, sub)

            args, specs = (q, lengths), (PartitionSpec("b"), PartitionSpec("b"))
    else:
        k, hid, di, do = 4096, 64, 9, 12
        bank = random_bank(rng, k, hid, di, do)
        rows = 8192 * n_dev
        r = rng.standard_normal((rows, di)).astype(np.float32)
        h = rng.standard_normal((rows, do)).astype(np.float32)
        idx = rng.integers(0, k, (rows, 10)).astype(np.int32)
        backproj_pallas.FAST_SIGMOID = base == "back_min"
        fn = functools.partial(backproj_pallas.back_min, bank, d_in=di, d_out=do, hidden=hid)
        args, specs = (r, h, idx), (PartitionSpec("b"),) * 3
    one = jax.block_until_ready(jax.jit(fn)(*jax.device_put(args, devs[0])))
    print("one device ok", flush=True)
    if case.endswith("_one"):
        print("ok 0.0", flush=True)
        return 0
    knn_like = base.startswith("knn") or base in ZERO
    out_spec = PartitionSpec(None, "b") if knn_like else PartitionSpec("b")
    sharded = jax.jit(
        jax.shard_map(fn, mesh=mesh, in_specs=specs, out_specs=out_spec, check_vma=False)
    )
    placed = [jax.device_put(a, NamedSharding(mesh, s)) for a, s in zip(args, specs, strict=True)]
    compiled = sharded.lower(*placed).compile()
    print("compiled", flush=True)
    got = compiled(*placed)  # an array, or the rollout's RolloutResult: compared leaf by leaf
    pairs = zip(jax.tree.leaves(got), jax.tree.leaves(one), strict=True)
    diff = max(float(np.max(np.abs(np.asarray(g, np.float64) - np.asarray(o, np.float64))))
               for g, o in pairs)  # fmt: skip
    print(f"ok {diff}", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--devices", type=int, default=2)
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--json", default=None)
    ap.add_argument("--timeout", type=float, default=300, help="seconds per case")
    a = ap.parse_args(argv)
    if a.child:
        return child(a.child, a.devices)
    import jax

    out: dict = {"device": f"{len(jax.devices())} x {jax.devices()[0].device_kind}",
                 "jax_version": jax.__version__, "devices": a.devices, "cases": {}}  # fmt: skip
    for case in a.cases.split(","):
        run = subprocess.run(
            [sys.executable, "-m", "benchmarks.experiments.pallas_shard_map", "--child", case,
             "--devices", str(a.devices)], capture_output=True, text=True, timeout=a.timeout,
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
