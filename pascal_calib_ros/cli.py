"""``pascal-calib``: offline calibration, synthetic sessions, studies and benchmarks.

Exit codes: 0 success, 1 calibration not possible (too few views, degenerate set), 2 bad input
(arguments, target file, images).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .calibrate.pipeline import METHODS, CalibrationError, CalibrationOptions, CalibrationResult, calibrate
from .calibrate.refine import DISTORTION_MODELS, SHAPE_CHOICES
from .detect.detection import Detection, DetectionParams
from .detect.target_detector import detect_target
from .geometry.camera import rectified_projection
from .geometry.lens import lens_model
from .geometry.transform import Transform
from .io.camera_yaml import CameraInfoData, write_camera_yaml
from .io.images import ImageReadError, expand_image_args, read_grey
from .targets import Target, TargetError, resolve_target
from .workflows.suggest import add_parser as add_suggest_parser

EXIT_OK, EXIT_CALIB, EXIT_INPUT = 0, 1, 2


def _progress(enabled: bool, k: int, n: int, text: str) -> None:
    if enabled:
        sys.stderr.write(f"\r[{k}/{n}] {text[:70]:<70}")
        sys.stderr.flush()
        if k == n:
            sys.stderr.write("\n")


def detect_images(items: Iterable[tuple[str, np.ndarray | str]], n: int, target: Target, params: DetectionParams,
                  progress: bool) -> list[Detection]:
    """Detect ``target`` in (name, grey image or why it cannot be read) items, in order; an image
    whose size differs from the first readable one is rejected."""
    dets: list[Detection] = []
    size: tuple[int, int] | None = None
    for k, (name, img) in enumerate(items, 1):
        _progress(progress, k, n, name)
        if isinstance(img, str):
            dets.append(Detection(0, 0, name=name, reason=img))
            continue
        if size is not None and (img.shape[1], img.shape[0]) != size:
            dets.append(Detection(img.shape[1], img.shape[0], name=name,
                                  reason=f"image size {img.shape[1]}x{img.shape[0]} differs from {size[0]}x{size[1]}"))
            continue
        size = (img.shape[1], img.shape[0])
        dets.append(detect_target(img, target, params, name=name))
    if size is not None:
        for d in dets:
            if d.width == 0:
                d.width, d.height = size
    return dets


def detect_files(paths: list[Path], target_name: str, params: DetectionParams, progress: bool) -> list[Detection]:
    def read() -> Iterator[tuple[str, np.ndarray | str]]:
        for p in paths:
            try:
                yield p.name, read_grey(p)
            except ImageReadError as e:
                yield p.name, str(e)

    return detect_images(read(), len(paths), resolve_target(target_name), params, progress)


def format_summary(res: CalibrationResult) -> str:
    lines = ["views:"]
    for v in res.views:
        if v.used:
            extra = f"edge rms {v.rms:.3f} px, edge offset {v.edge_offset:+.3f} px" if np.isfinite(v.rms) else ""
            lines.append(f"  used      {v.name}  {extra}")
        else:
            lines.append(f"  rejected  {v.name}  {v.reason}")
    K, D, s = res.K, res.D, res.std

    def pm(name: str, value: float) -> str:
        return f"{value:.3f} +- {s[name]:.3f}" if name in s else f"{value:.3f}"

    lines += [
        f"method: {res.method}{' + refinement' if res.refined and res.method != 'zhang' else ''}"
        f"    views used: {res.n_used}/{len(res.views)}",
        f"RMS: {res.rms:.4f} px" + ("  (edge distance)" if res.method != "zhang" else "  (corner reprojection)"),
        f"degeneracy ratio: {res.degeneracy_ratio:.4f}  (>= 0.05 good, < 0.01 rejected)"
        if np.isfinite(res.degeneracy_ratio) else "degeneracy ratio: n/a",
        f"fx = {pm('fx', K[0, 0])}   fy = {pm('fy', K[1, 1])}",
        f"cx = {pm('cx', K[0, 2])}   cy = {pm('cy', K[1, 2])}   skew = {K[0, 1]:.4f}",
        f"D {res.model} ({' '.join(res.camera().lens.coefficients)}) = "
        + "  ".join(pm(n, v) for n, v in zip(res.camera().lens.coefficients, D, strict=True)),
    ]
    if res.shape:
        desc = {"pitch_ratio": ("y/x pitch ratio - 1", 100, "%"), "warp_x": ("warp along x", 1000, "mm"),
                "warp_y": ("warp along y", 1000, "mm")}
        parts = []
        for n, value in res.shape.items():
            if n in res.shape_std:
                label, scale, unit = desc[n]
                parts.append(f"{label} {scale * value:+.4f} +- {scale * res.shape_std[n]:.4f} {unit}")
        lines.append("target shape: " + "; ".join(parts))
        lines.append("  against a flat nominal sheet: " + "  ".join(
            f"{k} {res.shape_effect[k]:+.3f}" for k in ("fx", "fy", "cx", "cy"))
            + f"  (edge RMS {res.shape_effect['rms_flat']:.4f} -> {res.rms:.4f} px)")
    if len(res.circle_names) > 2 and res.edge_circles:
        from .io.report import per_circle_rms

        worst = list(per_circle_rms(res).items())[:3]
        lines.append("worst circles (edge RMS over all views): " + ", ".join(f"{k} {v:.3f} px" for k, v in worst))
    lines += [f"warning: {w}" for w in res.warnings]
    return "\n".join(lines)


def _write_report(res: CalibrationResult, dets: list[Detection], out_dir: str, paths: list[Path],
                  hand_eye: Any = None) -> None:
    """report.pdf / .png / .json (io/report.py), the worst views drawn on their own images; with a
    hand-eye result its page and numbers too."""
    from .io.report import write_report

    by_name = {p.name: p for p in paths}
    t0 = time.perf_counter()
    files = write_report(res, dets, out_dir, images=lambda n: read_grey(by_name[n]) if n in by_name else None,
                         hand_eye=hand_eye)
    print(f"wrote {files.pdf}, {files.png} and {files.json} ({time.perf_counter() - t0:.1f} s)")


def _target_or_none(name: str) -> Target | None:
    """The target, or None after printing why it cannot be loaded."""
    try:
        return resolve_target(name)
    except TargetError as e:
        print(f"error: {e}", file=sys.stderr)
        return None


def cmd_calibrate(args: argparse.Namespace) -> int:
    target = _target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    method = args.method or target.default_method()
    if not args.method:
        print(f"method: {method} (default for target {target.name})")
    paths = expand_image_args(args.images)
    if not paths:
        print("error: no images given", file=sys.stderr)
        return EXIT_INPUT
    params = DetectionParams.for_lens(lens_model(args.distortion).wide, gamma=args.gamma, max_blur=args.max_blur)
    t0 = time.perf_counter()
    dets = detect_files(paths, args.target, params, progress=sys.stderr.isatty())
    t_detect = time.perf_counter() - t0
    opts = CalibrationOptions(method=method, refine=not args.no_refine, distortion=args.distortion,
                              zero_skew=not args.skew, edge_offsets=not args.no_edge_offset,
                              min_views=args.min_views, target_shape=SHAPE_CHOICES[args.target_shape or ""])
    t1 = time.perf_counter()
    try:
        res = calibrate(dets, target, opts)
    except CalibrationError as e:
        for d in dets:
            if not d.ok:
                print(f"  rejected  {d.name}  {d.reason}")
        print(f"error: calibration failed: {e}", file=sys.stderr)
        print("no calibration written", file=sys.stderr)
        return EXIT_CALIB
    t_cal = time.perf_counter() - t1
    print(format_summary(res))
    print(res.projection_line())
    print(f"time: detection {t_detect:.2f} s ({len(paths)} images), calibration {t_cal:.2f} s")
    info = CameraInfoData(res.width, res.height, args.camera_name, res.K, res.D, res.model,
                          P=rectified_projection(res.camera()))
    out = write_camera_yaml(args.output, info)
    print(f"wrote {out}")
    if args.report:
        _write_report(res, dets, args.report, paths)
    if args.cross_validate:
        # two interleaved halves against their projection uncertainty (calibrate/cross_validation.py); a
        # disagreement or a refusal is a WARNING, not a failure: the calibration is written either way
        from .calibrate.cross_validation import cross_validate

        try:
            cv = cross_validate(dets, target, opts)
        except CalibrationError as e:
            print(f"WARNING: cross-validation not possible: {e}")
        else:
            print(cv.summary_line())
            print(("" if cv.agree else "WARNING: ") + cv.message)
    return EXIT_OK


def _handeye_bag_input(args: argparse.Namespace, target: Target, params: DetectionParams
                       ) -> tuple[str, str, list[Detection], list[Transform | None]] | None:
    """(base frame, tool frame, detections, robot poses) of the still frames of an arm session
    bag (:mod:`.io.arm_bag`), or None after printing why not."""
    from .io.arm_bag import read_arm_bag
    from .io.bags import BagError

    try:
        bag = read_arm_bag(args.bag, args.image_topic, args.pose_topic, args.pose_max_age, args.tool_frame)
        print(bag.summary())
        if not bag.used:
            print(f"error: no still frame with a robot pose in {args.bag} (the robot pose changes by more than "
                  "1e-6 m or 1e-6 rad around every frame)", file=sys.stderr)
            return None
        frames = [(f.name, img) for f, img in bag.images()]  # only the used frames are decoded
    except BagError as e:
        print(f"error: {e}", file=sys.stderr)
        return None
    dets = detect_images(frames, len(frames), target, params, progress=sys.stderr.isatty())
    return bag.frame_id, bag.child_frame_id, dets, [f.pose for f in bag.used]


def cmd_handeye(args: argparse.Namespace) -> int:
    """Joint intrinsic + hand-eye calibration from images and POSES.yaml, or from an arm session bag."""
    from .calibrate.handeye import HandEyeError, HandEyeOptions, calibrate_hand_eye
    from .io.hand_eye_yaml import PosesYamlError, read_poses_yaml, write_hand_eye_yaml

    target = _target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    params = DetectionParams.for_lens(lens_model(args.distortion).wide, gamma=args.gamma, max_blur=args.max_blur)
    he = HandEyeOptions(args.mode, args.robot_sigma_mm, args.robot_sigma_deg, not args.fixed_robot_sigma,
                        arm_accuracy_mm=args.arm_accuracy_mm, arm_accuracy_length=args.arm_accuracy_length)
    if he.arm_accuracy_problem():  # before any work
        print(f"error: --arm-accuracy-mm / --arm-accuracy-length: {he.arm_accuracy_problem()}", file=sys.stderr)
        return EXIT_INPUT
    if args.bag and (args.poses or args.images):
        print("error: give either --bag BAG or --poses POSES.yaml IMAGES..., not both", file=sys.stderr)
        return EXIT_INPUT
    if args.bag:
        loaded = _handeye_bag_input(args, target, params)
        if loaded is None:
            return EXIT_INPUT
        frame_id, child_id, dets, robot = loaded
        pose_source = Path(args.bag).name
        paths: list[Path] = []  # no image files: the report draws no view images
    else:
        if not args.poses or not args.images:
            print("error: give --poses POSES.yaml and image files or folders, or --bag BAG", file=sys.stderr)
            return EXIT_INPUT
        try:
            frame_id, child_id, poses = read_poses_yaml(args.poses)
        except PosesYamlError as e:
            print(f"error: {e}", file=sys.stderr)
            return EXIT_INPUT
        paths = expand_image_args(args.images)
        if not paths:
            print("error: no images given", file=sys.stderr)
            return EXIT_INPUT
        missing = [p.name for p in paths if p.name not in poses]
        if len(missing) == len(paths):
            print(f"error: no image has a pose in {args.poses} (images are matched by file name, e.g. "
                  f"{paths[0].name})", file=sys.stderr)
            return EXIT_INPUT
        dets = detect_files(paths, args.target, params, progress=sys.stderr.isatty())
        robot = [poses.get(p.name) for p in paths]
        pose_source = Path(args.poses).name
    opts = CalibrationOptions(method=args.method or "", distortion=args.distortion, zero_skew=not args.skew)
    t0 = time.perf_counter()
    try:
        res = calibrate_hand_eye(dets, robot, target, args.mode, opts, he)
    except (HandEyeError, CalibrationError) as e:
        for d, r in zip(dets, robot, strict=True):
            if r is None:
                print(f"  rejected  {d.name}  no pose in {pose_source}")
            elif not d.ok:
                print(f"  rejected  {d.name}  {d.reason}")
        print(f"error: hand-eye calibration failed: {e}", file=sys.stderr)
        print("no calibration written", file=sys.stderr)
        return EXIT_CALIB
    print(format_summary(res.calibration))
    print(res.summary())
    print(f"time: calibration {time.perf_counter() - t0:.2f} s")
    cal = res.calibration
    info = CameraInfoData(cal.width, cal.height, args.camera_name, cal.K, cal.D, cal.model,
                          P=rectified_projection(cal.camera()))
    out = write_camera_yaml(args.output, info)
    print(f"wrote {out}")
    parent = child_id if args.mode == "eye_in_hand" else frame_id
    target_frame = frame_id if args.mode == "eye_in_hand" else child_id
    he_out = Path(args.hand_eye_out) if args.hand_eye_out else Path(args.output).parent / "hand_eye.yaml"
    write_hand_eye_yaml(he_out, res, parent, args.camera_frame, target_frame)
    print(f"wrote {he_out}")
    t, q = res.hand_eye.translation, res.hand_eye.quat
    print("publish it with:\n  ros2 run tf2_ros static_transform_publisher "
          f"--x {t[0]:.6f} --y {t[1]:.6f} --z {t[2]:.6f} --qx {q[0]:.7f} --qy {q[1]:.7f} --qz {q[2]:.7f} "
          f"--qw {q[3]:.7f} --frame-id {parent} --child-frame-id {args.camera_frame}")
    if args.report:
        _write_report(cal, dets, args.report, paths, hand_eye=res)
    return EXIT_OK


def cmd_render(args: argparse.Namespace) -> int:
    from .sim.session import SessionSpec, render_session

    target = _target_or_none(args.target)
    if target is None:
        return EXIT_INPUT
    w, h = (int(v) for v in args.size.lower().split("x"))
    spec = SessionSpec(width=w, height=h, focal=args.focal, k1=args.k1, views=args.views, blur=args.blur,
                       gamma=args.gamma, noise=args.noise, jpeg=args.jpeg, seed=args.seed,
                       cut_views=args.cut_views, empty_views=args.empty_views, defocused_views=args.defocused_views,
                       size_range=(args.min_size, args.max_size), pitch_ratio=args.pitch_ratio,
                       warp_x=args.warp_x / 1000, warp_y=args.warp_y / 1000, lens=args.lens,
                       dist=tuple(float(v) for v in args.dist.split(",")) if args.dist else (),
                       pixel_range=(0.05, 0.95) if args.lens == "equidistant" else (0.2, 0.8))
    paths = render_session(target, spec, Path(args.out), progress=sys.stderr.isatty())
    print(f"wrote {len(paths)} images and ground truth to {args.out}")
    return EXIT_OK


def cmd_bench(args: argparse.Namespace) -> int:
    from .sim.bench import run_bench

    result: dict[str, Any] = dict(run_bench(quick=args.quick, print_table=not args.json))
    if args.json:
        print(json.dumps(result))
    return EXIT_OK


def cmd_study(args: argparse.Namespace) -> int:
    if args.name == "guided":
        from .studies.guided_study import run_guided_study

        run_guided_study(Path(args.out), seeds=args.seeds, quick=args.quick, only=args.only, jobs=args.jobs)
        return EXIT_OK
    if args.name == "handeye":
        from .sim.handeye_study import run_handeye_study

        run_handeye_study(Path(args.out), views=args.views or 20, seed=args.seed, opencv4_python=args.opencv4_python,
                          targets=tuple(args.targets.split(",")), systematic_mm=args.arm_systematic_mm)
        return EXIT_OK
    if args.name == "trust":
        from .sim.trust_study import trust

        trust(Path(args.out), draws=args.draws, views=args.views or 12, only=args.only)
        return EXIT_OK
    if args.name == "model-bias":
        from .sim.model_bias_study import model_bias_study

        model_bias_study(Path(args.out), views=args.views or 12)
        return EXIT_OK
    from .sim.study import run_study

    run_study(args.name, Path(args.out), views=args.views, seed=args.seed)
    return EXIT_OK


def cmd_bag(args: argparse.Namespace) -> int:
    from .io.bags import BagError, write_arm_bag, write_image_bag

    paths = expand_image_args(args.images)
    if not paths:
        print("error: no images given", file=sys.stderr)
        return EXIT_INPUT
    kind = "CompressedImage" if args.compressed else "Image"
    try:
        if args.poses:
            out = write_arm_bag(args.out, paths, args.poses, args.topic, args.pose_topic, args.storage,
                                args.compressed, args.rate, args.hold, args.pose_rate, args.frame_id,
                                args.pose_type)
            pose_kind = "PoseStamped" if args.pose_type == "pose" else "TransformStamped"
            print(f"wrote an arm session of {len(paths)} pose(s) to {out} ({args.storage}): sensor_msgs/{kind} on "
                  f"{args.topic} ({args.rate:g} Hz, {args.hold:g} s per pose), geometry_msgs/{pose_kind} on "
                  f"{args.pose_topic} ({args.pose_rate:g} Hz and at every frame)")
            return EXIT_OK
        out = write_image_bag(args.out, paths, args.topic, args.storage, args.compressed, args.rate, args.frame_id)
    except (BagError, ImageReadError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_INPUT
    print(f"wrote {len(paths)} sensor_msgs/{kind} on {args.topic} to {out} ({args.storage})")
    return EXIT_OK


def cmd_experiment(args: argparse.Namespace) -> int:
    from .sim.experiments import run_experiment

    run_experiment(args.name, Path(args.out), args.trials, args.seed)
    return EXIT_OK


def cmd_target(args: argparse.Namespace) -> int:
    from .io.printable import write_printable

    try:
        target = resolve_target(args.target)
        out = write_printable(target, args.output)
    except (TargetError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_INPUT
    print(f"wrote {out} ({1000 * target.sheet[0]:g} x {1000 * target.sheet[1]:g} mm; print at 100 %)")
    return EXIT_OK


def cmd_diff(args: argparse.Namespace) -> int:
    """Projection difference of calibration B against A after the implied rotation (mrcal's
    projection_diff; :mod:`.calibrate.compare`), over the image or a report's observed field."""
    from .calibrate.compare import camera_from_yaml, projection_difference, region_from_report
    from .errors import PascalCalibError

    try:
        a, b = camera_from_yaml(args.a), camera_from_yaml(args.b)
        mask = None if args.region == "image" else region_from_report(args.region).mask
        res = projection_difference(a, b, mask, args.distance, args.step)
    except PascalCalibError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_INPUT
    print(res.summary())
    if res.n_excluded:
        print(f"note: {res.n_excluded} grid point(s) left out (beyond the range of one of the models)", file=sys.stderr)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        img, extent = res.image()
        fig, ax = plt.subplots(figsize=(8.0, 6.0 * a.height / a.width + 1.2))
        im = ax.imshow(img, extent=extent, origin="upper", interpolation="nearest", cmap="viridis")
        if mask is not None:
            ax.contour(mask.astype(np.uint8), levels=[0.5], colors="red", linewidths=1.0)
        ax.set_xlim(0, a.width)
        ax.set_ylim(a.height, 0)
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")
        rng = "infinity" if args.distance is None else f"{args.distance:g} m"
        where = "image" if mask is None else f"{Path(args.region).name} (red outline)"
        ax.set_title(f"{Path(args.b).name} against {Path(args.a).name}, range {rng}, region {where}\n"
                     f"{res.summary()}", fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.9, label="projection difference (px)")
        fig.tight_layout()
        try:
            Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(args.plot, dpi=100)
        except (OSError, ValueError) as e:  # unwritable path, unknown image format
            print(f"error: cannot write {args.plot}: {e}", file=sys.stderr)
            return EXIT_INPUT
        finally:
            plt.close(fig)
        print(f"wrote {args.plot}")
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="pascal-calib", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)

    c = sub.add_parser("calibrate", help="calibrate from image files; writes camera_calibration_parsers YAML")
    c.add_argument("--target", required=True, help="target YAML file or packaged name (ring_a4, pascal_board_a3)")
    c.add_argument("--method", choices=METHODS, help="default: the target's natural method (ring for a ring)")
    c.add_argument("--camera-name", default="camera")
    c.add_argument("-o", "--output", required=True, help="output YAML path")
    c.add_argument("--distortion", default="plumb_bob", choices=sorted(DISTORTION_MODELS))
    c.add_argument("--no-refine", action="store_true", help="closed form only (no distortion)")
    c.add_argument("--no-edge-offset", action="store_true", help="do not estimate the per-view edge offset")
    c.add_argument("--skew", action="store_true", help="estimate skew (default: zero skew)")
    c.add_argument("--gamma", type=float, default=1.0, help="linearise with this display gamma before edges")
    c.add_argument("--max-blur", type=float, default=4.0, help="reject views whose edges are wider (px)")
    c.add_argument("--min-views", type=int, default=3)
    c.add_argument("--target-shape", nargs="?", const="warp", choices=[k for k in SHAPE_CHOICES if k],
                   help="also estimate the printed sheet's shape (grids, checkerboards): warp (parabolic "
                        "out-of-plane bend; the default), pitch (y/x scale ratio) or all")
    c.add_argument("--report", metavar="DIR", help="write report.pdf (7 pages), report.png and report.json into DIR")
    c.add_argument("--cross-validate", action="store_true",
                   help="also calibrate two interleaved halves of the views and compare them against their "
                        "projection uncertainty (a model error shows as a larger difference; needs 2 x --min-views "
                        "usable views)")
    c.add_argument("images", nargs="+", help="image files or folders")
    c.set_defaults(func=cmd_calibrate)

    h = sub.add_parser("handeye", help="intrinsics + hand-eye transform from images and robot poses (POSES.yaml), "
                                       "or from a recorded arm session (rosbag2)")
    h.add_argument("--target", required=True, help="target YAML file or packaged name")
    h.add_argument("--poses", help="POSES.yaml: the tool pose in the base frame per image")
    h.add_argument("--bag", help="instead of --poses and images: a rosbag2 arm session (images and the tool pose "
                                 "as PoseStamped or TransformStamped); one still frame per rest of the arm is used")
    h.add_argument("--image-topic", default="", help="with --bag: the image topic (default: the only one)")
    h.add_argument("--pose-topic", default="", help="with --bag: the tool pose topic (default: the only one)")
    h.add_argument("--pose-max-age", type=float, default=0.1,
                   help="with --bag: a frame's pose is interpolated from samples at most this many seconds away")
    h.add_argument("--tool-frame", default="", help="with --bag: the tool frame of PoseStamped poses (default tool0)")
    h.add_argument("--mode", required=True, choices=("eye_in_hand", "eye_to_hand"))
    h.add_argument("-o", "--output", required=True, help="camera YAML path")
    h.add_argument("--hand-eye-out", default="", help="HAND_EYE.yaml path (default: hand_eye.yaml beside -o)")
    h.add_argument("--camera-frame", default="camera_optical_frame")
    h.add_argument("--camera-name", default="camera")
    h.add_argument("--method", choices=METHODS, help="default: the target's natural method")
    h.add_argument("--distortion", default="plumb_bob", choices=sorted(DISTORTION_MODELS))
    h.add_argument("--skew", action="store_true", help="estimate skew (default: zero skew)")
    h.add_argument("--gamma", type=float, default=1.0, help="linearise with this display gamma before edges")
    h.add_argument("--max-blur", type=float, default=4.0, help="reject views whose edges are wider (px)")
    h.add_argument("--robot-sigma-mm", type=float, default=0.1, help="the arm's pose accuracy per axis (start)")
    h.add_argument("--robot-sigma-deg", type=float, default=0.01)
    h.add_argument("--fixed-robot-sigma", action="store_true", help="do not estimate the arm's accuracy")
    h.add_argument("--arm-accuracy-mm", type=float, default=0.2,
                   help="the arm's systematic position error per axis over the workspace (absolute accuracy), which "
                        "no session can measure; its share is added to sigma(X) (0: left out)")
    h.add_argument("--arm-accuracy-length", type=float, default=0.3, help="metres over which that error changes")
    h.add_argument("--report", metavar="DIR", help="write report.pdf (8 pages: the camera's 7 and the hand-eye "
                                                    "page), report.png and report.json into DIR")
    h.add_argument("images", nargs="*", help="image files or folders (with --poses)")
    h.set_defaults(func=cmd_handeye)

    df = sub.add_parser("diff", help="projection difference between two calibrations of one camera (after the "
                                     "implied rotation, as mrcal-show-projection-diff)")
    df.add_argument("a", metavar="A.yaml", help="camera_calibration_parsers YAML (the reference)")
    df.add_argument("b", metavar="B.yaml", help="camera_calibration_parsers YAML compared against A")
    df.add_argument("--region", default="image", metavar="image|REPORT_JSON",
                    help="grid over the whole image (default) or over the observed field of a calibration "
                         "report.json (coverage.view_hulls)")
    df.add_argument("--distance", type=float, default=None, metavar="M",
                    help="range of the compared points in metres (default: infinity, rotation-only fit; "
                         "finite: rotation and translation are fitted)")
    df.add_argument("--step", type=float, default=16.0, metavar="PX", help="grid spacing in pixels")
    df.add_argument("--plot", metavar="OUT.png", help="write a heat map of the difference over the image")
    df.set_defaults(func=cmd_diff)

    r = sub.add_parser("render", help="render a synthetic session with ground truth")
    r.add_argument("--target", default="ring_a4")
    r.add_argument("--out", required=True)
    r.add_argument("--size", default="800x600")
    r.add_argument("--focal", type=float, default=0.0, help="px (default: image width)")
    r.add_argument("--k1", type=float, default=0.0)
    r.add_argument("--lens", default="plumb_bob", choices=("plumb_bob", "rational_polynomial", "equidistant"),
                   help="lens model of the rendered camera (with --dist)")
    r.add_argument("--dist", default="", help="its coefficients, comma-separated, in ROS order (e.g. fisheye: "
                   "--lens equidistant --focal 300 --dist 0.02,-0.005,0.001,-0.0002)")
    r.add_argument("--views", type=int, default=12)
    r.add_argument("--blur", type=float, default=1.0)
    r.add_argument("--gamma", type=float, default=2.2)
    r.add_argument("--noise", type=float, default=1.5)
    r.add_argument("--jpeg", type=int, default=0, help="JPEG quality (0: PNG)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--cut-views", type=int, default=0, help="extra views with the target cut by the frame")
    r.add_argument("--empty-views", type=int, default=0, help="extra views without any target")
    r.add_argument("--defocused-views", type=int, default=0, help="extra strongly defocused views")
    r.add_argument("--min-size", type=float, default=0.3, help="smallest target extent, fraction of the width")
    r.add_argument("--max-size", type=float, default=0.6, help="largest target extent, fraction of the width")
    r.add_argument("--pitch-ratio", type=float, default=0.0, help="print the sheet's y this much longer (0.003)")
    r.add_argument("--warp-x", type=float, default=0.0, help="bend the sheet along x by this many mm")
    r.add_argument("--warp-y", type=float, default=0.0, help="bend the sheet along y by this many mm")
    r.set_defaults(func=cmd_render)

    g = sub.add_parser("bag", help="write a folder of images into a rosbag2 bag (record once, calibrate later)")
    g.add_argument("--out", required=True, help="new bag folder")
    g.add_argument("--topic", default="/image")
    g.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3")
    g.add_argument("--compressed", action="store_true", help="store the files' bytes as CompressedImage")
    g.add_argument("--rate", type=float, default=2.0, help="message rate for the recorded timestamps (Hz)")
    g.add_argument("--frame-id", default="camera")
    g.add_argument("--poses", help="POSES.yaml: an arm session; each image is shown for --hold s at --rate Hz "
                                   "with its tool pose published at --pose-rate Hz and at every frame")
    g.add_argument("--pose-topic", default="/tool_pose")
    g.add_argument("--pose-type", choices=["pose", "transform"], default="pose",
                   help="geometry_msgs/PoseStamped or TransformStamped")
    g.add_argument("--hold", type=float, default=1.0, help="with --poses: seconds the arm rests at each pose")
    g.add_argument("--pose-rate", type=float, default=20.0, help="with --poses: pose messages per second")
    g.add_argument("images", nargs="+")
    g.set_defaults(func=cmd_bag)

    b = sub.add_parser("bench", help="timings: detection of every shipped target at 800x600, 1920x1080 and "
                                     "2456x2058 (and vs cv2.Canny), calibration vs view count")
    b.add_argument("--json", action="store_true")
    b.add_argument("--quick", action="store_true", help="fewer repetitions")
    b.set_defaults(func=cmd_bench)

    t = sub.add_parser("target", help="printable target at exact scale (.pdf, .svg, .png)")
    t.add_argument("--target", required=True)
    t.add_argument("-o", "--output", required=True)
    t.set_defaults(func=cmd_target)

    e = sub.add_parser("experiment", help="the seed paper's experiments: CSV + PNG + table")
    e.add_argument("name", choices=["layouts", "methods", "literal", "board", "reconstruct"])
    e.add_argument("--out", default="out/experiments")
    e.add_argument("--trials", type=int, default=None,
                   help="default: 50 (simulations), 3 sessions (board, reconstruct)")
    e.add_argument("--seed", type=int, default=0)
    e.set_defaults(func=cmd_experiment)

    s = sub.add_parser("study", help="accuracy studies against ground truth (see README)")
    s.add_argument("name", choices=["accuracy", "edge-bias", "grids", "target-shape", "lenses", "handeye", "trust",
                                        "model-bias", "guided"])
    s.add_argument("--seeds", type=int, default=20, help="guided: sessions per case and strategy")
    s.add_argument("--quick", action="store_true", help="guided: 640x480 renders")
    s.add_argument("--jobs", type=int, default=2, help="guided: sessions run in parallel")
    s.add_argument("--draws", type=int, default=10, help="trust: noise draws and new sessions per scenario")
    s.add_argument("--only", default="", help="trust: only the scenarios whose name contains this text")
    s.add_argument("--opencv4-python", default="", help="handeye: a Python with OpenCV 4.x for calibrateHandEye")
    s.add_argument("--targets", default="ring_a4,checkerboard_a4", help="handeye: targets, comma-separated")
    s.add_argument("--arm-systematic-mm", type=float, default=0.25,
                   help="handeye: amplitude of the arm's systematic position error field (0: random arm noise only)")
    s.add_argument("--out", default="out/study")
    s.add_argument("--views", type=int, default=None, help="default: 15 (lenses: 20 per lens)")
    s.add_argument("--seed", type=int, default=1)
    s.set_defaults(func=cmd_study)

    add_suggest_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if getattr(args, "min_views", 3) < 3:
        print("error: --min-views must be at least 3", file=sys.stderr)
        return EXIT_INPUT
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
