"""Build and projection settings, validated in plain Python before anything is traced.

``BuildConfig`` (with its per-chain view ``ChainConfig`` and the tuned ``DEFAULTS``) says how
``jaxproj.projection.build`` builds a model; ``FullConfig`` how the full objective
(``jaxproj.projection.full``) solves. Both are frozen, hashable dataclasses (``FullConfig`` is a
static argument of the jitted projection) that raise ``ConfigError`` saying what to change.
They sit apart from the code that uses them so that the model file (``model_file``), the
builder and the projection read one definition without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Literal

from jaxproj import robots
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import resolve_bones
from jaxproj.io.bundled import UTK_SUBJECTS, UTK_TRAIN_SUBJECTS
from jaxproj.robots import Robot

DEFAULT_LANDMARKS = 1000
"""Landmarks of a chain of the ``"upper"`` chain set whose robot gives it no tuned bandwidth
(``Chain.bandwidth``), when ``BuildConfig`` sets no size: not tuned."""

DEFAULTS: dict[str, dict[str, object]] = {
    "upper": dict(k=96, hidden=192, lam=1e-4, input_scale=0.5),
    "whole": dict(landmarks=1644, k=96, hidden=96, lam=1e-3, input_scale=0.5),
}
"""What a ``BuildConfig`` setting left at ``None`` means, per chain set. ``"upper"``: tuned per
chain on the training subjects only (leave-one-training-subject-out over 1,3,5,7,9; the grid,
fold means and the rule are in ``benchmarks/TUNING.md``): mean-shift bandwidths (head, left arm,
right arm; the right arm takes the left arm's tuned value: the robot's ``Chain.bandwidth``; a
chain without one gets ``DEFAULT_LANDMARKS``), 192 hidden units, ridge 1e-4.
``"whole"``: the paper's 1644 landmarks and the whole-body engine's earlier defaults, so that
its answers stay those measured before chains existed."""

PerChain = tuple  # a tuple with one value per chain, in chain order


def _per_chain(value: object, c: int, n: int, name: str) -> object:
    if isinstance(value, (tuple, list)):
        if len(value) != n:
            raise ConfigError(f"{name} has {len(value)} values for {n} chains")
        return value[c]
    return value


@dataclass(frozen=True)
class ChainConfig:
    """The settings of one chain's projector (``BuildConfig.chain_config``)."""

    landmarks: int | None
    bandwidth: float | None
    k: int
    hidden: int
    lam: float
    input_scale: float
    seed: int


@dataclass(frozen=True)
class BuildConfig:
    """How a model is built: which chains, per chain its landmarks and kernels, and which
    bundled UTKinect-Action3D people its training data holds.

    Validated when constructed (``ConfigError`` with what to change). Every per-chain setting
    is one value for all chains or a tuple with one value per chain (in
    ``robot_spec.chain_set(chains)`` order; the default robot's: head, left_arm, right_arm).

    Attributes:
      chains: ``"upper"`` (default): one projector per kinematic chain of the robot
        (``Robot.chains``; the default robot's: head, left arm, right arm), searched and trained in
        the chain's own bones; ``"whole"``: one projector over the whole descriptor, the paper's
        formulation (``Robot.whole_chain``).
      landmarks: target landmark count (the mean-shift bandwidth is found by bisection). One
        number sets each chain (and the whole-body chain) but those whose robot marks them
        ``Chain.keep_bandwidth`` (a head chain read from the neck alone varies little, so a count
        target would bisect over many mean-shift runs), which keep their robot's
        ``Chain.bandwidth``. A per-chain tuple may hold ``None`` where ``bandwidth`` gives it.
        With neither ``landmarks`` nor ``bandwidth`` given, ``DEFAULTS[chains]`` decides.
      bandwidth: mean-shift bandwidth, used as is (per chain where ``landmarks`` is ``None``).
      bones: descriptor bone subset (``skeleton.descriptor``): ``"auto"`` (default) is
        ``"upper"`` when the robot's IK reads only those bones (the default robot's), else
        ``"full"`` (e.g. a robot whose waist and legs read the hips, thighs, shins and feet);
        resolved when constructed.
      mirror: mirror imitation (human left drives robot right).
      k: training neighbours per ELM kernel (the landmark itself included), capped at the
        chain's number of landmarks ``K``: a small set (the paper's 86) trains every kernel on all
        its landmarks. The ``k`` used is in the model's layout.
      hidden: hidden units per kernel (``>= k``).
      lam: ridge regulariser of the ELMs.
      input_scale: standard deviation of the random hidden weights.
      (``k``, ``hidden``, ``lam``, ``input_scale`` left at ``None``: ``DEFAULTS[chains]``.)
      seed: PRNG seed of the random hidden layers (chain 0 uses ``PRNGKey(seed)``, chain ``c``
        ``fold_in(PRNGKey(seed), c)``).
      robot: the name of a registered robot (``jaxproj.robots.names()``) whose chains, limits
        and IK the model is built for.
      utkinect_people: the training data's people from the bundled UTKinect-Action3D subset
        (of 3, 4, 6, 7, 9), whose whole recordings join MSR Action3D's training subjects
        1,3,5,7,9 in the default training set (``datasets.training_sequences``: what ``jaxproj
        build`` trains on from the bundled data). Default ``(3, 4, 6)``
        (``datasets.UTK_TRAIN_SUBJECTS``), chosen by measurement (``docs/results.md``, "Which
        people the default model trains on"); ``()``: MSR Action3D alone. ``build`` trains on
        the descriptors it is given and records this field as it is, in the model file too:
        give it what they hold (``jaxproj build`` records ``()`` for data other than the
        bundled training set). Score a model on UTKinect only with
        ``datasets.utkinect_held_out(model.config.utkinect_people)``.
    """

    landmarks: int | PerChain | None = None
    bandwidth: float | PerChain | None = None
    chains: str = "upper"
    bones: str = "auto"
    mirror: bool = False
    k: int | PerChain | None = None
    hidden: int | PerChain | None = None
    lam: float | PerChain | None = None
    input_scale: float | PerChain | None = None
    seed: int = 0
    robot: str = robots.DEFAULT
    utkinect_people: tuple[int, ...] = UTK_TRAIN_SUBJECTS

    def __post_init__(self) -> None:
        for name in ("landmarks", "bandwidth", "k", "hidden", "lam", "input_scale"):
            if isinstance(getattr(self, name), list):  # from JSON
                object.__setattr__(self, name, tuple(getattr(self, name)))
        people = self.utkinect_people
        if (
            not isinstance(people, (tuple, list))
            or any(isinstance(x, bool) or x not in UTK_SUBJECTS for x in people)
            or len(set(people)) != len(people)
        ):
            raise ConfigError(
                f"utkinect_people={people!r} must be distinct people of the bundled "
                f"UTKinect-Action3D subset {UTK_SUBJECTS} (a tuple; () for none)"
            )
        object.__setattr__(self, "utkinect_people", tuple(int(x) for x in people))
        if robots.is_file_name(self.robot):  # a robot file: read, registered, named
            object.__setattr__(self, "robot", robots.get(self.robot).name)
        if not isinstance(self.robot, str) or self.robot not in robots.names():
            raise ConfigError(
                f"robot={self.robot!r} is not a registered robot; use one of {robots.names()} "
                "(or register it: jaxproj.robots.register)"
            )
        chains = self.robot_spec.chain_set(self.chains)
        if self.bones == "auto":
            upper = all(b in resolve_bones("upper") for b in self.robot_spec.ik_bones)
            object.__setattr__(self, "bones", "upper" if upper else "full")
        elif not isinstance(self.bones, str):
            object.__setattr__(self, "bones", tuple(self.bones))
        self.robot_spec.check_bones(self.bones)  # unknown names, or a subset the IK cannot use
        for c in range(len(chains)):
            self.chain_config(c)

    @property
    def robot_spec(self) -> Robot:
        """The registered ``Robot`` called ``robot``."""
        return robots.get(self.robot)

    @property
    def chain_names(self) -> tuple[str, ...]:
        """Names of the chains, in order."""
        return tuple(ch.name for ch in self.robot_spec.chain_set(self.chains))

    def chain_config(self, c: int) -> ChainConfig:
        """Chain ``c``'s settings (validated; ``ConfigError`` says what to change)."""
        chains = self.robot_spec.chain_set(self.chains)
        n, name = len(chains), chains[c].name

        defaults = DEFAULTS[self.chains]
        sizes_given = self.landmarks is not None or self.bandwidth is not None

        # Any: the type depends on field_name (int or float per field; None for an unset size)
        def get(field_name: str) -> Any:
            value = getattr(self, field_name)
            if value is None and (field_name not in ("landmarks", "bandwidth") or not sizes_given):
                value = defaults.get(field_name)
            return _per_chain(value, c, n, field_name)

        landmarks, bandwidth = get("landmarks"), get("bandwidth")
        if self.chains == "upper" and not sizes_given:  # the robot's tuned size, else a count
            tuned = chains[c].bandwidth
            landmarks, bandwidth = (None, tuned) if tuned is not None else (DEFAULT_LANDMARKS, None)
        keep = chains[c].bandwidth if chains[c].keep_bandwidth else None
        if keep is not None and isinstance(self.landmarks, int) and bandwidth is None:
            landmarks, bandwidth = None, keep
        if (landmarks is None) == (bandwidth is None):
            raise ConfigError(f"chain {name}: give exactly one of landmarks (a count) or bandwidth")
        if landmarks is not None and landmarks < 2:
            raise ConfigError(f"chain {name}: landmarks={landmarks} must be >= 2")
        if bandwidth is not None and not bandwidth > 0:
            raise ConfigError(f"chain {name}: bandwidth={bandwidth} must be > 0")
        cfg = ChainConfig(
            landmarks, bandwidth, get("k"), get("hidden"), get("lam"), get("input_scale"), self.seed
        )
        if cfg.k < 2:
            raise ConfigError(f"chain {name}: k={cfg.k} must be >= 2")
        if self.k is not None and landmarks is not None and cfg.k > landmarks:
            raise ConfigError(
                f"chain {name}: k={cfg.k} is larger than its landmark count {landmarks} (a kernel "
                f"trains on at most all landmarks): lower k to <= {landmarks} or raise landmarks"
            )
        if cfg.hidden < cfg.k:
            raise ConfigError(f"chain {name}: hidden={cfg.hidden} must be >= k={cfg.k}")
        if not cfg.lam > 0:
            raise ConfigError(f"chain {name}: lam={cfg.lam} must be > 0")
        if not cfg.input_scale > 0:
            raise ConfigError(f"chain {name}: input_scale={cfg.input_scale} must be > 0")
        return cfg


FullObjective = Literal["weighted", "min"]
Solver = Literal["newton", "adam"]


@dataclass(frozen=True)
class FullConfig:
    """Settings of the full (simplex-weighted) objective. Static (hashable) under ``jax.jit``.

    The problems are stated exactly in ``jaxproj.projection.full`` and the docs' engine page.
    Validated when constructed: a bad value raises ``ConfigError``.

    Attributes:
      objective: ``"weighted"`` (default): one problem per candidate, its kernels' deviations
        weighted by the simplex weights; ``"min"``: the paper's eq. 2 read literally,
        ``min_k min_w``: one problem per (candidate, kernel).
      solver: ``"newton"`` (default, ``NEWTON``): projected Gauss-Newton in joint space,
        run until every problem of the batch is stationary or ``iterations``
        (``simplex_newton``): converged; ``"adam"`` (``ADAM_30``): projected ``optax.adam``,
        exactly ``iterations`` steps: ~2.2x faster on a CPU, 1.3x on an H200, but it stops
        short of the minimum (``docs/results.md``). Both project with
        ``optax.projections.projection_simplex`` and never return worse than the warm start.
      iterations: Newton: cap on steps per problem; Adam: its steps. ``>= 0``.
      learning_rate: Adam's step size on the weights, ``> 0``. Unused by Newton.
      include_candidate: add the candidate itself as vertex 0 of its simplex (warm start
        ``w0 = e_0``, i.e. the relaxed answer).
      clusters: optimise only the ``clusters`` problems whose objective is smallest at their
        warm start (``0``: all, the exact full objective). A speed option; its measured effect
        is in ``benchmarks/RESULTS.md``.
      proximal: ``rho``, the weight of ``rho/2 ||r - r_c||^2`` toward the cluster's candidate
        (makes the minimiser unique where the kernels leave a joint free), ``>= 0``.
      ridge: ``eps``, the weight of ``eps/2 ||w||^2`` (least-norm weights), ``>= 0``.
      dec_tol: Newton's stationarity test: its quadratic model predicts a decrease of at most
        ``dec_tol * max(F, 1e-8)``, ...
      step_tol: ... and its last step (none, if rejected) moved every joint by less than
        ``step_tol`` rad, ...
      gap_tol: ... and the Frank-Wolfe gap (``simplex_newton.frank_wolfe_gap``: the decrease
        the gradient promises by moving all the way to the best vertex; 0 exactly at a KKT
        point) is at most ``gap_tol * max(F, 1e-8)``: the first-order certificate that the
        weighted objective's indefinite model does not give (before it, a rejected step of
        that model stopped problems short of their minimum: answers that jumped by degrees
        under a one-ulp input change, ``docs/results.md``). ``0``: no gap test. ``>= 0``.
      screen, finalists: Newton solves every problem for ``screen`` steps, then only the
        ``finalists`` with the least objective on to ``iterations`` (``0`` finalists: every
        problem to the end). Measured against solving all: ``benchmarks/results``.
      tie_rtol: the full objective's near-tie rule. Solved problems whose objective lies within
        ``tie_rtol * F_min`` of the least ``F_min`` are equally good answers (the solver stops
        within ``dec_tol`` of a minimum, and F is a float32 sum): the answer is the first of
        them in candidate order (the candidate of the nearest human landmark first), not the
        one whose F rounding made least, so a one-ulp change of the input cannot move the
        answer between two near-equal minima. ``0``: the least F, as before. ``>= 0``.
    """

    objective: FullObjective = "weighted"
    solver: Solver = "newton"
    iterations: int = 30
    learning_rate: float = 0.05
    include_candidate: bool = False
    clusters: int = 0
    proximal: float = 1e-3
    ridge: float = 1e-8
    dec_tol: float = 1e-6
    step_tol: float = 1e-5
    screen: int = 8
    finalists: int = 2
    tie_rtol: float = 1e-3
    gap_tol: float = 1e-2

    def __post_init__(self) -> None:
        if self.objective not in ("weighted", "min"):
            raise ConfigError(f"full objective must be 'weighted' or 'min', got {self.objective!r}")
        if self.solver not in ("newton", "adam"):
            raise ConfigError(f"full solver must be 'newton' or 'adam', got {self.solver!r}")
        if self.iterations < 0:
            raise ConfigError(f"full iterations={self.iterations} must be >= 0")
        if not self.learning_rate > 0:
            raise ConfigError(f"full learning_rate={self.learning_rate} must be > 0")
        if self.clusters < 0:
            raise ConfigError(f"full clusters={self.clusters} must be >= 0 (0: all L)")
        if self.screen < 0 or self.finalists < 0:
            raise ConfigError(f"full screen={self.screen}, finalists={self.finalists} must be >= 0")
        for name in ("proximal", "ridge", "dec_tol", "step_tol", "tie_rtol", "gap_tol"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"full {name}={getattr(self, name)} must be >= 0")


ADAM_30 = FullConfig(solver="adam", iterations=30)
"""The fast, unconverged solver: 30 projected Adam steps (``FullConfig()`` until 0.2.0)."""

NEWTON = FullConfig()
"""The converged solver, ``FullConfig()``: projected Gauss-Newton in joint space
(``simplex_newton``)."""

FULL_READINGS = {
    "weighted": NEWTON,
    "weighted+candidate": replace(NEWTON, include_candidate=True),
    "min": replace(NEWTON, objective="min"),
    "min+candidate": replace(NEWTON, objective="min", include_candidate=True),
}
"""The readings of the full objective (``objective`` x ``include_candidate``), each converged:
``retarget --full-reading`` and ``benchmarks/full_objective.py`` choose among them."""
