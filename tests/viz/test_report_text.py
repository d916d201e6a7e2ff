"""The demo report's prose (jaxproj.viz.report_text) says what the numbers it is given say."""

from jaxproj.viz import report_text


def _pose(m_max: float, errors: dict[str, float]) -> dict:
    return {"relaxed": {"M_max": m_max, "joint_errors_deg": errors}}


def test_pose_notes_name_the_worst_joint_and_the_cause():
    bp = {
        "poses": {
            "POSE_1": _pose(49.5, {"LElbowYaw": 49.5, "LShoulderPitch": 2.0}),
            "POSE_2": _pose(60.0, {"RShoulderPitch": 60.0, "RElbowYaw": 3.0}),
            "POSE_3": _pose(4.0, {"HeadYaw": 4.0}),
        },
        "coverage_deg": {
            p: {"pose": v} for p, v in (("POSE_1", 6.2), ("POSE_2", 25.0), ("POSE_3", 1.0))
        },  # fmt: skip
    }
    text = report_text.pose_notes(bp)[1]
    assert "POSE_1 49.5 deg at LElbowYaw, 2.0 without ElbowYaw (nearest landmark 6.2 deg)" in text
    assert "POSE_2 60.0 deg at RShoulderPitch, 60.0 without ElbowYaw" in text
    assert "POSE_3" not in text and "In 1 of 2 the worst joint is an ElbowYaw" in text
    assert "The other 1 lie far from every landmark (the nearest 25-25 deg away" in text
    ok = {"poses": {"POSE_3": bp["poses"]["POSE_3"]}, "coverage_deg": bp["coverage_deg"]}
    assert report_text.pose_notes(ok) == ["", "Every basic pose is within 10 deg (relaxed)."]


def test_smoother_label_and_confidence_md():
    assert "zero-lag offline RTS" in report_text.smoother_label(
        {"kind": "offline", "accel_std": 7.0, "noise_std": 0.02}
    )
    assert "alpha 0.75" in report_text.smoother_label(
        {"kind": "paper", "alpha": 0.75, "gamma": 0.3, "eta": 0.15}
    )
    assert report_text.smoother_label(None) == "no smoother"
    assert report_text.confidence_md({}) == []
