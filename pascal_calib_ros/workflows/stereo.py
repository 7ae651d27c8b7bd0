"""Stereo pairs and camera rigs, offline or from a node: paired images -> detections -> the joint
calibration (:func:`~..calibrate.rig.calibrate_rig`) -> files and the lines a person reads.

- :func:`pair_files` matches each camera's image files into shots: by file stem when the cameras
  share stems (``left/0001.png`` and ``right/0001.png``), else by the number in the file names
  (``left-0001.png`` and ``right-0001.png``, ROS ``camera_calibration``'s archive), else by sorted
  order when every camera has as many files; the outcome says which.
- :func:`stereo_from_detections` and :func:`rig_from_detections` are what a node calls with its
  paired detections: the calibration, the rectification (pairs), and the files:
  ``left.yaml``, ``right.yaml``, ``stereo.yaml`` (:mod:`..io.stereo_yaml`), or one camera YAML
  per camera and ``rig.yaml``.
- :func:`run_stereo` and :func:`run_rig` add the files' reading and detection (the CLI's
  ``pascal-calib stereo`` and ``pascal-calib rig``).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..analysis import assess_rig, epipolar_rms
from ..calibrate import RigOptions, RigResult, calibrate_rig
from ..detect import Detection, DetectionParams, DetectionRefusal, detect_target
from ..errors import PascalCalibError
from ..geometry import StereoRectification, rectify_pair
from ..io import (
    CalibrationRecord,
    CameraInfoData,
    ImageReadError,
    RigCameraData,
    StereoData,
    camera_info_of,
    pair_camera_infos,
    read_grey,
    sidecar_path,
    static_transform_command,
    write_calibration_json,
    write_camera_yaml,
    write_pair_yamls,
    write_rig_yaml,
    write_stereo_yaml,
)
from ..targets import Target
from .calibration_record import record_of_rig_camera


class PairingError(PascalCalibError):
    """The cameras' image files cannot be matched into shots."""


@dataclass
class Pairing:
    """Each camera's file of each shot (None: that camera has no image of the shot)."""

    shots: list[str]
    paths: list[list[Path | None]]  # [camera][shot]
    how: str
    unmatched: list[str] = field(default_factory=list)  # files left without a partner


def _number(p: Path) -> int | None:
    m = re.findall(r"\d+", p.stem)
    return int(m[-1]) if m else None


def _by_key(groups: list[list[Path]], key: Callable[[Path], object]) -> dict[object, list[Path | None]] | None:
    """Shots keyed by ``key`` of the file names, or None if a key is missing or repeats within a
    camera."""
    shots: dict[object, list[Path | None]] = {}
    for c, paths in enumerate(groups):
        keys = [key(p) for p in paths]
        if None in keys or len(set(keys)) != len(keys):
            return None
        for k, p in zip(keys, paths, strict=True):
            shots.setdefault(k, [None] * len(groups))[c] = p
    return shots


def pair_files(groups: list[list[Path]], names: list[str]) -> Pairing:
    """Match the cameras' files into shots (module docstring); a :class:`PairingError` if no rule
    gives a shot that two cameras share."""
    if any(not g for g in groups):
        empty = [n for n, g in zip(names, groups, strict=True) if not g]
        raise PairingError(f"no images for {', '.join(empty)}")
    rules: list[tuple[str, Callable[[Path], object]]] = [("by file stem", lambda p: p.stem),
                                                         ("by the number in the file names", _number)]
    for how, key in rules:
        shots = _by_key(groups, key)
        if shots is None or not any(sum(p is not None for p in v) >= 2 for v in shots.values()):
            continue
        ordered = sorted(shots, key=str) if how == "by file stem" else sorted(shots, key=lambda k: int(str(k)))
        paths = [[shots[k][c] for k in ordered] for c in range(len(groups))]
        alone = [k for k in ordered if sum(p is not None for p in shots[k]) < 2]
        unmatched = [str(p) for k in alone for p in shots[k] if p is not None]
        names_ = [next(p for p in shots[k] if p is not None).stem for k in ordered]
        return Pairing(names_, paths, how, unmatched)
    if len({len(g) for g in groups}) == 1:
        srt = [sorted(g) for g in groups]
        ordered_paths: list[list[Path | None]] = [list(g) for g in srt]
        return Pairing([p.stem for p in srt[0]], ordered_paths,
                       "by sorted order (the file names share no stem and no number)")
    counts = ", ".join(f"{n} {len(g)}" for n, g in zip(names, groups, strict=True))
    raise PairingError(f"cannot match the images into shots: the file names share no stem and no number, and the "
                       f"cameras have different numbers of images ({counts})")


def detect_shots(pairing: Pairing, target: Target, params: DetectionParams,
                 progress: Callable[[int, int, str], None] | None = None) -> list[list[Detection]]:
    """Every camera's detection of every shot; a rejected detection (with the reason) where the
    camera has no image of the shot, cannot read it, or its size differs from that camera's."""
    out: list[list[Detection]] = []
    total = sum(len(p) for p in pairing.paths)
    k = 0
    for cam_paths in pairing.paths:
        dets: list[Detection] = []
        size: tuple[int, int] | None = None
        for shot, p in zip(pairing.shots, cam_paths, strict=True):
            k += 1
            if progress is not None:
                progress(k, total, shot if p is None else p.name)
            if p is None:
                dets.append(Detection(0, 0, name=shot, reason="no image of this shot",
                                      refusal=DetectionRefusal.MISSING_IMAGE))
                continue
            try:
                img = read_grey(p)
            except ImageReadError as e:
                dets.append(Detection(0, 0, name=shot, reason=str(e), refusal=DetectionRefusal.UNREADABLE_IMAGE))
                continue
            if size is not None and (img.shape[1], img.shape[0]) != size:
                why = f"image size {img.shape[1]}x{img.shape[0]} differs from {size[0]}x{size[1]}"
                dets.append(Detection(img.shape[1], img.shape[0], name=shot, reason=why,
                                      refusal=DetectionRefusal.SIZE_MISMATCH))
                continue
            size = (img.shape[1], img.shape[0])
            dets.append(detect_target(img, target, params, name=shot))
        for d in dets:
            if d.width == 0 and size is not None:
                d.width, d.height = size
        out.append(dets)
    return out


@dataclass(frozen=True)
class StereoOptions:
    rig: RigOptions = field(default_factory=RigOptions)
    alpha: float = 0.0  # rectification: 0 valid pixels only (camera_calibration's default) .. 1 all pixels
    camera_name: str = "narrow_stereo"  # left.yaml / right.yaml hold NAME/left and NAME/right
    left_frame: str = "left_camera_optical_frame"
    right_frame: str = "right_camera_optical_frame"


@dataclass
class StereoOutcome:
    rig: RigResult
    rectification: StereoRectification
    epipolar_rms: float
    stereo: StereoData  # what stereo.yaml holds
    files: list[Path]
    lines: list[str]

    def camera_infos(self) -> tuple[CameraInfoData, CameraInfoData]:
        """The left and right CameraInfo contents (K, D, R = R1 / R2, P = P1 / P2), as written to
        left.yaml and right.yaml: what a node publishes on left/camera_info and right/camera_info."""
        return pair_camera_infos(self.rig.cameras[0].camera(), self.rig.cameras[1].camera(), self.rectification,
                                 self.camera_name)

    @property
    def camera_name(self) -> str:
        """The pair's name (``left.yaml`` holds ``NAME/left``)."""
        return self.stereo.left_name.rsplit("/", 1)[0]

    def write(self, out_dir: str | Path) -> list[Path]:
        """``left.yaml``, ``right.yaml`` and ``stereo.yaml`` (:mod:`..io.stereo_yaml`) and each camera's
        record (``left.calibration.json``, ``right.calibration.json``: :func:`write_rig_records`) in
        ``out_dir``."""
        left, right = self.rig.cameras[0].camera(), self.rig.cameras[1].camera()
        out = Path(out_dir)
        return [*write_pair_yamls(out, left, right, self.rectification, self.camera_name),
                write_stereo_yaml(out / "stereo.yaml", self.stereo),
                *write_rig_records(self.rig, out, [f"{self.camera_name}/{n}" for n in ("left", "right")])]


def _shot_lines(rig: RigResult) -> list[str]:
    lines = []
    for s, name in enumerate(rig.shot_names):
        cams = [n for c, n in enumerate(rig.names) if rig.used[c, s]]
        why = [f"{n}: {rig.reasons[(c, s)]}" for c, n in enumerate(rig.names) if (c, s) in rig.reasons]
        lines.append(f"  {name}: " + (("used by " + ", ".join(cams)) if cams else "not used")
                     + ("; " + "; ".join(why) if why else ""))
    return lines


def stereo_from_detections(dets: list[list[Detection]], target: Target, options: StereoOptions = StereoOptions(),
                           out_dir: str | Path | None = None) -> StereoOutcome:
    """Paired detections (``dets[0]`` left, ``dets[1]`` right, one per shot) -> the joint
    calibration, the rectification and, with ``out_dir``, ``left.yaml``, ``right.yaml``,
    ``stereo.yaml`` there. Raises :class:`~..calibrate.pipeline.CalibrationError` (nothing
    written) when it cannot."""
    if len(dets) != 2:
        raise PairingError(f"a stereo pair has two cameras, got {len(dets)}")
    rig = calibrate_rig(dets, target, ["left", "right"], options.rig, [d.name for d in dets[0]])
    return stereo_outcome(rig, dets, target, options, out_dir)


def stereo_outcome(rig: RigResult, dets: list[list[Detection]], target: Target, options: StereoOptions,
                   out_dir: str | Path | None = None) -> StereoOutcome:
    """A calibrated pair's rectification, epipolar RMS, stereo.yaml data, lines and (with
    ``out_dir``) files (:func:`stereo_from_detections` after the calibration)."""
    left, right = rig.cameras[0].camera(), rig.cameras[1].camera()
    E = rig.extrinsics[1]
    rect = rectify_pair(left, right, E.R, E.translation, options.alpha)
    epi = epipolar_rms(rig, rect, dets, target)
    (sig_r, sig_t), (pose_r, pose_t) = rig.extrinsic_sigma[1], rig.pose_sigma[1]
    sd = StereoData(left_name=f"{options.camera_name}/left", right_name=f"{options.camera_name}/right",
                    left_frame=options.left_frame, right_frame=options.right_frame, width=left.width,
                    height=left.height, rig=E, sigma_rotation_deg=sig_r, sigma_translation_mm=sig_t,
                    pose_sigma_rotation_deg=pose_r, pose_sigma_translation_mm=pose_t, epipolar_rms_px=epi,
                    rectification=rect)
    outcome = StereoOutcome(rig, rect, epi, sd, [], [])
    files = outcome.write(out_dir) if out_dir is not None else []
    sr, st = rig.extrinsic_sigma[1]
    lines = ["shots:", *_shot_lines(rig), *rig.summary_lines(),
             f"X_right = R X_left + T: T = [{', '.join(f'{v:.6f}' for v in E.translation)}] m "
             f"(+- [{', '.join(f'{v:.4f}' for v in st)}] mm), rotation {E.angle_deg():.4f} deg "
             f"(+- [{', '.join(f'{v:.5f}' for v in sr)}] deg about the right camera's axes)",
             f"rectification: {rect.method}; baseline {rect.baseline:.6f} m; right P[0,3] = {rect.P2[0, 3]:.4f}",
             f"epipolar RMS {epi:.4f} px (rows of the same circle tangents / corners in the rectified pair)"]
    if files:
        lines.append("wrote " + ", ".join(str(f) for f in files))
    lines += ["publish the right optical frame with:", "  " + sd.static_transform()]
    outcome.files, outcome.lines = files, lines
    return outcome


def rig_records(rig: RigResult, camera_names: list[str]) -> list[CalibrationRecord]:
    """Each camera of a jointly calibrated rig as a calibrated camera, with its intrinsics'
    covariance from the joint fit (:func:`~.calibration_record.record_of_rig_camera`)."""
    assessed = assess_rig(rig)
    return [record_of_rig_camera(rig, c, assessed[c], cn) for c, cn in enumerate(camera_names)]


def write_rig_records(rig: RigResult, out: Path, camera_names: list[str]) -> list[Path]:
    """``NAME.calibration.json`` beside each camera's ``NAME.yaml`` in ``out`` (NAME the rig's camera
    name): what ``pascal-calib verify`` and ``export`` read (:func:`rig_records`)."""
    return [write_calibration_json(sidecar_path(out / f"{n}.yaml"), rec)
            for n, rec in zip(rig.names, rig_records(rig, camera_names), strict=True)]


@dataclass
class RigOutcome:
    """A rig's joint calibration: each camera as a calibrated camera (its record), the frames its
    transforms are published in, the lines a person reads, the files written."""

    rig: RigResult
    records: list[CalibrationRecord]
    frames: list[str]
    lines: list[str]
    files: list[Path] = field(default_factory=list)

    def camera_infos(self) -> list[CameraInfoData]:
        """Each camera's CameraInfo (monocular: R = I, P as ``pascal-calib calibrate`` writes it)."""
        return [camera_info_of(rec) for rec in self.records]

    def write(self, out_dir: str | Path) -> list[Path]:
        """``NAME.yaml`` and ``NAME.calibration.json`` per camera (both from its record) and
        ``rig.yaml`` (:mod:`..io.stereo_yaml`) in ``out_dir``."""
        out, rig, names = Path(out_dir), self.rig, self.rig.names
        files = [write_camera_yaml(out / f"{n}.yaml", info) for n, info in zip(names, self.camera_infos(), strict=True)]
        cams = [RigCameraData(n, self.frames[c], f"{n}.yaml", rig.pose_in_reference(c), *rig.pose_sigma[c])
                for c, n in enumerate(names)]
        files.append(write_rig_yaml(out / "rig.yaml", cams, int(np.sum(rig.used.any(0)))))
        return files + [write_calibration_json(sidecar_path(out / f"{n}.yaml"), rec)
                        for n, rec in zip(names, self.records, strict=True)]


def rig_from_detections(dets: list[list[Detection]], target: Target, names: list[str], out_dir: str | Path,
                        options: RigOptions = RigOptions(), frames: list[str] | None = None  # noqa: B008 (frozen)
                        ) -> RigOutcome:
    """Detections of N cameras (``dets[c][s]``) -> the joint calibration, written to ``out_dir``
    (:meth:`RigOutcome.write`)."""
    rig = calibrate_rig(dets, target, names, options, [d.name for d in dets[0]])
    frames = frames or [f"{n}_optical_frame" for n in names]
    lines = ["shots:", *_shot_lines(rig), *rig.summary_lines()]
    for c in range(1, len(names)):
        sr, st = rig.pose_sigma[c]
        t = rig.pose_in_reference(c).translation
        lines.append(f"{names[c]} in {names[0]}'s frame: t = [{', '.join(f'{v:.6f}' for v in t)}] m "
                     f"(+- [{', '.join(f'{v:.4f}' for v in st)}] mm), +- [{', '.join(f'{v:.5f}' for v in sr)}] deg")
        lines.append("  " + static_transform_command(rig.pose_in_reference(c), frames[0], frames[c]))
    outcome = RigOutcome(rig, rig_records(rig, names), frames, lines)
    outcome.files = outcome.write(out_dir)
    outcome.lines.append("wrote " + ", ".join(str(f) for f in outcome.files))
    return outcome


def progress_printer(enabled: bool) -> Callable[[int, int, str], None] | None:
    """A progress callback writing ``[k/n] name`` to stderr (None when not enabled)."""
    if not enabled:
        return None

    def show(k: int, n: int, text: str) -> None:
        sys.stderr.write(f"\r[{k}/{n}] {text[:70]:<70}")
        if k == n:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return show


def expand_glob(pattern: str) -> list[Path]:
    """Image files of a folder, a glob pattern or a file (sorted)."""
    import glob

    from ..io import IMAGE_SUFFIXES, expand_image_args

    p = Path(pattern)
    if p.is_dir() or p.is_file():
        return expand_image_args([pattern])
    return sorted(Path(f) for f in glob.glob(pattern) if Path(f).suffix.lower() in IMAGE_SUFFIXES)


def run_stereo(left: list[str], right: list[str], target: Target, out_dir: str | Path, options: StereoOptions,
               params: DetectionParams, progress: bool = False) -> tuple[Pairing, list[list[Detection]], StereoOutcome]:
    """Image files (folders, globs) of the left and the right camera -> :func:`stereo_from_detections`."""
    groups = [[q for a in arg for q in expand_glob(a)] for arg in (left, right)]
    pairing = pair_files(groups, ["left", "right"])
    dets = detect_shots(pairing, target, params, progress_printer(progress))
    return pairing, dets, stereo_from_detections(dets, target, options, out_dir)


def parse_camera_args(items: list[str]) -> tuple[list[str], list[list[Path]]]:
    """``NAME=GLOB`` arguments -> names and their image files (a :class:`PairingError` for a bad
    or repeated one)."""
    names, groups = [], []
    for it in items:
        name, sep, pattern = it.partition("=")
        if not sep or not name or not pattern:
            raise PairingError(f"--camera {it!r}: expected NAME=GLOB (e.g. front=imgs/front/*.png)")
        if name in names:
            raise PairingError(f"--camera {name} given twice")
        names.append(name)
        groups.append(expand_glob(pattern))
    if len(names) < 2:
        raise PairingError("a rig needs at least two --camera NAME=GLOB")
    return names, groups


def run_rig(cameras: list[str], target: Target, out_dir: str | Path, options: RigOptions, params: DetectionParams,
            progress: bool = False) -> tuple[Pairing, list[list[Detection]], RigOutcome]:
    """``NAME=GLOB`` per camera -> :func:`rig_from_detections` (the first camera is the reference)."""
    names, groups = parse_camera_args(cameras)
    pairing = pair_files(groups, names)
    dets = detect_shots(pairing, target, params, progress_printer(progress))
    return pairing, dets, rig_from_detections(dets, target, names, out_dir, options)


def write_reports(rig: RigResult, dets: list[list[Detection]], pairing: Pairing, out_dir: str | Path,
                  stereo: StereoOutcome | None = None, target: Target | None = None) -> list[Path]:
    """Each camera's report (:func:`~..report.pages.write_report` of its part of the joint
    estimate, its worst views drawn on its own images) in ``out_dir/<camera>/``; for a pair
    (``stereo`` and ``target`` given) also the stereo page (:mod:`..report.stereo`)."""
    from ..report import write_report

    out = []
    assessed = assess_rig(rig)
    for c, name in enumerate(rig.names):
        by_name = {s: p for s, p in zip(pairing.shots, pairing.paths[c], strict=True) if p is not None}

        def image(n: str, by_name: dict[str, Path] = by_name) -> np.ndarray | None:
            return read_grey(by_name[n]) if n in by_name else None

        files = write_report(assessed[c], dets[c], Path(out_dir) / name, images=image)
        out.append(files.pdf)
    if stereo is not None and target is not None:
        from ..report import write_stereo_report

        def shot_image(c: int, s: int) -> np.ndarray | None:
            p = pairing.paths[c][s]
            return read_grey(p) if p is not None else None

        out.append(write_stereo_report(out_dir, rig, stereo.rectification, dets, target, stereo.lines, shot_image)[0])
    return out
