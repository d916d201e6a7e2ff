"""A/B of the robot-landmark search inside the relaxed projection on a CUDA GPU: the fused Pallas
kernel (``jaxproj.projection.ops.knn_pallas``, ``impl="pallas"``, the default there) against the
XLA search (``impl="xla"``, ``search.nearest``), in one run, on the same model and queries; both
checked against the float64 reference; then the public ``jaxproj.project`` on 1 M host poses.

    python -m benchmarks.experiments.fused_knn_ab MODEL.npz [--ref-queries 500]

Prints, for relaxed L = M = 10 at batch 65,536 in one jitted relaxed projection (the fused
back-projection in both, ``selection_ab.relaxed_rows_batch``): ns per pose of both; the search
alone on the batch's real candidate rows (ns per pose, neighbour sets equal, and the kernel's
neighbour distances against float64 distances); both engines' largest
difference from the float64 reference on held-out queries. Needs a CUDA GPU (elsewhere
``impl="pallas"`` runs in Pallas' interpreter: far too slow at this batch).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.experiments.selection_ab import (
    BATCH,
    ab_setup,
    per_pose_ns,
    print_public_rate,
    print_reference_errors,
    relaxed_rows_batch,
)
from jaxproj.projection.projector import candidates
from jaxproj.projection.search import nearest_rows


def main() -> None:
    args, model, q = ab_setup(__doc__, 500)
    sp = model.projector

    fused = relaxed_rows_batch("pallas", "pallas")
    r_new, t_new = np.asarray(fused(sp, q)[0]), per_pose_ns(fused, sp, q)
    xla = relaxed_rows_batch("xla", "pallas")  # the XLA search
    r_old, t_old = np.asarray(xla(sp, q)[0]), per_pose_ns(xla, sp, q)
    diff = np.degrees(np.abs(r_new - r_old)).max(axis=1)
    print(
        f"relaxed L=M=10, batch {BATCH}: XLA search {t_old:.1f} ns/pose, fused kernel "
        f"{t_new:.1f} ns/pose ({t_old / t_new:.2f}x); identical answers {np.mean(diff == 0):.5f}, "
        f"max diff {diff.max():.2e} deg",
        flush=True,
    )

    # the search alone, on the batch's real candidate rows
    st = sp.stack
    lay = sp.layout
    x = jnp.concatenate([q, jnp.zeros((BATCH, 1), q.dtype)], axis=1)[:, lay.input_index()]
    cands = jax.jit(
        lambda s, x: jax.vmap(jax.vmap(candidates, in_axes=(0, 0, None)), in_axes=(None, 0, None))(
            s, x, 10
        )
    )
    with jax.default_matmul_precision("highest"):
        cand = cands(st, x)
    c, n = cand.shape[1], cand.shape[3]
    rows = cand.transpose(1, 0, 2, 3).reshape(c, BATCH * 10, n)
    kern = jax.jit(lambda p, s, r: nearest_rows(p, s, r, 10, impl="pallas"))
    ref = jax.jit(lambda p, s, r: nearest_rows(p, s, r, 10, impl="xla"))
    with jax.default_matmul_precision("highest"):
        t_k = per_pose_ns(kern, st.robot, st.robot_sq, rows)
        t_x = per_pose_ns(ref, st.robot, st.robot_sq, rows)
        i_k = np.asarray(kern(st.robot, st.robot_sq, rows)[0])
        i_x = np.asarray(ref(st.robot, st.robot_sq, rows)[0])
    same = np.all(np.sort(i_k, -1) == np.sort(i_x, -1), axis=-1)
    # exactness of the kernel's sets against float64 distances on a sample of rows
    rows_np, pts = np.asarray(rows, np.float64), np.asarray(st.robot, np.float64)
    valid = np.isfinite(np.asarray(st.robot_sq))
    worst = 0.0
    for ci in range(c):
        sample = rows_np[ci, :: max(1, rows_np.shape[1] // 4096)]
        d = ((sample[:, None, :] - pts[ci][None]) ** 2).sum(-1)
        d[:, ~valid[ci]] = np.inf
        kth = np.sort(d, axis=1)[:, 9]
        got = np.take_along_axis(d, i_k[ci, :: max(1, rows_np.shape[1] // 4096)], axis=1)
        worst = max(worst, float(np.max(got.max(axis=1) - kth)))
    print(
        f"robot search alone ({c} chains x {BATCH * 10} rows): XLA {t_x:.1f} ns/pose, fused "
        f"{t_k:.1f} ns/pose ({t_x / t_k:.2f}x); equal neighbour sets {same.mean():.5f}; fused "
        f"farthest kept neighbour beyond the float64 10th distance by at most {worst:.2e}",
        flush=True,
    )

    # both engines against the float64 reference
    print_reference_errors(sp, q, {"fused": r_new, "XLA": r_old}, args.ref_queries)

    print_public_rate(model)


if __name__ == "__main__":
    main()
