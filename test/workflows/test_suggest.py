"""``pascal-calib suggest`` (workflows/suggest.py): NEXT.yaml with the issue's fields, exit 2 with
the reason on bad input; arm suggestions stay inside the trust region."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from pascal_calib_ros.analysis.guide.candidates import feature_centre
from pascal_calib_ros.cli import main
from pascal_calib_ros.geometry import ImageSize
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.hand_eye_yaml import write_poses_yaml
from pascal_calib_ros.sim.arm import ArmSpec, simulate_arm_session
from pascal_calib_ros.sim.session import SessionSpec, render_session
from pascal_calib_ros.targets import Target, resolve_target


@pytest.fixture(scope="module")
def views(tmp_path_factory: pytest.TempPathFactory, ring_target: Target) -> list[Path]:
    out = tmp_path_factory.mktemp("suggest")
    return render_session(ring_target, SessionSpec(width=640, height=480, k1=-0.2, views=4, seed=2), out)


def test_next_yaml_has_the_fields_and_a_pose_that_puts_the_target_where_said(views: list[Path], tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "NEXT.yaml"
    code = main(["suggest", "--target", "ring_a4", "-n", "3", "--goal-sigma", "0.05", "-o", str(out),
                 *map(str, views)])
    assert code == 0
    doc = yaml.safe_load(out.read_text())
    assert doc["done"] is False and doc["goal_sigma_px"] == 0.05
    assert doc["projection_sigma_px"] > 0.05 and doc["views_used"] == 4
    assert 1 <= len(doc["suggestions"]) <= 3
    sig = [s["predicted_sigma_px"] for s in doc["suggestions"]]
    assert sig == sorted(sig) and sig[0] < doc["projection_sigma_px"]
    target = resolve_target("ring_a4")
    for s in doc["suggestions"]:
        T = s["camera_T_target"]
        assert len(T["translation"]) == 3 and len(T["rotation"]) == 4
        pose = Transform.from_quat(T["rotation"], T["translation"])
        # X_cam = R X_target + t: the ring's centre (target YAML frame) lies at the placement's distance
        centre = pose.apply(np.r_[target.rings[0].center, 0.0])
        assert np.linalg.norm(centre) == pytest.approx(s["placement"]["distance_m"], rel=1e-3)
    assert "next views" in capsys.readouterr().out
    # a goal already met: done
    code = main(["suggest", "--target", "ring_a4", "--goal-sigma", "1000", "-o", str(out), *map(str, views)])
    assert code == 0 and yaml.safe_load(out.read_text())["done"] is True


def test_bad_input_exits_2_with_the_reason(views: list[Path], tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "NEXT.yaml"
    assert main(["suggest", "--target", "ring_a4", "-o", str(out), str(views[0]), str(views[1])]) == 2
    assert "need at least 3" in capsys.readouterr().err
    assert main(["suggest", "--target", "no_such_target", "-o", str(out), *map(str, views)]) == 2
    assert "target file not found" in capsys.readouterr().err
    assert main(["suggest", "--target", "ring_a4", "--poses", str(tmp_path / "p.yaml"), "-o", str(out),
                 *map(str, views)]) == 2
    assert "--mode" in capsys.readouterr().err
    assert main(["suggest", "--target", "ring_a4", "--goal-sigma", "0", "-o", str(out), *map(str, views)]) == 2
    assert "--goal-sigma" in capsys.readouterr().err
    assert main(["suggest", "--target", "ring_a4", "--mode", "eye_in_hand", "--poses", str(tmp_path / "none.yaml"),
                 "-o", str(out), *map(str, views)]) == 2
    assert "cannot read" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("mode", ["eye_in_hand", "eye_to_hand"])
def test_arm_suggestions_stay_within_reach_and_max_turn(tmp_path: Path, mode: str) -> None:
    target = resolve_target("ring_grid_a4")
    s = simulate_arm_session(target, ArmSpec(mode=mode, views=5, width=640, height=480, seed=3, systematic_mm=0.0))
    paths = []
    import cv2

    for name, img in zip(s.names, s.images[target.name], strict=True):
        cv2.imwrite(str(tmp_path / name), img)
        paths.append(tmp_path / name)
    write_poses_yaml(tmp_path / "POSES.yaml", "base_link", "tool0", dict(zip(s.names, s.robot_poses, strict=True)))
    out = tmp_path / "NEXT.yaml"
    reach, turn = 0.1, 30.0
    code = main(["suggest", "--target", "ring_grid_a4", "--poses", str(tmp_path / "POSES.yaml"), "--mode",
                 mode, "--reach", str(reach), "--max-turn", str(turn), "-n", "4", "-o", str(out),
                 *map(str, paths)])
    assert code == 0
    doc = yaml.safe_load(out.read_text())
    assert doc["mode"] == mode and doc["frame_id"] == "base_link" and doc["child_frame_id"] == "tool0"
    assert doc["hand_eye_sigma_deg"] > 0 and doc["hand_eye_sigma_mm"] > 0
    assert doc["suggestions"], "no suggestion inside the trust region"
    visited = s.robot_poses
    for sg in doc["suggestions"]:
        tool = Transform.from_quat(sg["tool"]["rotation"], sg["tool"]["translation"])
        d = min(np.linalg.norm(tool.translation - v.translation) for v in visited)
        a = min((tool.rotation * v.rotation.inv()).magnitude() for v in visited)
        assert d <= reach + 1e-9 and np.degrees(a) <= turn + 1e-6
        assert sg["predicted_hand_eye_sigma_deg"] > 0
        # the tool pose and the view agree through the estimated hand-eye loop: the true loop puts
        # the target's features where the suggestion says (up to the grid's 180 degree symmetry, which
        # the session's labelling may have chosen: the features' centre and the sheet's normal agree)
        C = s.hand_eye.inverse() @ (tool.inverse() if mode == "eye_in_hand" else tool) @ s.target_pose
        want = Transform.from_quat(sg["camera_T_target"]["rotation"], sg["camera_T_target"]["translation"])
        c = np.r_[feature_centre(target), 0.0]
        assert np.linalg.norm(C.apply(c) - want.apply(c)) < 0.01
        assert np.degrees(np.arccos(np.clip(C.R[:, 2] @ want.R[:, 2], -1, 1))) < 1.0
    # a trust region that excludes everything but the visited poses themselves gives no tool pose far away
    code = main(["suggest", "--target", "ring_grid_a4", "--poses", str(tmp_path / "POSES.yaml"), "--mode",
                 mode, "--reach", "0.001", "--max-turn", "0.1", "-o", str(out), *map(str, paths)])
    assert code == 0 and yaml.safe_load(out.read_text())["suggestions"] == []


def _numbers(doc: dict) -> list[float]:
    """Every number of a NEXT.yaml document, in order."""
    out: list[float] = []
    for v in doc.values() if isinstance(doc, dict) else doc:
        if isinstance(v, (dict, list)):
            out += _numbers(v)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(float(v))
    return out


def test_warm_arm_suggestions_answer_what_the_cold_call_answers() -> None:
    """The node's sequence (a call after every capture) starts each call from the previous estimate:
    the same document up to the last rounded digit; a removed view or a reset is answered cold."""
    from pascal_calib_ros.detect.target_detector import detect_target
    from pascal_calib_ros.io.next_yaml import next_document
    from pascal_calib_ros.workflows.suggest import SuggestOptions, WarmArmSuggestions, suggest_for_arm

    target = resolve_target("ring_grid_a4")
    s = simulate_arm_session(target, ArmSpec(mode="eye_in_hand", views=8, width=640, height=480, k1=-0.1, seed=3))
    dets = [detect_target(im, target) for im in s.images[target.name]]
    robot = list(s.robot_poses)
    opt, frames, guide = SuggestOptions(mode="eye_in_hand"), ("base_link", "tool0"), WarmArmSuggestions()
    for n in (5, 6, 7, 8):
        warm = next_document(guide.suggest(dets[:n], robot[:n], target, opt, frames))
        cold = next_document(suggest_for_arm(dets[:n], robot[:n], target, opt, frames))
        assert warm.keys() == cold.keys() and warm["done"] == cold["done"] and warm["views_used"] == n
        assert len(warm["suggestions"]) == len(cold["suggestions"]) > 0
        np.testing.assert_allclose(_numbers(warm), _numbers(cold), rtol=1e-4, atol=2e-6)
    for views in (dets[:7], dets[:8]):  # one view fewer: cold; then the same views again after a reset
        if len(views) == 8:
            guide.reset()
        assert next_document(guide.suggest(views, robot[:len(views)], target, opt, frames)) == \
            next_document(suggest_for_arm(views, robot[:len(views)], target, opt, frames))
    # issue 36: the view at the first suggestion was refused: the next call offers nothing in its
    # neighbourhood (the arm's roll counted), as many suggestions as before, the figures now unchanged
    from pascal_calib_ros.analysis.guide.arm_guidance import DISTINCT_ROLL_DEG
    from pascal_calib_ros.analysis.guide.view_ranking import distinct_from_all
    from pascal_calib_ros.io.next_yaml import placement_of_doc

    before = next_document(suggest_for_arm(dets, robot, target, opt, frames))
    was = placement_of_doc(before["suggestions"][0]["placement"])
    after = next_document(guide.suggest(dets, robot, target, opt, frames, avoid=[was]))
    assert after["avoided"] == [before["suggestions"][0]["placement"]]
    assert len(after["suggestions"]) == len(before["suggestions"])
    assert after["suggestions"][0] != before["suggestions"][0]
    assert distinct_from_all([placement_of_doc(sg["placement"]) for sg in after["suggestions"]], [was],
                             ImageSize(640, 480),
                             DISTINCT_ROLL_DEG).all()
    for key in ("projection_sigma_px", "hand_eye_sigma_deg", "hand_eye_sigma_mm", "done", "views_used"):
        assert after[key] == pytest.approx(before[key], rel=1e-4)


def test_a_refused_newest_image_makes_the_previous_first_suggestion_avoided(
        views: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 36, iteratively: the refused images are listed with the reason; with --previous, a
    refused newest image puts the previous call's first suggestion (and its neighbourhood) out of
    the suggestions, says so, and NEXT.yaml carries it on in ``avoided``."""
    import os
    import shutil

    import cv2

    from pascal_calib_ros.analysis.guide.view_ranking import distinct_from_all
    from pascal_calib_ros.io.next_yaml import placement_of_doc

    folder = tmp_path / "views"
    folder.mkdir()
    for p in views:
        shutil.copy(p, folder / p.name)
    first, second, third = tmp_path / "NEXT1.yaml", tmp_path / "NEXT2.yaml", tmp_path / "NEXT3.yaml"
    assert main(["suggest", "--target", "ring_a4", "-n", "3", "--goal-sigma", "0.01", "-o", str(first),
                 str(folder)]) == 0
    doc1 = yaml.safe_load(first.read_text())
    assert "avoided" not in doc1
    capsys.readouterr()
    refused = folder / "zz_refused.png"  # the view taken at the first suggestion: the detector refuses it
    cv2.imwrite(str(refused), np.full((480, 640), 200, np.uint8))
    newest = max(p.stat().st_mtime for p in folder.iterdir()) + 10
    os.utime(refused, (newest, newest))
    assert main(["suggest", "--target", "ring_a4", "-n", "3", "--goal-sigma", "0.01", "--previous", str(first),
                 "-o", str(second), str(folder)]) == 0
    out = capsys.readouterr().out
    assert "rejected  zz_refused.png  no contrast" in out
    assert "the newest image zz_refused.png was refused (no contrast" in out and "no longer suggested" in out
    assert "avoided (a view there was refused)" in out
    doc2 = yaml.safe_load(second.read_text())
    was = placement_of_doc(doc1["suggestions"][0]["placement"])
    assert doc2["avoided"] == [doc1["suggestions"][0]["placement"]]
    assert doc2["suggestions"] and doc2["views_used"] == doc1["views_used"]
    assert doc2["projection_sigma_px"] == doc1["projection_sigma_px"] and doc2["done"] == doc1["done"]
    assert distinct_from_all([placement_of_doc(s["placement"]) for s in doc2["suggestions"]], [was],
                             ImageSize(640, 480)).all()
    # the next call, its newest image measured: the avoided placement is carried on, nothing added
    os.utime(folder / views[0].name, (newest + 10, newest + 10))
    assert main(["suggest", "--target", "ring_a4", "-n", "3", "--goal-sigma", "0.01", "--previous", str(second),
                 "-o", str(third), str(folder)]) == 0
    assert "the newest image" not in capsys.readouterr().out
    assert yaml.safe_load(third.read_text())["avoided"] == doc2["avoided"]
    # without --previous the refused image changes nothing: the same first suggestion as before
    assert main(["suggest", "--target", "ring_a4", "-n", "3", "--goal-sigma", "0.01", "-o", str(third),
                 str(folder)]) == 0
    assert yaml.safe_load(third.read_text())["suggestions"][0] == doc1["suggestions"][0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("- just a list\n")
    assert main(["suggest", "--target", "ring_a4", "--previous", str(bad), "-o", str(third), str(folder)]) == 2
    assert "--previous" in capsys.readouterr().err
