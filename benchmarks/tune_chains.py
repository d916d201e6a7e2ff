"""Per-chain tuning of the projection engine on the TRAINING subjects only (1, 3, 5, 7, 9).

Protocol: leave-one-training-subject-out, 5 folds. In each fold the landmarks (mean shift in the
chain's columns + the chain's IK) and the kernels come from the valid frames of all actions of
four training subjects; the validation frames are the held-out subject's valid frames of the
arm-heavy actions (``datasets.ARM_ACTIONS``). Chains (``ik.CHAINS``: head, left_arm, right_arm)
are independent: each is tuned on its own joints' errors against the IK truth. The test subjects
(2, 4, 6, 8, 10) are never read while choosing; ``--test`` builds the chosen model ONCE on all
five training subjects and scores the test split for the record (together with today's default
model, on the same code).

Per chain and setting, for each fold (degrees, the chain's joints):

* ``med``: median over frames of the chain's mean joint error (the chain's ``M_avg``);
* ``p95``: p95 over frames of the chain's max joint error (the chain's ``M_max``);
* ``p95_no_ey`` (arms): p95 of the max over the chain's joints without its ElbowYaw;
* per-joint p50 / p95.

The fold means of these are what the settings are chosen by. Rule (``choose``): a setting with
a NaN prediction is out; the lowest fold mean of ``med`` wins, where settings within
``max(0.01 deg, 2 %)`` of it count as tied; among tied ones the lowest fold-mean ``p95`` wins,
where settings within ``max(0.05 deg, 2 %)`` of it count as tied again; among those the cheapest
(fewest landmarks, then narrower kernels, then smaller ``L * M``, relaxed before full).

Grid, coordinate-wise (each stage starts from the choices of the ones before; never the
product), per chain:

1. ``bandwidth`` (the mean-shift bandwidth, so the landmark count follows the data: a fold has
   4/5 of the training frames); arms ``--arm-bandwidths`` plus the bandwidth that gives today's
   1644 landmarks on all five subjects, head ``--head-bandwidths`` (a bandwidth whose single
   mean-shift run took > ``--slow-s`` s stops the head grid going smaller); default kernels;
2. at that bandwidth: ``(k, hidden)`` in ``{48, 96, 192} x {max(k, 96), 2k}``, then ``lam`` in
   ``{1e-4, 1e-3, 1e-2}``, then ``input_scale`` in ``{0.25, 0.5, 1.0}``;
   then (``refine``) the bandwidth grid again at the chosen kernel settings;
3. ``(L, M)`` in ``{(5, 5), (10, 10), (20, 20), (10, 20), (20, 10)}`` (relaxed objective);
4. the full objective at the chosen settings and ``(L, M)``: ``FullConfig()``,
   ``FullConfig(objective="min", include_candidate=True)``, ``FullConfig(include_candidate=True)``.

Also reported: landmark counts and single mean-shift run times per (fold, chain, bandwidth), the
count each bandwidth gives on all five training subjects, and, on the validation frames, what
limits ElbowYaw (error by human elbow flexion; the IK truth's own change under 3.7 mm of Kinect
noise per joint coordinate; the hand / forearm error of the frames with the largest ElbowYaw
error).

Caching (``--cache``, default ``/tmp/tune-cache``): landmarks per (fold, chain, bandwidth) as
``.npz`` (with the run time), every evaluation (metrics ``.json`` + predictions ``.npz``) per
(fold, chain, setting, projection); a rerun only computes what is missing. ``--quick`` uses its
own sub-folder (folds 1 and 3, every 4th training and every 5th validation frame, two
bandwidths per chain, a reduced grid).

    python -m benchmarks.tune_chains [--json OUT] [--test] [--cache DIR] [--quick]
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import json
import os
import platform
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import jax
import numpy as np

from jaxproj.eval import metrics
from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import landmarks
from jaxproj.projection.config import FullConfig
from jaxproj.projection.meanshift import find_bandwidth
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import ik, robot

TRAIN_SUBJECTS = (1, 3, 5, 7, 9)
TEST_SUBJECTS = (2, 4, 6, 8, 10)
CHAIN_NAMES = tuple(ch.name for ch in ik.CHAINS)
DEFAULT_ARM_TARGET = 1644  # today's BuildConfig.landmarks
ARM_BANDWIDTHS = (0.06, 0.045, 0.035, 0.025)
HEAD_BANDWIDTHS = (0.04, 0.03, 0.02, 0.015)
K_HIDDEN = ((48, 96), (96, 96), (96, 192), (192, 192), (192, 384))
LAMS = (1e-4, 1e-3, 1e-2)
SCALES = (0.25, 0.5, 1.0)
LMS = ((5, 5), (10, 10), (20, 20), (10, 20), (20, 10))
FULL_CONFIGS = {
    "full_weighted": FullConfig(),
    "full_min_cand": FullConfig(objective="min", include_candidate=True),
    "full_weighted_cand": FullConfig(include_candidate=True),
}
KINECT_NOISE_M = 0.0037  # per joint coordinate (jaxproj.paper.synthetic)
TIE_ABS, TIE_P95_ABS, TIE_REL = 0.01, 0.05, 0.02


@dataclass(frozen=True)
class Setting:
    """One chain's landmark and kernel settings."""

    bandwidth: float
    k: int = 96
    hidden: int = 96
    lam: float = 1e-3
    input_scale: float = 0.5
    seed: int = 0

    def tag(self) -> str:
        return (
            f"bw{self.bandwidth:.5f}_k{self.k}_h{self.hidden}_lam{self.lam:g}"
            f"_s{self.input_scale:g}_seed{self.seed}"
        )


@dataclass(frozen=True)
class Query:
    """How a chain is projected."""

    objective: str = "relaxed"  # "relaxed" or a FULL_CONFIGS name
    n_l: int = 10
    n_m: int = 10

    def tag(self) -> str:
        return f"{self.objective}_L{self.n_l}_M{self.n_m}"


def _load() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


def _chain(name: str) -> ik.Chain:
    return ik.CHAINS[CHAIN_NAMES.index(name)]


def _chain_key(name: str, seed: int) -> jax.Array:
    """The PRNG key ``engine.build`` gives this chain (chain 0: the seed's key)."""
    c = CHAIN_NAMES.index(name)
    base = jax.random.PRNGKey(seed)
    return base if c == 0 else jax.random.fold_in(base, c)


def _elbow_yaw_columns(chain: ik.Chain) -> list[int]:
    return [i for i, j in enumerate(chain.joints) if j.endswith("ElbowYaw")]


def chain_metrics(err: np.ndarray, chain: ik.Chain) -> dict:
    """Metrics of ``(F, n_chain)`` errors in degrees (see the module doc)."""
    out = {
        "med": float(np.median(err.mean(axis=1))),
        "mean": float(np.mean(err.mean(axis=1))),
        "p95": float(np.percentile(err.max(axis=1), 95)),
        "per_joint": {
            j: {
                "p50": float(np.percentile(err[:, i], 50)),
                "p95": float(np.percentile(err[:, i], 95)),
            }
            for i, j in enumerate(chain.joints)
        },
        "frames": int(len(err)),
        "nan_frames": int((~np.isfinite(err).all(axis=1)).sum()),
    }
    ey = _elbow_yaw_columns(chain)
    if ey:
        keep = [i for i in range(err.shape[1]) if i not in ey]
        out["p95_no_ey"] = float(np.percentile(err[:, keep].max(axis=1), 95))
    return out


def _cost(r: dict) -> tuple:
    """Run-time cost of a setting, for the last tie-break: landmarks, kernel width, L * M,
    relaxed before full."""
    st, q = r["setting"], r["query"]
    return (
        float(np.mean(r["K"])),
        st["hidden"] * min(st["k"], float(np.mean(r["K"]))),
        q["n_l"] * q["n_m"],
        q["objective"] != "relaxed",
    )


def choose(rows: list[dict]) -> dict:
    """The rule. Rows with a non-finite fold mean (a NaN prediction) are out. Then: the lowest
    fold-mean ``med``; rows within ``max(TIE_ABS, TIE_REL * best)`` of it are tied on ``med``;
    among those the lowest fold-mean ``p95``, rows within ``max(TIE_P95_ABS, TIE_REL * best
    p95)`` of it tied again; among those the cheapest (``_cost``), then the lowest ``med``."""
    ok = [r for r in rows if np.isfinite(r["med"]) and np.isfinite(r["p95"])]
    best = min(r["med"] for r in ok)
    tied = [r for r in ok if r["med"] <= best + max(TIE_ABS, TIE_REL * best)]
    best95 = min(r["p95"] for r in tied)
    tied = [r for r in tied if r["p95"] <= best95 + max(TIE_P95_ABS, TIE_REL * best95)]
    return min(tied, key=lambda r: (_cost(r), r["med"]))


class Tuner:
    """Folds, caches and evaluations."""

    def __init__(self, cache: Path, quick: bool, seed: int, tune_seeds: int = 1, log=print) -> None:
        self.quick = quick
        self.cache = cache / "quick" if quick else cache
        (self.cache / "landmarks").mkdir(parents=True, exist_ok=True)
        (self.cache / "eval").mkdir(parents=True, exist_ok=True)
        self.folds = (1, 3) if quick else TRAIN_SUBJECTS
        self.seed = seed
        self.tune_seeds = tuple(range(seed, seed + tune_seeds))
        self.log = log
        self._data: dict = {}
        self._proj: tuple | None = None
        self.kernel_s: list[float] = []

    # ------------------------------------------------------------------ data
    def data(self, fold: int | str) -> tuple[np.ndarray, np.ndarray | None]:
        """(training descriptors, validation descriptors or None) of a fold (``"all"``: all five
        training subjects, no validation)."""
        if fold not in self._data:
            if fold == "all":
                subjects = list(TRAIN_SUBJECTS)
                val = None
            else:
                subjects = [s for s in TRAIN_SUBJECTS if s != fold]
                val = datasets.valid_descriptors(
                    datasets.msr_action3d(subjects=[fold], actions=datasets.ARM_ACTIONS)
                )
            train = datasets.valid_descriptors(datasets.msr_action3d(subjects=subjects))
            if self.quick:
                train = train[::4]
                val = None if val is None else val[::5]
            truth = None if val is None else np.asarray(ik.solve_driven(val))
            self._data[fold] = (train, val, truth)
        train, val, _ = self._data[fold]
        return train, val

    def truth(self, fold: int, chain: ik.Chain) -> np.ndarray:
        self.data(fold)
        return self._data[fold][2][:, list(ik.chain_joints(chain))]

    # ------------------------------------------------------------- landmarks
    def landmarks(self, fold: int | str, chain_name: str, bandwidth: float) -> dict:
        """Landmarks of one (fold, chain, bandwidth): cached ``.npz`` with the run time."""
        path = self.cache / "landmarks" / f"{fold}_{chain_name}_{bandwidth:.5f}.npz"
        if not path.exists():
            train, _ = self.data(fold)
            t0 = time.perf_counter()
            lm = landmarks.build_landmarks(train, bandwidth=bandwidth, chain=_chain(chain_name))
            seconds = time.perf_counter() - t0
            tmp = path.with_suffix(".tmp.npz")
            np.savez(
                tmp,
                human=lm.human,
                robot=lm.robot,
                counts=lm.counts,
                seconds=seconds,
                n_frames=lm.n_frames,
                load=_load(),
            )
            tmp.replace(path)
            self.log(
                f"  mean shift fold {fold} {chain_name} h={bandwidth:g}: K={lm.n_landmarks} "
                f"in {seconds:.1f} s (load {_load()})"
            )
        with np.load(path) as z:
            out = {k: z[k] for k in z.files}
        return out

    def bandwidth_for(self, chain_name: str, target: int) -> float:
        """The bandwidth whose mean shift on all five training subjects gives ``target``
        landmarks (cached)."""
        path = self.cache / f"bandwidth_{chain_name}_{target}.json"
        if not path.exists():
            train, _ = self.data("all")
            pts = train[:, list(ik.chain_columns(_chain(chain_name)))]
            t0 = time.perf_counter()
            h, res = find_bandwidth(pts, target)
            path.write_text(
                json.dumps({"bandwidth": h, "K": res.n_modes, "seconds": time.perf_counter() - t0})
            )
        return round(float(json.loads(path.read_text())["bandwidth"]), 5)

    # ------------------------------------------------------------ evaluation
    def projector(self, fold: int, chain_name: str, s: Setting):
        key = (fold, chain_name, s)
        if self._proj is None or self._proj[0] != key:
            shapes = (fold, chain_name, s.bandwidth)
            if (
                self._proj is not None
                and self._proj[0][:2] + (self._proj[0][2].bandwidth,) != shapes
            ):
                # new landmark shapes: drop the executables compiled for the old ones (a long run
                # that kept them all crashed in LLVM with "Cannot allocate memory")
                self._proj = None
                jax.clear_caches()
                gc.collect()
            lm = self.landmarks(fold, chain_name, s.bandwidth)
            joints = list(ik.chain_joints(_chain(chain_name)))
            cc = engine.ChainConfig(None, s.bandwidth, s.k, s.hidden, s.lam, s.input_scale, s.seed)
            t0 = time.perf_counter()
            p = engine.build_from_landmarks(
                lm["human"],
                lm["robot"],
                cc,
                key=_chain_key(chain_name, s.seed),
                lower=robot.LOWER[robot.DRIVEN_INDEX][joints],
                upper=robot.UPPER[robot.DRIVEN_INDEX][joints],
            )
            jax.block_until_ready(p)
            self.kernel_s.append(time.perf_counter() - t0)
            self._proj = (key, p)
        return self._proj[1]

    def _eval_path(self, fold: int, chain_name: str, s: Setting, q: Query, ext: str) -> Path:
        name = f"{fold}_{chain_name}_{s.tag()}_{q.tag()}"
        if len(name) > 150:
            name = hashlib.sha1(name.encode()).hexdigest()
        return self.cache / "eval" / f"{name}{ext}"  # tags hold dots: no with_suffix

    def evaluate(self, fold: int, chain_name: str, s: Setting, q: Query) -> dict:
        """Metrics of one (fold, chain, setting, projection) on the fold's validation frames."""
        js = self._eval_path(fold, chain_name, s, q, ".json")
        if js.exists():
            return json.loads(js.read_text())
        chain = _chain(chain_name)
        _, val = self.data(fold)
        x = np.ascontiguousarray(val[:, list(ik.chain_columns(chain))])
        truth = self.truth(fold, chain)
        p = self.projector(fold, chain_name, s)
        objective = "relaxed" if q.objective == "relaxed" else "full"
        full = FULL_CONFIGS.get(q.objective)
        batch = -(-len(x) // 256) * 256
        t0 = time.perf_counter()
        pred, _ = engine.project(p, x, objective, n_l=q.n_l, n_m=q.n_m, full=full, batch_size=batch)
        wall = time.perf_counter() - t0
        err = np.degrees(np.abs(np.asarray(pred, np.float64) - truth))
        out = chain_metrics(err, chain) | {
            "K": int(p.n_landmarks),
            "wall_s": wall,
            "setting": asdict(s),
            "query": asdict(q),
            "fold": fold,
            "chain": chain_name,
        }
        np.savez(self._eval_path(fold, chain_name, s, q, ".npz"), pred=np.asarray(pred, np.float32))
        js.write_text(json.dumps(out))
        return out

    def predictions(self, fold: int, chain_name: str, s: Setting, q: Query) -> np.ndarray:
        self.evaluate(fold, chain_name, s, q)
        with np.load(self._eval_path(fold, chain_name, s, q, ".npz")) as z:
            return z["pred"]

    def summary(
        self, chain_name: str, s: Setting, q: Query | None = None, seeds: tuple | None = None
    ) -> dict:
        """Fold means (and per-fold values) of one setting; each fold's values are first
        averaged over the kernel seeds (default ``self.tune_seeds``; ``s.seed`` is not used)."""
        q = Query() if q is None else q
        seeds = self.tune_seeds if seeds is None else seeds
        keys = ["med", "mean", "p95", "p95_no_ey"]
        per = []
        for f in self.folds:
            runs = [self.evaluate(f, chain_name, replace(s, seed=sd), q) for sd in seeds]
            r = {k: float(np.mean([x[k] for x in runs])) for k in keys if k in runs[0]}
            r["per_joint"] = {
                j: {p: float(np.mean([x["per_joint"][j][p] for x in runs])) for p in ("p50", "p95")}
                for j in runs[0]["per_joint"]
            }
            r["K"], r["wall_s"] = runs[0]["K"], float(np.sum([x["wall_s"] for x in runs]))
            per.append(r)
        keys = [k for k in keys if k in per[0]]
        out = {k: float(np.mean([r[k] for r in per])) for k in keys}
        out["per_fold"] = {k: [round(r[k], 3) for r in per] for k in keys}
        out["per_joint_p95"] = {
            j: float(np.mean([r["per_joint"][j]["p95"] for r in per])) for j in per[0]["per_joint"]
        }
        out["per_joint_p50"] = {
            j: float(np.mean([r["per_joint"][j]["p50"] for r in per])) for j in per[0]["per_joint"]
        }
        out["K"] = [r["K"] for r in per]
        out["wall_s"] = float(np.sum([r["wall_s"] for r in per]))
        out["setting"] = asdict(replace(s, seed=seeds[0]))
        out["seeds"] = list(seeds)
        out["query"] = asdict(q)
        return out


# ------------------------------------------------------------------------------- stages


def _row_line(label: str, r: dict) -> str:
    extra = f" p95noEY {r['p95_no_ey']:6.2f}" if "p95_no_ey" in r else ""
    k = r.get("K")
    ks = f" K {min(k)}-{max(k)}" if k else ""
    return f"    {label:34s} med {r['med']:.3f}  p95 {r['p95']:6.2f}{extra}{ks}"


def _grid(tuner: Tuner, chain: str, label: str, settings: list, log) -> tuple[list[dict], dict]:
    """Evaluate (label, setting, query) triples, print them and apply the rule."""
    rows = []
    log(f"  [{chain}] {label}")
    for name, s, q in settings:
        r = tuner.summary(chain, s, q) | {"label": name}
        rows.append(r)
        log(_row_line(name, r))
    best = choose(rows)
    log(f"    -> {best['label']}")
    return rows, best


def _scan(tuner: Tuner, chain: str, label: str, values: list, make, field: str, args, log,
          down=None, up=None, allowed=None) -> tuple[list[dict], dict, list]:  # fmt: skip
    """A one-knob grid (``make(value) -> (label, setting, query)``; ``field`` names the value
    in the setting) extended past an edge that wins: ``down(min)`` / ``up(max)``, at most
    ``args.extend`` times each way (``allowed(value)`` may refuse a step)."""
    values = list(values)
    rows, best = _grid(tuner, chain, label, [make(v) for v in values], log)
    for _ in range(args.extend):
        v = best["setting"][field]
        nxt = None
        if v == min(values) and down is not None:
            nxt = down(v)
        elif v == max(values) and up is not None:
            nxt = up(v)
        if nxt is None or nxt in values or (allowed is not None and not allowed(nxt)):
            break
        values.append(nxt)
        name, ss, qq = make(nxt)
        r = tuner.summary(chain, ss, qq) | {"label": name + " (edge extension)"}
        rows.append(r)
        log(_row_line(r["label"], r))
        best = choose(rows)
        log(f"    -> {best['label']}")
    return rows, best, values


def tune_chain(tuner: Tuner, chain: str, args, log) -> dict:
    """Stages 1-4 for one chain."""
    res: dict = {}
    arm = chain != "head"
    if arm:
        default_bw = tuner.bandwidth_for(chain, DEFAULT_ARM_TARGET)
        grid = sorted(set(args.arm_bandwidths) | {default_bw}, reverse=True)
    else:
        default_bw = NAO_H25.chains[0].bandwidth
        grid = sorted(set(args.head_bandwidths) | {default_bw}, reverse=True)
    res["default_bandwidth"] = default_bw

    def fast(bw: float) -> bool:
        """Every fold's single mean-shift run at ``bw`` took <= slow_s (runs it if needed)."""
        return all(tuner.landmarks(f, chain, bw)["seconds"] <= args.slow_s for f in tuner.folds)

    # 1. bandwidth (default kernels); the grid stops going smaller past a slow mean shift
    usable = []
    for bw in grid:
        usable.append(bw)
        if not fast(bw):
            log(f"  [{chain}] h={bw:g}: a mean-shift run took > {args.slow_s:g} s; not smaller")
            break

    def smaller(bw: float) -> float | None:
        return round(bw * 0.75, 5) if fast(bw) else None

    def larger(bw: float) -> float:
        return round(bw / 0.75, 5)

    rows, best, usable = _scan(
        tuner, chain, "1. bandwidth", usable, lambda bw: (f"h={bw:g}", Setting(bw), Query()),
        "bandwidth", args, log, down=smaller, up=larger,
    )  # fmt: skip
    res["bandwidth"] = {"grid": rows, "chosen": best["setting"]["bandwidth"]}
    s = Setting(res["bandwidth"]["chosen"])

    # 2. kernels, coordinate-wise
    kh = [(k, h) for k, h in K_HIDDEN if not args.quick or k <= 96]
    rows, best = _grid(
        tuner,
        chain,
        "2a. k, hidden",
        [(f"k={k} hidden={h}", replace(s, k=k, hidden=h), Query()) for k, h in kh],
        log,
    )
    res["k_hidden"] = {"grid": rows}
    s = replace(s, k=best["setting"]["k"], hidden=best["setting"]["hidden"])
    rows, best, _ = _scan(
        tuner, chain, "2b. lam", LAMS, lambda v: (f"lam={v:g}", replace(s, lam=v), Query()),
        "lam", args, log, down=lambda v: v / 10, up=lambda v: v * 10,
    )  # fmt: skip
    res["lam"] = {"grid": rows}
    s = replace(s, lam=best["setting"]["lam"])
    rows, best, _ = _scan(
        tuner, chain, "2c. input_scale", SCALES,
        lambda v: (f"input_scale={v:g}", replace(s, input_scale=v), Query()),
        "input_scale", args, log, down=lambda v: v / 2, up=lambda v: v * 2,
    )  # fmt: skip
    res["input_scale"] = {"grid": rows}
    s = replace(s, input_scale=best["setting"]["input_scale"])

    # 2d. the bandwidth again at the chosen kernels (and one more step past a winning edge)
    rows, best, _ = _scan(
        tuner, chain, "2d. bandwidth at the chosen kernels", usable,
        lambda bw: (f"h={bw:g}", replace(s, bandwidth=bw), Query()),
        "bandwidth", args, log, down=smaller, up=larger,
    )  # fmt: skip
    res["refine"] = {"grid": rows}
    s = replace(s, bandwidth=best["setting"]["bandwidth"])
    res["setting"] = asdict(s)

    # 3. L, M (relaxed)
    rows, best = _grid(
        tuner, chain, "3. L, M", [(f"L={a} M={b}", s, Query("relaxed", a, b)) for a, b in LMS], log
    )
    res["lm"] = {"grid": rows}
    q = Query("relaxed", best["query"]["n_l"], best["query"]["n_m"])
    res["query"] = asdict(q)
    res["chosen"] = best

    # 4. the full objective at the chosen settings
    if not args.no_full:
        names = list(FULL_CONFIGS) if not args.quick else ["full_weighted"]
        cand = [("relaxed", s, q)] + [(n, s, replace(q, objective=n)) for n in names]
        rows = []
        log(f"  [{chain}] 4. full objective at L={q.n_l} M={q.n_m}")
        for name, ss, qq in cand:
            r = tuner.summary(chain, ss, qq) | {"label": name}
            rows.append(r)
            log(_row_line(name, r) + f"  ({r['wall_s']:.1f} s)")
        res["full"] = {"grid": rows}

    # the baseline: today's defaults (bandwidth of 1644 landmarks / the head's own, k=hidden=96)
    res["baseline"] = tuner.summary(chain, Setting(default_bw), Query())
    # seed spread of the chosen and the baseline (what a difference has to beat)
    if args.seeds > 1:
        spread = {}
        for label, ss, qq in (("chosen", s, q), ("baseline", Setting(default_bw), Query())):
            vals = [
                tuner.summary(chain, ss, qq, seeds=(tuner.seed + i,)) for i in range(args.seeds)
            ]
            spread[label] = {
                "med": [round(v["med"], 4) for v in vals],
                "p95": [round(v["p95"], 3) for v in vals],
            }
        res["seeds"] = spread
        log(f"  [{chain}] one seed at a time, seeds 0..{args.seeds - 1}: {spread}")
    return res


def bandwidth_table(tuner: Tuner, chain: str, bandwidths: list[float]) -> list[dict]:
    """Per bandwidth: counts and single-run times on each fold and on all five subjects."""
    out = []
    for bw in bandwidths:
        row = {"bandwidth": bw, "folds": {}}
        for f in tuner.folds:
            lm = tuner.landmarks(f, chain, bw)
            row["folds"][str(f)] = {
                "K": int(len(lm["human"])),
                "seconds": round(float(lm["seconds"]), 2),
                "frames": int(lm["n_frames"]),
            }
        all_lm = tuner.landmarks("all", chain, bw)
        row["all"] = {
            "K": int(len(all_lm["human"])),
            "seconds": round(float(all_lm["seconds"]), 2),
            "frames": int(all_lm["n_frames"]),
        }
        out.append(row)
    return out


# ------------------------------------------------------------------------ ElbowYaw limit


def elbow_yaw_limit(tuner: Tuner, settings: dict, queries: dict, log) -> dict:
    """What limits ElbowYaw, on the validation frames of the training folds (no test data).

    * error of the chosen projection per human elbow flexion bin (p50 / p95 ElbowYaw error,
      and p95 of the arm's other joints);
    * the IK truth's own change when every joint coordinate gets 3.7 mm of Gaussian noise
      (one draw per frame, seed 0) per flexion bin: how steep the truth is where the arm is
      near straight;
    * the hand (wrist point) and forearm direction error (MJCF forward kinematics) of the
      frames whose ElbowYaw error is over 20 deg.
    """
    bins = (0, 10, 20, 30, 45, 60, 90, 180)
    rng = np.random.default_rng(0)
    out: dict = {"bins_deg": list(bins)}
    for chain_name in ("left_arm", "right_arm"):
        chain = _chain(chain_name)
        s, q = Setting(**settings[chain_name]), Query(**queries[chain_name])
        ey = _elbow_yaw_columns(chain)[0]
        others = [i for i in range(4) if i != ey]
        side = "left" if chain_name == "left_arm" else "right"
        flex_all, err_all, noise_all, pred_all, truth_all = [], [], [], [], []
        for f in tuner.folds:
            _, val = tuner.data(f)
            cols = list(ik.chain_columns(chain))
            u, fa = val[:, cols[:3]], val[:, cols[3:]]
            flex = np.degrees(
                np.arctan2(np.linalg.norm(np.cross(u, fa), axis=1), np.sum(u * fa, axis=1))
            )
            pred = tuner.predictions(f, chain_name, s, q)
            truth = tuner.truth(f, chain)
            flex_all.append(flex)
            err_all.append(np.degrees(np.abs(pred.astype(np.float64) - truth)))
            pred_all.append(pred)
            truth_all.append(truth)
            # IK truth under Kinect noise: the same frames, positions perturbed
            seqs = datasets.msr_action3d(subjects=[f], actions=datasets.ARM_ACTIONS)
            pos = np.concatenate([s_.positions for s_ in seqs]).astype(np.float32)
            ok0 = np.concatenate([s_.valid for s_ in seqs])
            d0, v0 = descriptor(pos)
            keep = ok0 & np.asarray(v0)
            if tuner.quick:
                keep_idx = np.flatnonzero(keep)[::5]
                keep = np.zeros_like(keep)
                keep[keep_idx] = True
            noisy = pos + rng.normal(0.0, KINECT_NOISE_M, pos.shape).astype(np.float32)
            d1, v1 = descriptor(noisy)
            ik0 = np.asarray(ik.solve_driven(np.asarray(d0)[keep]))
            ik1 = np.asarray(ik.solve_driven(np.asarray(d1)[keep]))
            dn = np.degrees(np.abs(ik1 - ik0))[:, list(ik.chain_joints(chain))]
            dn[~np.asarray(v1)[keep]] = np.nan
            noise_all.append(dn)
        flex = np.concatenate(flex_all)
        err = np.concatenate(err_all)
        noise = np.concatenate(noise_all)
        rows = []
        for lo, hi in zip(bins[:-1], bins[1:], strict=True):
            m = (flex >= lo) & (flex < hi)
            if not m.any():
                continue
            nz = noise[m][:, ey]
            nz = nz[np.isfinite(nz)]
            rows.append(
                {
                    "flex_deg": f"{lo}-{hi}",
                    "frames": int(m.sum()),
                    "share": round(float(m.mean()), 4),
                    "ey_err_p50": round(float(np.percentile(err[m][:, ey], 50)), 2),
                    "ey_err_p95": round(float(np.percentile(err[m][:, ey], 95)), 2),
                    "others_err_p95": round(
                        float(np.percentile(err[m][:, others].max(axis=1), 95)), 2
                    ),
                    "ik_noise_ey_p50": round(float(np.percentile(nz, 50)), 2),
                    "ik_noise_ey_p95": round(float(np.percentile(nz, 95)), 2),
                }
            )
        # task space of the worst ElbowYaw frames
        pred = np.concatenate(pred_all)
        truth = np.concatenate(truth_all)
        big = err[:, ey] > 20.0
        task = {}
        full_p = np.zeros((len(pred), 10), np.float32)
        full_t = np.zeros((len(pred), 10), np.float32)
        joints = list(ik.chain_joints(chain))
        full_p[:, joints] = pred
        full_t[:, joints] = truth
        ae = metrics.arm_errors(
            metrics.arm_points(full_p, robot=NAO_H25), metrics.arm_points(full_t, robot=NAO_H25)
        )
        si = metrics.sides(NAO_H25).index(side)
        for label, m in (("ey_err_over_20", big), ("all", np.ones_like(big))):
            if m.any():
                task[label] = {
                    "frames": int(m.sum()),
                    "flex_p50_deg": round(float(np.median(flex[m])), 1),
                    "hand_cm_p50": round(float(np.median(ae.hand[m, si]) * 100), 2),
                    "hand_cm_p95": round(float(np.percentile(ae.hand[m, si], 95) * 100), 2),
                    "forearm_deg_p50": round(float(np.degrees(np.median(ae.forearm[m, si]))), 2),
                    "forearm_deg_p95": round(
                        float(np.degrees(np.percentile(ae.forearm[m, si], 95))), 2
                    ),
                }
        share = float(np.mean(flex[big] < 30)) if big.any() else 0.0
        out[chain_name] = {
            "by_flexion": rows,
            "task_space": task,
            "ey_err_over_20_share_below_30deg_flex": round(share, 3),
        }
        log(f"  [{chain_name}] ElbowYaw by human elbow flexion (validation, pooled over folds):")
        for r in rows:
            log(f"    {r}")
        log(f"    task space: {task}; share of >20 deg ElbowYaw errors at flex < 30: {share:.2f}")
    return out


# ------------------------------------------------------------------------------- test split


def _headline(pred: np.ndarray, truth: np.ndarray) -> dict:
    m_max, m_avg = metrics.frame_errors(pred, truth)
    no_ey = metrics.m_max_without(pred, truth, robot=NAO_H25)
    pj = metrics.joint_percentiles(pred, truth, robot=NAO_H25)
    return {
        "M_avg_median": float(np.median(m_avg)),
        "M_max_p95": float(np.percentile(m_max, 95)),
        "M_max_no_elbow_yaw_p95": float(np.percentile(no_ey, 95)),
        "per_joint_p95": {j: round(v["p95"], 2) for j, v in pj.items()},
    }


def _project_chains(model: engine.Model, x: np.ndarray, objective: str, lm: dict, full) -> tuple:
    """Each chain with its own (L, M) (one ``engine.project`` per chain on its projector)."""
    sp = model.projector
    pred = np.zeros((len(x), 10), np.float32)
    t0 = time.perf_counter()
    for c, name in enumerate(sp.layout.names):
        n_l, n_m = lm[name]
        r, _ = engine.project(
            sp.chain(c), x[:, list(sp.layout.inputs[c])], objective, n_l=n_l, n_m=n_m, full=full
        )
        pred[:, list(sp.layout.outputs[c])] = r
    return pred, time.perf_counter() - t0


def test_split(chosen: dict, queries: dict, full_names: dict, log, quick: bool = False) -> dict:
    """Build the chosen model ONCE on all five training subjects; score subjects 2,4,6,8,10
    (``quick``: a code-path smoke run on every 4th training and every 20th test frame)."""
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=list(TRAIN_SUBJECTS)))
    test = datasets.valid_descriptors(
        datasets.msr_action3d(subjects=list(TEST_SUBJECTS), actions=datasets.ARM_ACTIONS)
    )
    if quick:
        train, test = train[::4], test[::20]
    truth = np.asarray(ik.solve_driven(test))
    per = [chosen[n] for n in CHAIN_NAMES]
    cfg = engine.BuildConfig(
        landmarks=None,
        bandwidth=tuple(p["bandwidth"] for p in per),
        k=tuple(p["k"] for p in per),
        hidden=tuple(p["hidden"] for p in per),
        lam=tuple(p["lam"] for p in per),
        input_scale=tuple(p["input_scale"] for p in per),
        seed=per[0]["seed"],
    )
    out: dict = {"load_before": _load(), "train_frames": len(train), "test_frames": len(test)}
    models = {}
    for label, c in (("chosen", cfg), ("default", engine.BuildConfig())):
        t0 = time.perf_counter()
        model = engine.build(train, c)
        jax.block_until_ready(model.projector)
        out[label] = {
            "build_s": time.perf_counter() - t0,
            "load_after_build": _load(),
            "landmarks": model.landmarks,
            "bandwidth": list(model.bandwidth),
            "config": asdict(c),
        }
        models[label] = model
        log(f"  built {label} in {out[label]['build_s']:.1f} s: {model.landmarks} (load {_load()})")
    ten = {n: (10, 10) for n in CHAIN_NAMES}
    lm = {n: (queries[n]["n_l"], queries[n]["n_m"]) for n in CHAIN_NAMES}
    runs = [
        ("default", "relaxed", ten, None),
        ("default", "full", ten, FullConfig()),
        ("chosen", "relaxed", lm, None),
        ("chosen", "full", lm, FullConfig()),
    ]
    if lm != ten:
        runs.append(("chosen", "relaxed", ten, None))
    # the full variant the folds preferred, per chain (if it is not the default FullConfig)
    for name in set(full_names.values()) - {"full_weighted"}:
        runs.append(("chosen", "full", lm, FULL_CONFIGS[name]))
    out["results"] = []
    for label, objective, lmx, full in runs:
        pred, wall = _project_chains(models[label], test, objective, lmx, full)
        r = _headline(pred, truth) | {
            "model": label,
            "objective": objective,
            "full": None if full is None else asdict(full),
            "L_M": {k: list(v) for k, v in lmx.items()},
            "wall_s": wall,
        }
        out["results"].append(r)
        log(
            f"  test {label:8s} {objective:8s} {str(r['full'] and r['full']['objective']):9s} "
            f"L,M={lmx['left_arm']}: med M_avg {r['M_avg_median']:.2f}  p95 M_max "
            f"{r['M_max_p95']:.1f}  p95 no EY {r['M_max_no_elbow_yaw_p95']:.1f}  ({wall:.1f} s)"
        )
        log(f"    per-joint p95 {r['per_joint_p95']}")
    out["load_after"] = _load()
    return out


# ------------------------------------------------------------------------------ markdown


def markdown(out: dict) -> str:
    """The result tables of a run (``--markdown OUT``), for ``benchmarks/TUNING.md``."""
    lines: list[str] = []
    stages = (
        ("bandwidth", "1. bandwidth (default kernels)"),
        ("k_hidden", "2a. k, hidden"),
        ("lam", "2b. lam"),
        ("input_scale", "2c. input_scale"),
        ("refine", "2d. bandwidth at the chosen kernels"),
        ("lm", "3. L, M (relaxed)"),
        ("full", "4. full objective (chosen settings, L, M)"),
    )

    def f(v: float, d: int = 2) -> str:
        return "NaN" if not np.isfinite(v) else f"{v:.{d}f}"

    for chain, res in out["chains"].items():
        arm = chain != "head"
        lines += [f"### {chain}", ""]
        head = "| stage | setting | K (folds) | med | p95 |" + (" p95 no EY |" if arm else "")
        lines += [head, "|---|---|---|---:|---:|" + ("---:|" if arm else "")]
        chosen_labels = {}
        for key, title in stages:
            if key not in res:
                continue
            rows = res[key]["grid"]
            pick = choose(rows)["label"] if key != "full" else None
            chosen_labels[key] = pick
            for r in rows:
                mark = " **<-**" if r["label"] == pick else ""
                cells = [
                    title,
                    r["label"] + mark,
                    f"{min(r['K'])}-{max(r['K'])}",
                    f(r["med"], 3),
                    f(r["p95"]),
                ]
                if arm:
                    cells.append(f(r.get("p95_no_ey", float("nan"))))
                lines.append("| " + " | ".join(cells) + " |")
        b = res["baseline"]
        cells = ["today's default", f"h={res['default_bandwidth']:g}, k=hidden=96, lam=1e-3, "
                 "input_scale=0.5, L=M=10", f"{min(b['K'])}-{max(b['K'])}", f(b["med"], 3),
                 f(b["p95"])] + ([f(b["p95_no_ey"])] if arm else [])  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        st, q = res["setting"], res["query"]
        lines.append(
            f"Chosen: bandwidth {st['bandwidth']:g}, k {st['k']}, hidden {st['hidden']}, "
            f"lam {st['lam']:g}, input_scale {st['input_scale']:g}, L {q['n_l']}, M {q['n_m']}."
        )
        pj = res["chosen"]["per_joint_p95"]
        bj = b["per_joint_p95"]
        lines.append(
            "Fold-mean per-joint p95, chosen (today's default): "
            + ", ".join(f"{j} {pj[j]:.2f} ({bj[j]:.2f})" for j in pj)
            + "."
        )
        if "seeds" in res:
            sd = res["seeds"]
            lines.append(
                f"One kernel seed at a time (seeds 0..{len(sd['chosen']['med']) - 1}): chosen med "
                f"{sd['chosen']['med']}, p95 {sd['chosen']['p95']}; today's default med "
                f"{sd['baseline']['med']}, p95 {sd['baseline']['p95']}."
            )
        lines += ["", "| bandwidth | K, all five subjects | run s (all five) | K per fold | run s "
                  "per fold |", "|---:|---:|---:|---|---|"]  # fmt: skip
        for row in res["bandwidth_table"]:
            ks = ", ".join(str(v["K"]) for v in row["folds"].values())
            ts = ", ".join(f"{v['seconds']:.1f}" for v in row["folds"].values())
            lines.append(
                f"| {row['bandwidth']:g} | {row['all']['K']} | {row['all']['seconds']:.1f} | "
                f"{ks} | {ts} |"
            )
        lines.append("")
    if "elbow_yaw_limit" in out:
        lim = out["elbow_yaw_limit"]
        lines += ["### What limits ElbowYaw (validation frames, chosen settings)", ""]
        for chain in ("left_arm", "right_arm"):
            lines += [
                f"{chain}:",
                "",
                "| human elbow flexion (deg) | share | EY err p50 | EY err p95 | other joints p95 "
                "| IK truth change under 3.7 mm noise, EY p50 | p95 |",
                "|---|---:|---:|---:|---:|---:|---:|",
            ]
            for r in lim[chain]["by_flexion"]:
                lines.append(
                    f"| {r['flex_deg']} | {r['share']:.3f} | {r['ey_err_p50']} | "
                    f"{r['ey_err_p95']} | {r['others_err_p95']} | {r['ik_noise_ey_p50']} | "
                    f"{r['ik_noise_ey_p95']} |"
                )
            lines += ["", f"Task space: {lim[chain]['task_space']}", ""]
    if "test" in out:
        t = out["test"]
        lines += [
            "### Test split (subjects 2,4,6,8,10, arm actions; built once on 1,3,5,7,9)",
            "",
            "| model | objective | L, M (arms) | median M_avg | p95 M_max | p95 no EY | "
            + " | ".join(robot.DRIVEN_JOINTS)
            + " |",
            "|---|---|---|---:|---:|---:|" + "---:|" * len(robot.DRIVEN_JOINTS),
        ]
        for r in t["results"]:
            obj = r["objective"] if r["full"] is None else f"full ({r['full']['objective']}"
            if r["full"] is not None:
                obj += ", candidate)" if r["full"]["include_candidate"] else ")"
            lines.append(
                f"| {r['model']} | {obj} | {tuple(r['L_M']['left_arm'])} | "
                f"{r['M_avg_median']:.2f} | {r['M_max_p95']:.1f} | "
                f"{r['M_max_no_elbow_yaw_p95']:.1f} | "
                + " | ".join(f"{r['per_joint_p95'][j]:.1f}" for j in robot.DRIVEN_JOINTS)
                + " |"
            )
        lines.append("")
        for label in ("chosen", "default"):
            lines.append(
                f"Build ({label}): {t[label]['build_s']:.1f} s, landmarks {t[label]['landmarks']}, "
                f"load after {t[label]['load_after_build']}."
            )
        lines.append("")
    return "\n".join(lines)


# -------------------------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default="/tmp/tune-cache", help="cache folder (default %(default)s)")
    ap.add_argument("--json", default=None, help="write every result here")
    ap.add_argument("--markdown", default=None, help="write the result tables here")
    ap.add_argument("--quick", action="store_true", help="smoke run (see the module doc)")
    ap.add_argument("--chains", default=",".join(CHAIN_NAMES), help="chains to tune")
    ap.add_argument("--arm-bandwidths", default=",".join(map(str, ARM_BANDWIDTHS)))
    ap.add_argument("--head-bandwidths", default=",".join(map(str, HEAD_BANDWIDTHS)))
    ap.add_argument("--slow-s", type=float, default=60.0, help="head grid stops past this run time")
    ap.add_argument(
        "--extend",
        type=int,
        default=1,
        help="steps past a winning grid edge (bandwidth, lam, input_scale; default %(default)s)",
    )
    ap.add_argument(
        "--tune-seeds", type=int, default=2, help="kernel seeds averaged per fold (default 2)"
    )
    ap.add_argument("--seeds", type=int, default=1, help="seeds for the seed-spread check")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-full", action="store_true", help="skip stage 4")
    ap.add_argument("--no-limit", action="store_true", help="skip the ElbowYaw analysis")
    ap.add_argument("--test", action="store_true", help="then score the test split once")
    args = ap.parse_args(argv)
    args.arm_bandwidths = [float(v) for v in args.arm_bandwidths.split(",")]
    args.head_bandwidths = [float(v) for v in args.head_bandwidths.split(",")]
    if args.quick:
        args.arm_bandwidths = args.arm_bandwidths[:1] + args.arm_bandwidths[2:3]
        args.head_bandwidths = args.head_bandwidths[:2]
    chains = [c for c in args.chains.split(",") if c]
    t_start = time.perf_counter()
    tuner = Tuner(Path(args.cache), args.quick, args.seed, args.tune_seeds)
    out: dict = {
        "protocol": "leave-one-training-subject-out over 1,3,5,7,9; validation: held-out "
        "subject's arm-action frames",
        "rule": f"drop NaN rows; lowest fold-mean med, rows within max({TIE_ABS} deg, "
        f"{TIE_REL:.0%}) of it tied; among them the lowest fold-mean p95, rows within "
        f"max({TIE_P95_ABS} deg, {TIE_REL:.0%}) of it tied; among them the cheapest (landmarks, "
        "hidden * k, L * M, relaxed first), then the lowest med",
        "quick": args.quick,
        "folds": list(tuner.folds),
        "load_start": _load(),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, jax {jax.__version__} "
        f"({jax.devices()[0].platform})",
        "chains": {},
    }
    print(f"tune_chains: folds {tuner.folds}, quick={args.quick}, load {_load()}")
    for chain in chains:
        res = tune_chain(tuner, chain, args, print)
        bws = sorted(
            {r["setting"]["bandwidth"] for st in ("bandwidth", "refine") for r in res[st]["grid"]},
            reverse=True,
        )
        res["bandwidth_table"] = bandwidth_table(tuner, chain, bws)
        for row in res["bandwidth_table"]:
            print(f"    h={row['bandwidth']:g}: all five subjects K={row['all']['K']} "
                  f"({row['all']['seconds']} s); folds {row['folds']}")  # fmt: skip
        out["chains"][chain] = res
    chosen = {c: out["chains"][c]["setting"] for c in chains}
    queries = {c: out["chains"][c]["query"] for c in chains}
    out["chosen"] = {"settings": chosen, "queries": queries}
    if not args.no_limit and {"left_arm", "right_arm"} <= set(chains):
        out["elbow_yaw_limit"] = elbow_yaw_limit(tuner, chosen, queries, print)
    out["kernel_train_s_median"] = float(np.median(tuner.kernel_s)) if tuner.kernel_s else None
    out["tuning_wall_s"] = time.perf_counter() - t_start
    if args.test and set(chains) == set(CHAIN_NAMES):
        full_names = {}
        for c in chains:
            rows = out["chains"][c].get("full", {}).get("grid", [])
            fulls = [r for r in rows if r["label"] != "relaxed"]
            if fulls:
                full_names[c] = choose(fulls)["label"]
        out["test"] = test_split(chosen, queries, full_names, print, args.quick)
    out["load_end"] = _load()
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(markdown(out))
    return out


if __name__ == "__main__":
    main()
