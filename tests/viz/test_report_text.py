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
    # one such pose: singular, and one distance, not "1 lie ... 25-25 deg"
    assert "The other one lies far from every landmark (its nearest 25 deg away" in text
    assert "1 lie" not in text and "25-25" not in text
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


def test_far_note_plural_and_range():
    bp = {
        "poses": {p: _pose(40.0, {"RShoulderPitch": 40.0}) for p in ("POSE_4", "POSE_6")},
        "coverage_deg": {"POSE_4": {"pose": 21.2}, "POSE_6": {"pose": 31.0}},
    }
    text = report_text.pose_notes(bp)[1]
    assert "The other 2 lie far from every landmark (their nearest 21-31 deg away" in text
    bp["coverage_deg"]["POSE_6"]["pose"] = 20.9  # both print as 21: one number, no "21-21"
    text = report_text.pose_notes(bp)[1]
    assert "(their nearest 21 deg away" in text and "21-21" not in text


def test_smoothness_rows_say_n_a_not_nan():
    rows = report_text.smoothness_md(
        {
            "relaxed": {"jerk_raw": 5.8e6, "jerk_smoothed": 2.1e6, "lag_frames_raw": -0.03,
                        "lag_frames_smoothed": 0.0},
            "ik": {"jerk_raw": 7.7e6},
        }
    )  # fmt: skip
    assert rows[0] == "| relaxed | 5.8e+06 | 2.1e+06 | -0.03 | +0.00 |"
    tiny = report_text.smoothness_md({"full": {"jerk_raw": 1.0, "lag_frames_raw": -0.001}})
    assert tiny == ["| full | 1 | n/a | +0.00 | n/a |"]  # not -0.00
    assert rows[1].startswith("| ik (the reference") and rows[1].endswith(
        "| 7.7e+06 | n/a | n/a | n/a |"
    )
    assert not any("nan" in r for r in rows)


def test_bandwidths_are_short():
    bw = {"head": 0.01125, "left_arm": 0.08222244790526831}
    assert report_text.bandwidths(bw) == "head 0.01125 / left_arm 0.08222"
    assert report_text.bandwidths([0.01875, 0.1111761806296]) == "0.01875 / 0.1112"
