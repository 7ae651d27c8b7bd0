"""``pascal-calib handeye --bag``: a recorded arm session (rosbag2) instead of POSES.yaml and image
files; still frames, one per rest of the arm, and the input errors."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml

from pascal_calib_ros.cli import main
from pascal_calib_ros.cli.common import EXIT_CALIB, EXIT_INPUT
from pascal_calib_ros.geometry.transform import Transform
from pascal_calib_ros.io.bags import write_arm_bag, write_image_bag
from pascal_calib_ros.io.hand_eye_yaml import read_hand_eye_yaml, write_poses_yaml
from pascal_calib_ros.session.arm_bag import ROBOT_MOVING, SAME_REST, read_arm_bag
from pascal_calib_ros.sim.arm import ArmSession, ArmSpec, hand_eye_errors, simulate_arm_session
from pascal_calib_ros.targets import Target

T0 = 1_700_000_000 * 10**9


def run(*args: str) -> subprocess.CompletedProcess:
    """``pascal-calib`` as a user runs it (as test_cli.run)."""
    exe = shutil.which("pascal-calib", path=str(Path(sys.executable).parent)) or "pascal-calib"
    return subprocess.run([exe, *args], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})


@pytest.fixture(scope="module")
def arm_files(tmp_path_factory: pytest.TempPathFactory, ring_target: Target) -> tuple[ArmSession, Path]:
    """6 rendered views from a camera on the arm (640x480), as image files + POSES.yaml (base
    ``base``, tool ``flange``) and as arm session bags written by ``write_arm_bag``: 3 frames per
    rest at 5 Hz, poses at 10 Hz and at every frame (TransformStamped and PoseStamped)."""
    out = tmp_path_factory.mktemp("arm_bag")
    s = simulate_arm_session(ring_target, ArmSpec(mode="eye_in_hand", views=6, width=640, height=480, k1=-0.1,
                                                  seed=3))
    imgs = out / "imgs"
    imgs.mkdir()
    for name, im in zip(s.names, s.images[ring_target.name], strict=True):
        cv2.imwrite(str(imgs / name), im)
    write_poses_yaml(out / "poses.yaml", "base", "flange", dict(zip(s.names, s.robot_poses, strict=True)))
    files = sorted(imgs.iterdir())
    for kind in ("transform", "pose"):
        write_arm_bag(out / f"bag_{kind}", files, out / "poses.yaml", rate=5.0, hold=0.6, pose_rate=10.0,
                      pose_type=kind)
    return s, out


def test_bag_gives_the_result_of_the_pose_file(arm_files: tuple[ArmSession, Path]) -> None:
    """The same images and poses through a bag and through POSES.yaml: the same calibration, close
    to the ground truth; the frames read, used and skipped are reported."""
    s, d = arm_files
    r = run("handeye", "--target", "ring_a4", "--mode", "eye_in_hand", "-o", str(d / "bag" / "cam.yaml"),
            "--bag", str(d / "bag_transform"))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "18 frame(s) on /image, 36 robot pose(s) on /tool_pose (TransformStamped, base -> flange)" in r.stdout
    assert "frames used: 6 " in r.stdout
    # the first frame of every rest but the first follows a pose sample of the previous rest
    assert "frames skipped: 12: 7 same rest of the arm as a used frame; 5 robot moving" in r.stdout
    assert "--frame-id flange --child-frame-id camera_optical_frame" in r.stdout
    ref = run("handeye", "--target", "ring_a4", "--mode", "eye_in_hand", "-o", str(d / "yaml" / "cam.yaml"),
              "--poses", str(d / "poses.yaml"), str(d / "imgs"))
    assert ref.returncode == 0, ref.stdout + ref.stderr
    doc, X = read_hand_eye_yaml(d / "bag" / "hand_eye.yaml")
    doc_ref, X_ref = read_hand_eye_yaml(d / "yaml" / "hand_eye.yaml")
    assert doc["parent_frame"] == "flange" and doc["target_frame"] == "base" and doc["views_used"] == 6
    for key in ("translation", "rotation", "translation_std_mm", "rotation_std_deg", "target_translation", "rms_px"):
        np.testing.assert_allclose(doc[key], doc_ref[key], rtol=1e-9, atol=1e-12, err_msg=key)
    cam, cam_ref = (yaml.safe_load((d / k / "cam.yaml").read_text()) for k in ("bag", "yaml"))
    np.testing.assert_allclose(cam["camera_matrix"]["data"], cam_ref["camera_matrix"]["data"], rtol=1e-9)
    np.testing.assert_allclose(cam["distortion_coefficients"]["data"], cam_ref["distortion_coefficients"]["data"],
                               rtol=1e-9, atol=1e-12)
    err_mm, err_deg, _, _ = hand_eye_errors(X, s.hand_eye)
    assert err_mm < 1.5 and err_deg < 0.1, (err_mm, err_deg)
    assert hand_eye_errors(X, X_ref)[0] < 1e-6


def test_pose_stamped_bag_frames_and_poses(arm_files: tuple[ArmSession, Path]) -> None:
    """PoseStamped has no child frame: tool0 or --tool-frame; the used frames carry the poses
    of POSES.yaml and decode to the image files."""
    s, d = arm_files
    bag = read_arm_bag(d / "bag_pose")
    assert (bag.frame_id, bag.child_frame_id) == ("base", "tool0") and "--tool-frame" in bag.notes[0]
    assert read_arm_bag(d / "bag_pose", tool_frame="flange").child_frame_id == "flange"
    assert [f.index for f in bag.used] == [1, 5, 8, 11, 14, 17]
    for f, T in zip(bag.used, s.robot_poses, strict=True):
        assert f.pose is not None
        np.testing.assert_allclose(f.pose.matrix, T.matrix, atol=1e-12)
    images = list(bag.images())
    assert len(images) == 6
    assert np.array_equal(images[2][1], cv2.imread(str(d / "imgs" / s.names[2]), cv2.IMREAD_UNCHANGED))


def _write_bag(path: Path, msgs: list[tuple[str, float, Any]]) -> Path:
    """A bag of (topic, seconds after T0, grey image | Transform (PoseStamped) | "transform:" Transform)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore
    from rosbags.typesys.stores.ros2_jazzy import builtin_interfaces__msg__Time as Time
    from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Point as Point
    from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Pose as Pose
    from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__PoseStamped as PoseStamped
    from rosbags.typesys.stores.ros2_jazzy import geometry_msgs__msg__Quaternion as Quaternion
    from rosbags.typesys.stores.ros2_jazzy import sensor_msgs__msg__Image as Image
    from rosbags.typesys.stores.ros2_jazzy import std_msgs__msg__Header as Header

    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9) as writer:
        conns: dict[str, Any] = {}
        for topic, t_s, payload in sorted(msgs, key=lambda m: m[1]):
            ts = T0 + round(t_s * 1e9)
            stamp = Time(sec=ts // 10**9, nanosec=ts % 10**9)
            if isinstance(payload, Transform):
                msgtype = "geometry_msgs/msg/PoseStamped"
                t, q = payload.translation, payload.quat
                msg: Any = PoseStamped(header=Header(stamp=stamp, frame_id="base_link"), pose=Pose(
                    position=Point(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                    orientation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))))
            else:
                msgtype = "sensor_msgs/msg/Image"
                h, w = payload.shape
                msg = Image(header=Header(stamp=stamp, frame_id="camera"), height=h, width=w, encoding="mono8",
                            is_bigendian=0, step=w, data=payload.ravel())
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], ts, store.serialize_cdr(msg, msgtype))
    return path


A = Transform.from_rotvec([0.1, 0.2, 0.3], [0.4, 0.0, 0.5])
B = Transform.from_rotvec([0.3, 0.1, -0.2], [0.5, 0.1, 0.4])


def _image(k: int) -> np.ndarray:
    return np.full((24, 32), 10 * k, np.uint8)


def test_still_frames_one_per_rest_moving_and_unposed_skipped(tmp_path: Path) -> None:
    """Poses every 0.1 s: A until 0.2 s, moving at 0.3 and 0.4 s, B from 0.5 to 0.8 s; frames at
    0.05 ... 0.75 s and one at 0.95 s (no pose sample within 0.1 s)."""
    poses = [(0.1 * k, A) for k in range(3)] + [(0.3, Transform.from_rotvec([0.2, 0.15, 0.0], [0.45, 0.05, 0.45])),
                                                (0.4, Transform.from_rotvec([0.25, 0.1, -0.1], [0.48, 0.08, 0.42]))]
    poses += [(0.1 * k, B) for k in range(5, 9)]
    frames = [0.05 + 0.1 * k for k in range(8)] + [0.95]
    bag = _write_bag(tmp_path / "bag", [("/pose", t, T) for t, T in poses]
                     + [("/image", t, _image(k)) for k, t in enumerate(frames)])
    arm = read_arm_bag(bag)
    why = [f.reason.split(" (")[0] for f in arm.frames]
    assert why == [SAME_REST, "", ROBOT_MOVING, ROBOT_MOVING, ROBOT_MOVING, SAME_REST, "", SAME_REST,
                   "no robot pose"], why
    used = arm.used
    assert used[0].pose is not None and used[1].pose is not None
    np.testing.assert_allclose(used[0].pose.matrix, A.matrix, atol=1e-12)
    np.testing.assert_allclose(used[1].pose.matrix, B.matrix, atol=1e-12)
    assert [int(img[0, 0]) for _, img in arm.images()] == [10, 60]
    text = arm.summary()
    assert "9 frame(s) on /image, 9 robot pose(s) on /pose (PoseStamped, base_link -> tool0)" in text
    assert "frames used: 2 " in text
    assert "frames skipped: 7: 3 same rest of the arm as a used frame; 3 robot moving (e.g. frame_0002@0.20s: " \
           "pose changes by" in text
    assert "1 no robot pose (e.g. frame_0008@0.90s: nearest sample 0.150 s from the image stamp" in text
    # a larger pose_max_age reaches the last sample: the last frame joins the rest at B
    assert read_arm_bag(bag, pose_max_age=0.2).frames[8].reason.startswith(SAME_REST)


def _handeye(capsys: pytest.CaptureFixture[str], tmp_path: Path, *args: str) -> tuple[int, str]:
    rc = main(["handeye", "--target", "ring_a4", "--mode", "eye_in_hand", "-o", str(tmp_path / "c.yaml"), *args])
    return rc, capsys.readouterr().err


def test_bag_input_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Each refusal exits 2 with the reason; nothing is written."""
    two_images = [("/image", 0.0, _image(1)), ("/image", 0.1, _image(2))]
    poses_far = [("/pose", 1.0, A), ("/pose", 1.1, A)]
    far = _write_bag(tmp_path / "far", two_images + poses_far)
    only_poses = _write_bag(tmp_path / "only_poses", poses_far)
    two_pose_topics = _write_bag(tmp_path / "two", [*two_images, *poses_far, ("/pose2", 0.0, A)])
    moving = _write_bag(tmp_path / "moving", [*two_images, ("/pose", 0.0, A), ("/pose", 0.05, B), ("/pose", 0.1, A),
                                              ("/pose", 0.15, B), ("/cam2", 0.0, _image(4))])
    png = tmp_path / "a.png"
    cv2.imwrite(str(png), _image(3))
    no_poses = write_image_bag(tmp_path / "no_poses", [png])
    cases: list[tuple[list[str], str]] = [
        (["--bag", str(tmp_path / "missing")], "bag not found"),
        (["--bag", str(only_poses)], "has no sensor_msgs/Image or CompressedImage topic; topics: /pose "
                                     "(geometry_msgs/msg/PoseStamped)"),
        (["--bag", str(no_poses)], "has no geometry_msgs/PoseStamped or TransformStamped topic (the robot's tool "
                                   "pose); topics: /image (sensor_msgs/msg/Image)"),
        (["--bag", str(far), "--pose-topic", "/image"], "pose topic '/image' is a sensor_msgs/msg/Image, not a "
                                                        "geometry_msgs/PoseStamped or TransformStamped"),
        (["--bag", str(far), "--image-topic", "/pose"], "image topic '/pose' is a geometry_msgs/msg/PoseStamped"),
        (["--bag", str(two_pose_topics)], "has 2 pose topics; choose one with --pose-topic: /pose "
                                          "(geometry_msgs/msg/PoseStamped), /pose2"),
        (["--bag", str(far)], "no frame has a robot pose within pose_max_age 0.1 s of its stamp (e.g. "
                              "frame_0000@0.00s: no robot pose (nearest sample 1.000 s"),
        (["--bag", str(moving)], "has 2 image topics; choose one with --image-topic: /cam2 (sensor_msgs/msg/Image), "
                                 "/image (sensor_msgs/msg/Image)"),
        (["--bag", str(moving), "--image-topic", "/image"], "no still frame with a robot pose"),
        (["--bag", str(far), "--poses", str(tmp_path / "p.yaml")], "give either --bag BAG or --poses"),
        (["--bag", str(far), str(png)], "give either --bag BAG or --poses"),
        ([], "give --poses POSES.yaml and image files or folders, or --bag BAG"),
    ]
    for args, why in cases:
        rc, err = _handeye(capsys, tmp_path, *args)
        assert rc == EXIT_INPUT and why in err, (args, err)
    assert not (tmp_path / "c.yaml").exists()
    # with the topic chosen the two-topic bag is read: its one rest gives one view (too few: exit 1)
    rc, err = _handeye(capsys, tmp_path, "--bag", str(two_pose_topics), "--pose-topic", "/pose2")
    assert rc == EXIT_CALIB and "hand-eye calibration failed" in err, err
