"""``undesigned``: views nobody designed (issue 36). A single ring (ring_a4) through a wide lens
(1280x720, f 640 px, k1 -0.28), placed at random: 0.5-1.1 of the image wide, tilted 20-60 deg,
its centre anywhere over 5-95 % of the image (the paper cut by the border, filling the frame),
blur 2 px; plus views with the target cut by the border and defocused ones (blur 7 px).

Every view is classified with the truth (the ring's true outer outline through the lens): whole
inside the image or not, its distance from the border, its imaged size, its tilt against the line
of sight. A ring whole inside the image must be measured unless the feature itself is unmeasurable
(defocused beyond the detector's widest edge). Accepted views are compared with the truth: each
edge point's signed distance to the circle's true image, and the ring centre's image from the
measured edges (the edges undistorted with the true lens, the two conics' centre
:func:`centre_image_from_ring`, projected back) against the true centre's image. The session is
calibrated (plumb_bob) and its projection compared with the truth over the whole image. The
views are detected with the renders' display gamma (2.2), as ``pascal-calib calibrate --gamma 2.2``.
"""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..calibrate import CalibrationError, CalibrationOptions, calibrate
from ..detect import Detection, DetectionParams
from ..geometry import Camera, centre_image_from_ring, fit_conic, grid_pixels
from ..sim import Pose, SessionSpec, render_session_views
from ..targets import Target, resolve_target
from ..workflows import detect_images, detection_params

BASE = SessionSpec(width=1280, height=720, focal=640, k1=-0.28, views=16, blur=2.0, size_range=(0.5, 1.1),
                   tilt_range=(20.0, 60.0), pixel_range=(0.05, 0.95), cut_views=2, defocused_views=2)


def undesigned_spec(seed: int, scale: float = 1.0, views: int = 16, extras: int = 2) -> SessionSpec:
    """The session of one seed: :data:`BASE` with the image (and focal length) scaled by ``scale``,
    ``views`` random views and ``extras`` cut and ``extras`` defocused ones."""
    return replace(BASE, width=round(BASE.width * scale), height=round(BASE.height * scale),
                   focal=BASE.focal * scale, views=views, cut_views=extras, defocused_views=extras, seed=seed)


@dataclass(frozen=True)
class ViewTruth:
    """What the truth says of a view's ring: whole inside the image (with the detector's border
    margin), the outer outline's least distance from the border (px, negative: cut), its largest
    extent (px), the tilt of the sheet against the line of sight to the ring's centre (deg)."""

    whole: bool
    margin: float
    size: float
    tilt: float


def circle_image(target: Target, cam: Camera, pose: Pose, circle: int, n: int = 720) -> np.ndarray:
    """(n, 2) pixels of the target's circle ``circle`` through the true lens."""
    c = target.circles[circle]
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    P = np.stack([c.center[0] + c.radius * np.cos(t), c.center[1] + c.radius * np.sin(t), 0 * t], 1)
    return cam.project(P @ pose.R.T + pose.t)


def view_truth(target: Target, cam: Camera, pose: Pose | None, border_margin: float = 3.0) -> ViewTruth:
    """:class:`ViewTruth` of a view (no pose: nothing whole, NaN figures)."""
    if pose is None:
        return ViewTruth(False, float("nan"), float("nan"), float("nan"))
    uv = circle_image(target, cam, pose, 0)
    margin = float(min(uv[:, 0].min(), uv[:, 1].min(), cam.width - 1 - uv[:, 0].max(),
                       cam.height - 1 - uv[:, 1].max()))
    centre = pose.R @ np.r_[target.rings[0].center, 0.0] + pose.t
    cos_tilt = abs(float(pose.R[:, 2] @ centre)) / float(np.linalg.norm(centre))
    return ViewTruth(bool(margin >= border_margin), margin, float(np.ptp(uv, axis=0).max()),
                     float(np.degrees(np.arccos(min(cos_tilt, 1.0)))))


def edge_errors(target: Target, cam: Camera, pose: Pose, det: Detection) -> dict[str, float]:
    """An accepted view's measurements against the truth: the signed distance (px) of every edge
    point to its circle's true image (nearest point of a dense sampling; mean and standard
    deviation per edge, the largest |distance| over all) and the error (px) of the ring centre's
    image from the measured edges, undistorted with the true lens (the image of the common centre
    of two concentric circles, :func:`centre_image_from_ring`), against the true centre's image."""
    from scipy.spatial import cKDTree

    out: dict[str, float] = {"edge_max": 0.0}
    for e in det.edges:
        truth = circle_image(target, cam, pose, e.circle, 20000)
        _, i = cKDTree(truth).query(e.points)
        tangent = truth[(i + 1) % len(truth)] - truth[i - 1]
        normal = np.c_[tangent[:, 1], -tangent[:, 0]] / np.linalg.norm(tangent, axis=1, keepdims=True)
        normal *= np.sign(np.einsum("ij,ij->i", normal, truth[i] - truth.mean(0)))[:, None]
        d = np.einsum("ij,ij->i", e.points - truth[i], normal)
        out[f"edge{e.circle}_mean"], out[f"edge{e.circle}_sd"] = float(np.mean(d)), float(np.std(d))
        out["edge_max"] = max(out["edge_max"], float(np.max(np.abs(d))))
    f = float(cam.K[0, 0])
    conics = [fit_conic(f * cam.undistort_pixels(det.edge(k).points)) for k in (0, 1)]  # type: ignore[union-attr]
    c = centre_image_from_ring(conics[0], conics[1])
    measured = cam.project(np.array([[c[0] / c[2] / f, c[1] / c[2] / f, 1.0]]))[0]
    true = cam.project((pose.R @ np.r_[target.rings[0].center, 0.0] + pose.t)[None])[0]
    out["centre_err"] = float(np.hypot(*(measured - true)))
    return out


def _calibration_error(dets: list[Detection], target: Target, truth: Camera) -> dict[str, float]:
    """The calibration of the measured views against the truth: fx and the projection difference
    (px) over the whole image (rays of a 40 px grid of pixels, reprojected), rms and largest."""
    try:
        res = calibrate(dets, target, CalibrationOptions())
    except CalibrationError as exc:
        return {"fx": float("nan"), "rms": float("nan"), "max": float("nan"), "error": str(exc)}  # type: ignore[dict-item]
    px = grid_pixels(truth.size, 40).astype(float)
    err = np.linalg.norm(res.camera().project(truth.unproject(px)) - px, axis=1)
    return {"fx": float(res.K[0, 0]), "rms": float(np.sqrt(np.nanmean(err**2))), "max": float(np.nanmax(err))}


def _seed_rows(seed: int, target: Target, params: DetectionParams, scale: float, views: int, extras: int
               ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Render, detect and classify one seed's session: a row per view and the seed's summary."""
    spec = undesigned_spec(seed, scale, views, extras)
    cam, rendered = render_session_views(target, spec)
    dets = detect_images(((str(v.meta["name"]), v.image) for v in rendered), len(rendered), target, params)
    rows = []
    for v, d in zip(rendered, dets, strict=True):
        tr = view_truth(target, cam, v.pose, params.border_margin)
        row: dict[str, Any] = {"seed": seed, "name": d.name, "blur": v.sensor.blur_sigma, "whole": tr.whole,
                               "margin": tr.margin, "size": tr.size, "tilt": tr.tilt, "measured": d.ok,
                               "refusal": str(d.refusal) if d.refusal else "", "reason": d.reason}
        if d.ok and v.pose is not None:
            row.update(edge_errors(target, cam, v.pose, d))
        rows.append(row)
    whole = [r for r in rows if r["whole"]]
    summary = {"seed": seed, "views": len(rows), "measured": sum(r["measured"] for r in rows),
               "whole": len(whole), "whole_measured": sum(r["measured"] for r in whole),
               "refused": dict(Counter(r["refusal"] for r in rows if not r["measured"])),
               "calibration": _calibration_error(dets, target, cam)}
    return rows, summary


def undesigned_views(seeds: tuple[int, ...] = (1, 2, 3), scale: float = 1.0, views: int = 16, extras: int = 2,
                     print_figures: bool = True) -> dict[str, Any]:
    """Run the study (module docstring) over ``seeds``: images ``scale`` times 1280x720 (the
    focal length with them), ``views`` random views and ``extras`` cut and defocused ones per seed.
    Returns ``{"rows": [per view], "seeds": [per seed], "whole_refused": [rows]}``; prints the
    figures when ``print_figures``."""
    target = resolve_target("ring_a4")
    # detected as a user of these images would: with the renders' display gamma (`--gamma 2.2`);
    # at gamma 1 every edge sits 0.8 px off its true image and the accuracy figures mean little
    params = detection_params("plumb_bob", BASE.gamma)
    rows: list[dict[str, Any]] = []
    seeds_out = []
    for seed in seeds:
        r, s = _seed_rows(seed, target, params, scale, views, extras)
        rows += r
        seeds_out.append(s)
        if print_figures:
            _print_seed(s, r)
    out = {"rows": rows, "seeds": seeds_out, "whole_refused": [r for r in rows if r["whole"] and not r["measured"]]}
    if print_figures:
        _print_totals(out)
    return out


def _print_seed(s: dict[str, Any], rows: list[dict[str, Any]]) -> None:
    c = s["calibration"]
    print(f"seed {s['seed']}: {s['measured']}/{s['views']} measured; ring whole in the image: "
          f"{s['whole_measured']}/{s['whole']} measured; refused by kind: {s['refused']}; calibration fx "
          f"{c['fx']:.1f}, error over the image rms {c['rms']:.3f} px, max {c['max']:.3f} px")
    for r in rows:
        acc = (f"edges mean {r['edge0_mean']:+.3f}/{r['edge1_mean']:+.3f} sd {r['edge0_sd']:.3f}/{r['edge1_sd']:.3f}"
               f" max {r['edge_max']:.2f} px, centre {r['centre_err']:.3f} px" if r["measured"] and "edge0_mean" in r
               else r["reason"])
        print(f"  {r['name']:<14} {'whole' if r['whole'] else 'cut  ' if r['margin'] == r['margin'] else 'none '}"
              f" margin {r['margin']:7.1f} px size {r['size']:6.0f} px tilt {r['tilt']:4.0f} deg blur {r['blur']:.0f}"
              f"  {'ok ' if r['measured'] else 'NO '} {acc}")
    sys.stdout.flush()


def _print_totals(out: dict[str, Any]) -> None:
    rows = out["rows"]
    whole = [r for r in rows if r["whole"]]
    ok = [r for r in rows if r["measured"] and "edge0_mean" in r]
    print(f"all seeds: {sum(r['measured'] for r in rows)}/{len(rows)} views measured; ring whole in the image: "
          f"{sum(r['measured'] for r in whole)}/{len(whole)} measured")
    if ok:
        bias = max(abs(r[k]) for r in ok for k in ("edge0_mean", "edge1_mean"))
        print(f"accepted views against the truth: |edge mean| <= {bias:.3f} px, "
              f"edge sd <= {max(r[k] for r in ok for k in ('edge0_sd', 'edge1_sd')):.3f} px, "
              f"centre error median {np.median([r['centre_err'] for r in ok]):.3f} px, "
              f"max {max(r['centre_err'] for r in ok):.3f} px")
    for r in out["whole_refused"]:
        print(f"  whole but refused: seed {r['seed']} {r['name']} (blur {r['blur']:.0f} px): {r['reason']}")
