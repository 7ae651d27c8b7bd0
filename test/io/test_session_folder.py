"""A session written as it is taken, read back the same."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.session_folder import (
    SessionFolder,
    SessionFolderError,
    SessionManifest,
    is_session_folder,
)

MANIFEST = SessionManifest("ring_grid_a4", "wrist", "plumb_bob", 2.2, "eye_in_hand", "base_link", "tool0")


def _frame(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 255, (48, 64), dtype=np.uint8)


def test_views_are_read_back_exactly(tmp_path: Path) -> None:
    folder = SessionFolder.create(tmp_path / "s", MANIFEST)
    q = np.array([0.1, -0.2, 0.3, 0.9])
    pose = Transform.from_quat(q / np.linalg.norm(q), [0.4, -0.1, 0.55])
    folder.record("frame_000003", _frame(3), 1_700_000_000_123_456_789, pose)
    folder.record("frame_000007", _frame(7), 1_700_000_001_000_000_000, None)
    back = SessionFolder.open(tmp_path / "s")
    assert is_session_folder(tmp_path / "s")
    assert back.manifest == SessionManifest(**{**MANIFEST.__dict__, "image_size": (64, 48)})
    assert [v.name for v in back.views] == ["frame_000003", "frame_000007"]
    assert back.views[0].stamp_ns == 1_700_000_000_123_456_789 and back.views[1].robot_pose is None
    p = back.views[0].robot_pose
    assert p is not None and np.allclose(p.matrix, pose.matrix, atol=1e-15)
    assert np.array_equal(back.image(back.views[0]), _frame(3))  # lossless


def test_a_frame_never_named_is_not_a_view(tmp_path: Path) -> None:
    """A kill between the frame and session.yaml: the view does not exist; recording it again works."""
    folder = SessionFolder.create(tmp_path / "s", MANIFEST)
    folder.record("frame_000001", _frame(1), 1, None)
    (tmp_path / "s" / "frames" / "frame_000002.png").write_bytes(b"half a png")
    back = SessionFolder.open(tmp_path / "s")
    assert [v.name for v in back.views] == ["frame_000001"]
    back.record("frame_000002", _frame(2), 2, None)
    assert np.array_equal(SessionFolder.open(tmp_path / "s").image(back.views[1]), _frame(2))


def test_an_existing_session_is_not_overwritten_and_cleared_views_are_kept(tmp_path: Path) -> None:
    folder = SessionFolder.create(tmp_path / "s", MANIFEST)
    folder.record("frame_000001", _frame(1), 1, None)
    with pytest.raises(SessionFolderError, match="already holds a session with views"):
        SessionFolder.create(tmp_path / "s", MANIFEST)
    assert folder.clear() == 1 and SessionFolder.open(tmp_path / "s").views == []
    kept = list((tmp_path / "s").glob("cleared-*.session.yaml"))
    assert len(kept) == 1 and yaml.safe_load(kept[0].read_text())["views"][0]["name"] == "frame_000001"


def test_a_target_file_is_copied_and_differences_are_named(tmp_path: Path) -> None:
    t = tmp_path / "board.yaml"
    t.write_text("name: mine\n")
    folder = SessionFolder.create(tmp_path / "s", SessionManifest(str(t)))
    assert Path(folder.target_source()).read_text() == "name: mine\n"
    assert MANIFEST.differences(SessionManifest("ring_a4", "wrist", "plumb_bob", 2.2, "eye_in_hand", "base_link",
                                                "tool0")) == ["target: 'ring_grid_a4' != 'ring_a4'"]


def test_bad_files_say_what_is_wrong(tmp_path: Path) -> None:
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "session.yaml").write_text("format: other\n")
    with pytest.raises(SessionFolderError, match="not a session file"):
        SessionFolder.open(tmp_path / "s")
    (tmp_path / "s" / "session.yaml").write_text(yaml.safe_dump({
        "format": "pascal_calib_session 1", "manifest": {"target": "ring_a4"},
        "views": [{"name": "v", "image": "frames/v.png", "rotation": [0, 0, 0, 5], "translation": [0, 0, 0]}]}))
    with pytest.raises(SessionFolderError, match="view v: bad robot pose"):
        SessionFolder.open(tmp_path / "s")
    with pytest.raises(SessionFolderError, match="cannot read"):
        SessionFolder.open(tmp_path / "missing")


STEREO = SessionManifest("ring_grid_a4", "head", "plumb_bob", 2.2, frame_id="left_optical",
                         child_frame_id="right_optical", cameras=("left", "right"))


def test_shots_of_a_pair_are_read_back_exactly(tmp_path: Path) -> None:
    """A stereo session: each shot's two frames (written before session.yaml names it), its stamps
    and why a camera's view was not used."""
    folder = SessionFolder.create(tmp_path / "s", STEREO)
    folder.record_shot("shot_000000", [_frame(1), _frame(2)], [10, 11])
    folder.record_shot("shot_000003", [_frame(3), _frame(4)], [30, 31], ["", "moving: 3 px"])
    assert (tmp_path / "s" / "frames" / "right" / "shot_000003.png").is_file()
    back = SessionFolder.open(tmp_path / "s")
    assert back.manifest == SessionManifest(**{**STEREO.__dict__, "image_size": (64, 48)})
    assert [(v.name, v.stamps_ns, v.not_used) for v in back.views] == [
        ("shot_000000", (10, 11), ("", "")), ("shot_000003", (30, 31), ("", "moving: 3 px"))]
    for v, seeds in zip(back.views, [(1, 2), (3, 4)], strict=True):
        assert all(np.array_equal(back.image(v, c), _frame(s)) for c, s in enumerate(seeds))  # lossless
    assert back.image(back.views[1]).shape == (48, 64) and back.views[1].stamp_ns == 30  # the first camera's


def test_a_recorded_shot_is_never_overwritten(tmp_path: Path) -> None:
    folder = SessionFolder.create(tmp_path / "s", STEREO)
    folder.record_shot("shot_000001", [_frame(1), _frame(2)], [1, 1])
    with pytest.raises(SessionFolderError, match="already records a view named shot_000001"):
        folder.record_shot("shot_000001", [_frame(5), _frame(6)], [2, 2])
    assert np.array_equal(folder.image(folder.views[0], 1), _frame(2))
    with pytest.raises(SessionFolderError, match="already holds a session with views"):
        SessionFolder.create(tmp_path / "s", STEREO)
    with pytest.raises(SessionFolderError, match="one frame and one stamp for each of its cameras"):
        folder.record_shot("shot_000002", [_frame(5)], [2])
    with pytest.raises(SessionFolderError, match="none recorded"):  # a one-camera session records no shots
        SessionFolder.create(tmp_path / "mono", MANIFEST).record_shot("shot", [_frame(1), _frame(2)], [1, 1])
    assert len(SessionFolder.open(tmp_path / "s").views) == 1


def test_a_pair_recorded_with_other_settings_names_the_differences(tmp_path: Path) -> None:
    SessionFolder.create(tmp_path / "s", STEREO).record_shot("shot_000001", [_frame(1), _frame(2)], [1, 1])
    recorded = SessionFolder.open(tmp_path / "s").manifest
    asked = SessionManifest("ring_grid_a4", "head", "plumb_bob", 1.0, frame_id="left_optical",
                            child_frame_id="cam2", cameras=("left", "right"))
    assert recorded.differences(asked) == ["gamma: 2.2 != 1.0", "child_frame_id: 'right_optical' != 'cam2'"]
    mono = SessionManifest("ring_grid_a4", "head", "plumb_bob", 2.2, frame_id="left_optical",
                           child_frame_id="right_optical")
    assert recorded.differences(mono) == ["cameras: ('left', 'right') != ()"]
    assert yaml.safe_load((tmp_path / "s" / "session.yaml").read_text())["manifest"]["cameras"] == ["left", "right"]
