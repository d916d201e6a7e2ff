"""Compatibility names: the old ``objectives`` module, now split by stage.

The projector pytrees are in ``projector``, the relaxed objective in ``relaxed``, the full
objective in ``full``, chain stacking in ``stacked`` and ``FullConfig`` in ``config``; this
module only re-exports their public names for code written against it. New code imports the
real homes.
"""

from jaxproj.projection.config import FullConfig, FullObjective, Solver
from jaxproj.projection.full import (
    GRADIENT_STEPS,
    NEWTON_DAMPING,
    NEWTON_STEPS,
    Cluster,
    cluster,
    cluster_objective,
    project_full_one,
    solve_cluster,
    solve_cluster_newton,
    start_value,
)
from jaxproj.projection.projector import (
    ChainLayout,
    Projector,
    StackedProjector,
    back_deviation,
    candidates,
    make_projector,
)
from jaxproj.projection.relaxed import (
    backward_widths,
    least_deviations_rows,
    project_relaxed_one,
    project_relaxed_rows,
    relaxed_candidates,
)
from jaxproj.projection.stacked import project_stacked_one, stack_projectors

Objective = FullObjective

__all__ = [
    "GRADIENT_STEPS",
    "NEWTON_DAMPING",
    "NEWTON_STEPS",
    "ChainLayout",
    "Cluster",
    "FullConfig",
    "Objective",
    "Projector",
    "Solver",
    "StackedProjector",
    "back_deviation",
    "backward_widths",
    "candidates",
    "cluster",
    "cluster_objective",
    "least_deviations_rows",
    "make_projector",
    "project_full_one",
    "project_relaxed_one",
    "project_relaxed_rows",
    "project_stacked_one",
    "relaxed_candidates",
    "solve_cluster",
    "solve_cluster_newton",
    "stack_projectors",
    "start_value",
]
