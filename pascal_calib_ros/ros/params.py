"""The calibration node's parameters: the one table they are declared from (name, default, description,
choices, range), their checks against each other and the target, and the Markdown table of
``docs/nodes.md`` (``python -m pascal_calib_ros.ros.params``)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from ..calibrate import DISTORTION_MODELS, METHODS, SHAPE_CHOICES
from ..errors import PascalCalibError
from ..targets import TargetError, resolve_target


class ParameterError(PascalCalibError):
    """A node parameter that cannot work (refused at start, exit code 2, or at run time)."""


@dataclass(frozen=True)
class Param:
    name: str
    default: Any
    description: str
    choices: tuple[str, ...] = ()
    int_range: tuple[int, int] | None = None
    float_range: tuple[float, float] | None = None
    modes: tuple[str, ...] = ("mono", "stereo")  # the node modes that declare it


MONO = ("mono",)
STEREO = ("stereo",)


# The one declaration table of the node's parameters.
PARAMS = (
    Param('mode', 'mono',
          '`mono`: one camera on `image`; `stereo`: a stereo pair on `left/image` and `right/image`, calibrated '
          'jointly (both intrinsics and the rig transform; see Stereo mode)', choices=('mono', 'stereo')),
    Param('target', 'ring_a4',
          'target YAML path or packaged target name (ring_a4, pascal_board_a3, ...)',),
    Param('method', '',
          "`ring`, `pt2`, `pt1`, `huang`, `grid`, `zhang`; empty: the target's natural method (`grid` for grid "
          'targets)', choices=('', *METHODS)),
    Param('min_views', 8,
          'views needed before calibrating (>= 3); stereo: shots both cameras see', int_range=(3, 1000)),
    Param('max_views', 40,
          'views kept at most (bounded memory); stereo: shots', int_range=(3, 1000)),
    Param('camera_name', 'camera',
          'camera_name written to the YAML and CameraInfo consumers; stereo: `NAME/left` and `NAME/right` (as '
          "`camera_calibration`'s stereo files)",),
    Param('output_dir', '',
          'where results go: each successful `~/calibrate` writes one result set, `results/<id>/` (the YAML, '
          '`<camera_name>.calibration.json`, `hand_eye.yaml`; with `output_dir` set also the '
          'report, see Calibration report), published at once by pointing `current` at it; `<camera_name>.yaml` '
          'and `hand_eye.yaml` in the folder are links through `current` (a kill never leaves a mixed set); '
          'stereo: `left/<shot>.png` and `right/<shot>.png` (the input of `pascal-calib stereo`), `left.yaml`, '
          '`right.yaml`, `stereo.yaml`, `left.calibration.json`, `right.calibration.json` and `report/`; default '
          "`~/.ros/pascal_calib/<camera_name>/` (nothing is written to the driver's `~/.ros/camera_info/` but "
          'through `~/commit`); `~` is expanded',),
    Param('calibration_file', '',
          'also copy each new camera YAML (and its `.calibration.json`) to this path (`~` is expanded); '
          '`~/verify` reads it when the session has no result yet; default: `<output_dir>/<camera_name>.yaml`',
          modes=MONO),
    Param('record_session', 'auto',
          'write every stored view as it is taken (the frame, its stamp and robot pose, and a manifest; see '
          'Sessions; stereo: both frames of a shot and their stamps) into `session_dir`: `auto` with '
          '`collect:=on_capture` or `output_dir` (stereo: `output_dir`), `always`, `never`',
          choices=('auto', 'always', 'never')),
    Param('session_dir', '',
          'the session folder; default `<output_dir or ~/.ros/pascal_calib/<camera_name>>/sessions/<time>`, named '
          'in `~/status` (`session_folder`); `~` is expanded'),
    Param('resume', False,
          'continue the views of an existing session folder (`session_dir`, or the newest under the default '
          'sessions folder): they are detected again and stored before the first frame; the folder must have been'
          ' recorded with the same target, camera_name, distortion_model, gamma, hand_eye and robot frames '
          '(stereo: the shots, with the same target, camera_name, distortion_model, gamma, left_frame and '
          'right_frame)'),
    Param('zero_skew', True,
          'estimate K with zero skew',),
    Param('distortion_model', 'plumb_bob',
          '`plumb_bob`, `plumb_bob_k3_fixed`, `radial`, `none`, `rational_polynomial` (8 coefficients), '
          '`equidistant` (fisheye, 4 coefficients); with `equidistant` the detector also accepts circles a fisheye '
          'bends away from ellipses', choices=tuple(DISTORTION_MODELS)),
    Param('target_shape', '',
          "also estimate the printed sheet's shape (grid and checkerboard targets): warp (out-of-plane bend), pitch"
          ' (y/x scale ratio), all; empty: nominal flat sheet', choices=tuple(SHAPE_CHOICES), modes=MONO),
    Param('cross_validate', False,
          '`~/calibrate` also calibrates two interleaved halves of the views and compares them against their '
          'projection uncertainty (see Cross-validation); needs 2 × `min_views` views; not with `hand_eye`',
          modes=MONO),
    Param('gamma', 1.0,
          'linearise intensities with this display gamma before locating edges: 1 for a linear sensor (most '
          "machine-vision drivers' default), about 2.2 for sRGB webcams; matters for thin features (ring grids, see"
          " Trust); as the CLI's `--gamma`", float_range=(0.2, 5.0)),
    Param('auto_calibrate', False,
          'calibrate as soon as the node is ready (and again as views are added)',),
    Param('qos', 'auto',
          '`auto` matches the publisher: reliable for reliable drivers (large frames are not lost), best-effort as '
          'soon as a best-effort publisher is seen (re-checked every second; stereo: per topic); or force '
          '`reliable` / `best_effort`',
          choices=('auto', 'reliable', 'best_effort')),
    Param('transport', 'raw',
          "raw (sensor_msgs/Image on 'image'; stereo: 'left/image', 'right/image') | compressed ('image/compressed'; "
          "stereo: 'left/image/compressed', 'right/image/compressed')", choices=('raw', 'compressed')),
    Param('set_camera_info_service', 'camera/set_camera_info',
          "driver's sensor_msgs/SetCameraInfo service", modes=MONO),
    Param('min_view_distance', 0.08,
          'diversity threshold between stored views (L1 in x, y, size, skew)', float_range=(0.0, 2.0)),
    Param('collect', 'auto',
          '`auto`: store frames that add diversity; `on_capture`: only `~/capture` stores views (robot-arm '
          'sessions)', choices=('auto', 'on_capture'), modes=MONO),
    Param('capture_timeout', 5.0,
          '~/capture waits this many seconds for a still frame', float_range=(0.1, 600.0), modes=MONO),
    Param('max_motion_px', -1.0,
          "a frame is used only if the target's features (circle centres and semi-axes, corners) moved less than "
          'this since the previous examined frame and, with robot poses, the robot did not move (more than 0.1 mm /'
          ' 0.01°) between the two frames; 0: off; -1 (auto): 0.5 px with `robot_pose_topic` or '
          '`collect:=on_capture`, otherwise off (a hand-held board is never still to 0.5 px, and a replayed '
          "folder's frames are different views); moving frames are counted as `rejected: moving`",
          float_range=(-1.0, 1000.0)),
    Param('robot_pose_topic', '',
          'geometry_msgs/PoseStamped or TransformStamped of the tool in the robot base (empty: no robot poses)',
          modes=MONO),
    Param('pose_max_age', 0.1,
          "a view's pose is interpolated (rotation slerp, translation lerp) from the samples around its image stamp"
          ' if both are within this many seconds, else the nearest sample within it; otherwise the view is refused '
          'with "no robot pose"', float_range=(0.001, 10.0), modes=MONO),
    Param('robot_base_frame', 'base_link',
          'the robot base frame (robot poses must be in it)', modes=MONO),
    Param('robot_tool_frame', 'tool0',
          'the robot tool (flange) frame the poses describe', modes=MONO),
    Param('camera_frame', 'camera_optical_frame',
          'child frame of the published hand-eye transform', modes=MONO),
    Param('hand_eye', '',
          '`eye_in_hand` / `eye_to_hand`: `~/calibrate` also solves hand-eye (needs `robot_pose_topic`), publishes '
          '`~/hand_eye` and CameraInfo, writes `hand_eye.yaml` into the result set beside the camera YAML '
          '(`output_dir`), and answers `hand_eye <mode>: <parent> -> '
          '<camera> t=[..] m std=[..] mm (arm accuracy share [..] mm) q=[..] rot_std=[..] deg views_used=N/M rms= '
          'robot_error= yaml=; camera: ...`. Nothing is published if it fails: fewer than 3 views with a pose, '
          'degenerate motions, a solver error, a non-finite result, or σ above 5 mm / 0.5°',
          choices=('', 'eye_in_hand', 'eye_to_hand'), modes=MONO),
    Param('arm_accuracy_mm', 0.2,
          "the arm's systematic position error (absolute accuracy over the session's workspace, per axis) that no "
          'session can measure: its share is added to the hand-eye std; 0: left out', float_range=(0.0, 100.0),
          modes=MONO),
    Param('arm_accuracy_length', 0.3,
          'metres over which that error changes (its correlation length)', float_range=(0.01, 100.0),
          modes=MONO),
    Param('guide', False,
          'guide a person holding the target (see Guided sessions): `~/detections` draws the next suggested view '
          "(the target's outline projected with the current camera), the match score, one hint line and the "
          'projection sigma against `goal_sigma_px`; with `collect:=auto` a view is stored only when the live '
          'target matches the outline (overlap >= 0.85) and is still (`max_motion_px` auto: 2 px); after each stored '
          'view the views are recalibrated and the next views ranked (off the image thread); DONE when the real '
          'worst projection sigma over the image reaches the goal', modes=MONO),
    Param('goal_sigma_px', 0.1,
          'the accuracy asked for: the worst projection sigma over the whole image (px), as `pascal-calib suggest '
          '--goal-sigma`; the guide and `~/suggest` say done when the recalibrated views reach it',
          float_range=(1e-4, 100.0), modes=MONO),
    Param('suggest_count', 5,
          '`~/suggest` and the guide rank this many next views (best first)', int_range=(1, 50), modes=MONO),
    Param('suggest_reach', 0.3,
          "arm suggestions stay within this many metres of a visited tool pose (the package knows no arm's "
          'kinematics), as `pascal-calib suggest --reach`', float_range=(0.001, 10.0), modes=MONO),
    Param('suggest_max_turn', 120.0,
          'arm suggestions turn the tool at most this many degrees from the nearest visited orientation '
          '(`--max-turn`)', float_range=(0.1, 180.0), modes=MONO),
    Param('goal_hand_eye_deg', 0.01,
          'with `hand_eye`: `~/suggest` says done only when also the hand-eye rotation sigma is at most this '
          '(degrees; `--goal-deg`)', float_range=(1e-5, 10.0), modes=MONO),
    Param('goal_hand_eye_mm', 0.1,
          'with `hand_eye`: and the hand-eye translation sigma at most this (mm; `--goal-mm`)',
          float_range=(1e-4, 100.0), modes=MONO),
    Param('sync_slop', 0.02,
          'stereo: a left and a right frame form a shot when their header stamps differ by at most this many '
          'seconds (approximate time, as message_filters; 0: equal stamps, hardware-triggered cameras). Frames '
          'that arrive but never pair are counted and `~/status` says why (e.g. their stamps differ by 0.5 s)',
          float_range=(0.0, 10.0), modes=STEREO),
    Param('left_set_camera_info_service', 'left/set_camera_info',
          "stereo: the left driver's own sensor_msgs/SetCameraInfo service (`~/commit`)", modes=STEREO),
    Param('right_set_camera_info_service', 'right/set_camera_info',
          "stereo: the right driver's own sensor_msgs/SetCameraInfo service (`~/commit`); must differ from the "
          "left's (one service would write both calibrations into one camera's file)", modes=STEREO),
    Param('left_frame', 'left_camera_optical_frame',
          'stereo: the left optical frame, parent of `~/stereo_transform`', modes=STEREO),
    Param('right_frame', 'right_camera_optical_frame',
          'stereo: the right optical frame, child of `~/stereo_transform`', modes=STEREO),
    Param('alpha', 0.0,
          "stereo: rectification's free scaling (OpenCV `stereoRectify`): 0 only valid pixels (camera_calibration's "
          'default) .. 1 every source pixel; sets R and P of both CameraInfos', float_range=(0.0, 1.0), modes=STEREO),
)


READ_ONLY = {"mode", "transport", "robot_pose_topic", "guide", "record_session", "session_dir", "resume",
             "left_set_camera_info_service",
             "right_set_camera_info_service"}
PATHS = {"output_dir", "calibration_file", "session_dir"}  # a leading `~` is expanded when the node reads them


def param_value(node: Any, name: str) -> Any:
    """The value of parameter ``name`` on ``node``; in a path (:data:`PATHS`) ``~`` is expanded."""
    v = node.get_parameter(name).value
    return os.path.expanduser(v) if name in PATHS and isinstance(v, str) else v


def params_for(mode: str) -> tuple[Param, ...]:
    """The parameters a node in ``mode`` declares (an unknown mode: the mono node's, which then refuses it)."""
    mode = mode if mode in ("mono", "stereo") else "mono"
    return tuple(p for p in PARAMS if mode in p.modes)


def validate_parameters(changes: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """Why the parameter ``changes`` cannot work together with the ``current`` values (empty: they
    can): values outside their choices, a method the target lacks, a target shape for a target
    without a grid or checkerboard, max_views < min_views, hand-eye without robot poses, a bad
    stillness threshold, a target that cannot be loaded."""
    values = {**current, **changes}
    problems = []
    table = {p.name: p for p in PARAMS}
    for name, value in changes.items():
        p = table.get(name)
        if p is not None and p.choices and value not in p.choices:
            problems.append(f"{name}={value!r} is not one of {', '.join(repr(c) for c in p.choices)}")
    if values.get("target") is not None:
        try:
            t = resolve_target(str(values["target"]))
            method = values.get("method", "")
            if method and method not in t.methods():
                problems.append(f"method {method!r} does not fit target {t.name} (supports {', '.join(t.methods())})")
            if values.get("target_shape") and not (t.grids or t.boards):
                problems.append(f"target_shape needs a grid or checkerboard target; {t.name} has neither")
        except TargetError as e:
            problems.append(f"target: {e}")
    if int(values.get("max_views", 1000)) < int(values.get("min_views", 3)):
        problems.append(f"max_views {values.get('max_views')} < min_views {values.get('min_views')}")
    if values.get("hand_eye") and not values.get("robot_pose_topic"):
        problems.append(f"hand_eye={values['hand_eye']!r} needs robot poses: set robot_pose_topic")
    motion = changes.get("max_motion_px")
    if motion is not None and float(motion) < 0 and float(motion) != -1.0:
        problems.append(f"max_motion_px={motion}: 0 (off), -1 (auto) or a positive threshold in px")
    return problems + _stereo_problems(changes, values)


def _stereo_problems(changes: dict[str, Any], values: dict[str, Any]) -> list[str]:
    """The stereo mode's own checks: a negative slop, one set_camera_info service or one optical
    frame for both cameras."""
    problems = []
    slop = changes.get("sync_slop")
    if slop is not None and float(slop) < 0:
        problems.append(f"sync_slop={slop}: the largest stamp difference of a pair in seconds, 0 or more "
                        "(0: equal stamps)")
    left, right = values.get("left_set_camera_info_service"), values.get("right_set_camera_info_service")
    if left is not None and left == right:
        problems.append(f"left_set_camera_info_service and right_set_camera_info_service are both {left!r}: each "
                        "camera's driver has its own service (one service would write both calibrations into one "
                        "camera's file)")
    if values.get("left_frame") is not None and values.get("left_frame") == values.get("right_frame"):
        problems.append(f"left_frame and right_frame are both {values['left_frame']!r}: the two optical frames "
                        "differ")
    return problems


def declare_parameters(node: Any, mode: str = "mono") -> None:
    """Declare the parameters of ``mode`` (:func:`params_for`) on ``node`` with their description,
    choices and range (what ``ros2 param describe`` shows); a value outside its range is a
    :class:`ParameterError` naming the parameter and the range."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

    for p in params_for(mode):
        desc = ParameterDescriptor(description=p.description + (f" ({', '.join(p.choices)})" if p.choices else ""),
                                   read_only=p.name in READ_ONLY)
        if p.int_range:
            desc.integer_range = [IntegerRange(from_value=p.int_range[0], to_value=p.int_range[1], step=1)]
        if p.float_range:
            desc.floating_point_range = [FloatingPointRange(from_value=p.float_range[0], to_value=p.float_range[1],
                                                            step=0.0)]
        try:
            node.declare_parameter(p.name, p.default, desc)
        except InvalidParameterValueException as e:
            lo, hi = p.int_range or p.float_range or (None, None)
            raise ParameterError(f"invalid parameter {p.name}: {e}" + (f" (range {lo:g} to {hi:g})"
                                                                       if lo is not None else "")) from None
        except InvalidParameterTypeException as e:
            hint = " (a floating-point number: write 1.0, not 1)" if isinstance(p.default, float) else ""
            raise ParameterError(f"invalid parameter {p.name}: {e}{hint}") from None
