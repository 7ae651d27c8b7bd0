"""The stereo pair's page of the report (``pascal-calib stereo --report DIR``): ``DIR/stereo.pdf``
and ``DIR/stereo.png`` beside each camera's own report in ``DIR/left`` and ``DIR/right``.

Panels: the numbers (rig transform and sigma, rectification, epipolar RMS, shots); the epipolar
error over the left image (each circle tangent's or corner's row difference in the rectified pair,
at the feature's place; :func:`~..calibrate.epipolar.epipolar_samples`); its histogram; and the
rectified pair of the shot with the most features, remapped exactly as a ROS consumer does
(``initUndistortRectifyMap`` with left.yaml / right.yaml, :func:`~..geometry.rectify.rectify_maps`)
with rows drawn across both images.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..analysis import epipolar_samples
from ..calibrate import RigResult
from ..detect import Detection
from ..geometry import ImageSize, StereoRectification, rectify_maps
from ..targets import Target

ShotImage = Callable[[int, int], "np.ndarray | None"]  # (camera, shot) -> grey image (None: not at hand)


def _best_shot(rig: RigResult, dets: list[list[Detection]]) -> int | None:
    both = np.flatnonzero(rig.used[0] & rig.used[1])
    if not len(both):
        return None
    return int(max(both, key=lambda s: len(dets[0][s].edges) + len(dets[1][s].edges)))


def _panel_epipolar(ax: Any, fig: Any, uv: np.ndarray, d: np.ndarray, size: ImageSize) -> None:
    width, height = size
    lim = float(np.percentile(np.abs(d), 99)) if len(d) else 1.0
    sc = ax.scatter(uv[:, 0], uv[:, 1], c=d, s=6, cmap="coolwarm", vmin=-lim, vmax=lim)
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_aspect("equal")
    ax.set_title("epipolar error over the left image (rectified row difference, px)")
    fig.colorbar(sc, ax=ax, shrink=0.8)


def _panel_rectified(ax: Any, rig: RigResult, rect: StereoRectification, images: list[np.ndarray | None],
                     shot: int) -> None:
    out = []
    for c, (R, P) in enumerate(((rect.R1, rect.P1), (rect.R2, rect.P2))):
        img = images[c]
        if img is None:
            return
        mx, my = rectify_maps(rig.cameras[c].camera(), R, P)
        out.append(cv2.remap(img, mx, my, cv2.INTER_LINEAR))
    pair = np.hstack(out)
    ax.imshow(pair, cmap="gray", vmin=0, vmax=255 if pair.dtype == np.uint8 else None)
    for y in np.linspace(0, pair.shape[0] - 1, 16)[1:-1]:
        ax.axhline(y, color="lime", lw=0.5)
    ax.set_title(f"rectified pair, shot {rig.shot_names[shot]} (left | right): features on the same rows")
    ax.axis("off")


def write_stereo_report(out_dir: str | Path, rig: RigResult, rect: StereoRectification, dets: list[list[Detection]],
                        target: Target, lines: list[str], image: ShotImage | None = None) -> tuple[Path, Path]:
    """``stereo.pdf`` and ``stereo.png`` in ``out_dir`` (module docstring); ``lines`` the text of
    the outcome, ``image(camera, shot)`` the images for the rectified pair."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    uv, d = epipolar_samples(rig, rect, dets, target)
    cam = rig.cameras[0]
    fig, ax = plt.subplots(2, 2, figsize=(18, 12), gridspec_kw={"width_ratios": [1.1, 1]})
    text = [w for line in lines if not line.startswith("  shot") for w in textwrap.wrap(line, 95) or [""]]
    ax[0][0].axis("off")
    ax[0][0].text(0.0, 1.0, "\n".join(["stereo pair", "", *text[:40]]), va="top", family="monospace", fontsize=7.5)
    _panel_epipolar(ax[0][1], fig, uv, d, cam.size)
    if len(d):
        ax[1][1].hist(d, bins=60, color="tab:blue")
    rms = float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
    ax[1][1].set_title(f"epipolar error: RMS {rms:.4f} px over {len(d)} features")
    ax[1][1].set_xlabel("rectified row difference, left - right (px)")
    shot = _best_shot(rig, dets)
    if shot is not None and image is not None:
        _panel_rectified(ax[1][0], rig, rect, [image(0, shot), image(1, shot)], shot)
    else:
        ax[1][0].axis("off")
    fig.tight_layout()
    pdf, png = out / "stereo.pdf", out / "stereo.png"
    fig.savefig(pdf)
    fig.savefig(png, dpi=70)
    plt.close(fig)
    return pdf, png
