"""The rollout's self-contact groups come from the robot's kinematic tree (no compile)."""

from __future__ import annotations

import mujoco
import pytest

from jaxproj.eval import rollout_model
from jaxproj.eval.rollout import RolloutConfig
from jaxproj.robots import NAO_H25, UNITREE_G1


def _by_name(model: mujoco.MjModel) -> list[str]:
    """The NAO's former rule, from its geom names: ``torso_*``, ``head_*``, ``l_upperarm*`` /
    ``l_forearm*`` / ``l_hand*`` and the ``r_`` twins."""
    out = []
    for g in range(model.ngeom):
        parts = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").split("_")
        if parts[0] in ("torso", "head"):
            out.append(parts[0])
        elif parts[0] in ("l", "r") and parts[1:2] in (["upperarm"], ["forearm"], ["hand"]):
            out.append({"l": "arm_left", "r": "arm_right"}[parts[0]])
        else:
            out.append("other")
    return out


@pytest.mark.parametrize("part", ["whole", "upper", "legs"])
def test_the_naos_groups_are_those_its_geom_names_gave(part: str) -> None:
    model = rollout_model._fixed_model(RolloutConfig(), part, NAO_H25)
    got = rollout_model._geom_classes(model, NAO_H25)
    if (
        part == "legs"
    ):  # no arm: nothing to report (the names saw the torso, which alone reports none)
        assert set(got) == {"other"} and not (rollout_model._pair_group(model, NAO_H25) >= 0).any()
    else:
        assert got == _by_name(model)


def test_the_g1s_arms_torso_and_head_are_found_though_named_otherwise() -> None:
    model = UNITREE_G1.load_model("fixed")
    name = lambda g: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)  # noqa: E731
    got = {name(g): c for g, c in enumerate(rollout_model._geom_classes(model, UNITREE_G1))}
    assert not any(c.startswith("arm") for c in _by_name(model))  # the names found no arm
    for side in ("left", "right"):
        arm = {g for g, c in got.items() if c == f"arm_{side}"}
        assert arm == {f"{side}_{p}_geom" for p in ("upper_arm", "forearm", "wrist", "hand")}
    assert [g for g, c in got.items() if c == "torso"] == ["torso_geom"]
    assert [g for g, c in got.items() if c == "head"] == ["head_geom"]
    assert got["pelvis_geom"] == got["left_thigh_geom"] == "other"
    groups = rollout_model._pair_group(model, UNITREE_G1)
    g = {name(i): i for i in range(model.ngeom)}
    arm_torso = rollout_model.CONTACT_GROUPS.index("arm_torso")
    assert groups[g["left_forearm_geom"], g["torso_geom"]] == arm_torso
    assert groups[g["left_hand_geom"], g["right_hand_geom"]] == rollout_model.CONTACT_GROUPS.index(
        "arm_arm"
    )
