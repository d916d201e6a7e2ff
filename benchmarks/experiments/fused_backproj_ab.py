"""A/B of the back-projection inside the relaxed projection on a CUDA GPU: the fused Pallas kernel
(``jaxproj.projection.ops.backproj_pallas``, ``impl="pallas"``, the default there) against XLA's
three passes (``impl="xla"``), in one run, on the same model and queries; both checked against
the float64 reference; then the public ``jaxproj.project`` on 1 M host poses.

    python -m benchmarks.experiments.fused_backproj_ab MODEL.npz [--ref-queries 1000]

Prints, for relaxed L = M = 10 at batch 65,536: ns per pose of one jitted relaxed projection
with each back-projection (the fused search in both, ``selection_ab.relaxed_rows_batch``); the
back-projection alone on the batch's real candidate rows; how many answers are identical; both
engines' distance from the float64 reference on held-out queries. Needs a CUDA GPU (elsewhere
``impl="pallas"`` runs in Pallas' interpreter: far too slow at this batch).
"""

from __future__ import annotations

import numpy as np

from benchmarks.experiments.selection_ab import (
    BATCH,
    ab_setup,
    per_pose_ns,
    print_public_rate,
    print_reference_errors,
    relaxed_rows_batch,
)
from jaxproj import testing
from jaxproj._internal.jit import jit
from jaxproj.projection import relaxed


def main() -> None:
    args, model, q = ab_setup(__doc__, 1000)
    sp = model.projector

    fused = relaxed_rows_batch("pallas", "pallas")
    r_new, t_new = np.asarray(fused(sp, q)[0]), per_pose_ns(fused, sp, q)
    xla = relaxed_rows_batch("pallas", "xla")  # XLA's back-projection
    r_old, t_old = np.asarray(xla(sp, q)[0]), per_pose_ns(xla, sp, q)
    diff = np.degrees(np.abs(r_new - r_old)).max(axis=1)
    print(
        f"relaxed L=M=10, batch {BATCH}: XLA back-projection {t_old:.1f} ns/pose, fused kernel "
        f"{t_new:.1f} ns/pose ({t_old / t_new:.2f}x); identical answers {np.mean(diff == 0):.5f}, "
        f"within 0.001 deg {np.mean(diff <= 1e-3):.5f}, max diff {diff.max():.2e} deg",
        flush=True,
    )

    # the back-projection alone, on the batch's real candidates
    st = sp.stack
    dims = relaxed.backward_widths(sp)
    x, cand, ridx = jit(lambda p, h: relaxed.relaxed_candidates(p, h, 10, 10))(sp, q)
    kern = jit(lambda s, x, c, r: relaxed.least_deviations_rows(s, dims, x, c, r, "pallas"))
    ref = jit(lambda s, x, c, r: relaxed.least_deviations_rows(s, dims, x, c, r, "xla"))
    t_k, t_x = per_pose_ns(kern, st, x, cand, ridx), per_pose_ns(ref, st, x, cand, ridx)
    b_k, b_x = np.asarray(kern(st, x, cand, ridx)), np.asarray(ref(st, x, cand, ridx))
    rel = np.abs(b_k - b_x) / np.maximum(b_x, 1e-30)
    same = np.mean(np.argmin(b_k, -1) == np.argmin(b_x, -1), axis=0)
    print(
        f"back-projection alone ({len(dims)} chains x {BATCH * 10} candidates x 10 kernels): "
        f"XLA {t_x:.1f} ns/pose, fused {t_k:.1f} ns/pose ({t_x / t_k:.2f}x); deviations' "
        f"relative difference median {np.median(rel):.1e}, max {rel.max():.1e}; same chosen "
        f"candidate per chain {np.array2string(same, precision=5)}",
        flush=True,
    )

    # both engines against the float64 reference
    print_reference_errors(sp, q, {"fused": r_new, "XLA": r_old}, args.ref_queries)

    # where the two differ (float32 near-ties of the deviations): which one float64 agrees with
    moved = np.flatnonzero(diff > 1e-3)[: args.ref_queries]
    if moved.size:
        reference = testing.StackedReference(sp)
        want = np.stack([reference.project(np.asarray(q[i]), "relaxed", 10, 10)[0] for i in moved])
        e_new = np.degrees(np.abs(r_new[moved] - want)).max(axis=1)
        e_old = np.degrees(np.abs(r_old[moved] - want)).max(axis=1)
        print(
            f"the {moved.size} queries whose answers differ by > 0.001 deg: float64 reference "
            f"within 0.001 deg of fused on {int(np.sum(e_new <= 1e-3))}, of XLA on "
            f"{int(np.sum(e_old <= 1e-3))}, of neither on "
            f"{int(np.sum((e_new > 1e-3) & (e_old > 1e-3)))}; max error fused "
            f"{e_new.max():.2e} deg, XLA {e_old.max():.2e} deg",
            flush=True,
        )

    print_public_rate(model)


if __name__ == "__main__":
    main()
