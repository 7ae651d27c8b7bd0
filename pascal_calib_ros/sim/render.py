"""Renderer of targets with exact geometry and a simple sensor model.

Each pixel centre (integer coordinates, OpenCV convention) is inverse-mapped through the camera
(its lens model's exact inverse to a ray, :meth:`Camera.unproject`; fisheye rays may point beyond
90 degrees; then ray-plane intersection) to the target plane. Edges are
anti-aliased with the box-filter coverage of the signed distance in pixels,
coverage = clip(1/2 - d / |grad_px d|, 0, 1), exact for straight edges and to O(curvature) for
curved ones. Then, in linear radiance: vignetting, Gaussian blur (optics/defocus); then the display
gamma, Gaussian noise, 8-bit quantisation and optional JPEG. Ground truth is returned beside the
image (and written as JSON by :func:`write_view`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..geometry import Camera, rodrigues, rotation_to_rvec
from ..targets import ModuleLattice, Target

WHITE = 0.85
BLACK = 0.06
BACKGROUND = 0.30


@dataclass(frozen=True)
class Pose:
    """Target-to-camera transform: X_cam = R X_target + t (metres)."""

    R: np.ndarray
    t: np.ndarray

    @property
    def rvec(self) -> np.ndarray:
        return rotation_to_rvec(self.R)

    def to_dict(self) -> dict[str, list[float]]:
        return {"rvec": self.rvec.tolist(), "t": np.asarray(self.t, float).tolist()}


@dataclass(frozen=True)
class SheetShape:
    """How the printed sheet departs from its nominal geometry (the model of calibrate/solver/refine.py):
    y printed (1 + pitch_ratio) times longer than nominal (about the frame's middle), and the
    sheet bent out of its plane by z = warp_x (1 - ux^2) + warp_y (1 - uy^2) metres, with ux, uy
    running from -1 to 1 across ``frame`` = (x mid, y mid, x half-width, y half-width)."""

    pitch_ratio: float = 0.0
    warp_x: float = 0.0
    warp_y: float = 0.0
    frame: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0)

    def z(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        xm, ym, xh, yh = self.frame
        return self.warp_x * (1 - ((x - xm) / xh) ** 2) + self.warp_y * (1 - ((y - ym) / yh) ** 2)

    def nominal_y(self, y_printed: np.ndarray) -> np.ndarray:
        ym = self.frame[1]
        return ym + (y_printed - ym) / (1 + self.pitch_ratio)


@dataclass(frozen=True)
class SensorModel:
    """Image formation after the geometry (all optional)."""

    blur_sigma: float = 0.8  # Gaussian blur in px (optics); defocus: 3-6 px
    noise_sigma: float = 1.5  # Gaussian noise in 8-bit grey levels, after gamma
    gamma: float = 2.2  # display gamma (1 = linear)
    vignetting: float = 0.25  # relative fall-off at the image corner (cos^4-like, quadratic)
    jpeg_quality: int = 0  # 0 = no JPEG
    background_texture: float = 0.08  # amplitude of smooth clutter in the background
    seed: int = 0


@dataclass
class RenderedView:
    image: np.ndarray  # uint8 (H, W)
    camera: Camera
    pose: Pose | None
    sensor: SensorModel
    target_name: str
    meta: dict[str, object] = field(default_factory=dict)

    def ground_truth(self) -> dict[str, object]:
        return {
            "target": self.target_name,
            "width": self.camera.width,
            "height": self.camera.height,
            "K": self.camera.K.tolist(),
            "D": self.camera.D.tolist(),
            "distortion_model": self.camera.model,
            "pose": None if self.pose is None else self.pose.to_dict(),
            "sensor": asdict(self.sensor),
            **self.meta,
        }


def plane_coordinates(camera: Camera, pose: Pose, shape: SheetShape | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nominal sheet coordinates (x, y) of every pixel centre, and a mask of pixels that see the
    sheet. A bent or mis-scaled sheet (``shape``) is intersected by fixed-point iteration: the
    ray meets the plane at the height z of the sheet point found last (z varies slowly)."""
    h, w = camera.height, camera.width
    us, vs = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    uv = np.stack([us, vs], -1).reshape(-1, 2)
    d = camera.unproject(uv)
    d = np.where(np.isfinite(d), d, 0.0)  # pixels the lens model cannot invert see nothing
    n = pose.R[:, 2]
    denom = d @ n
    safe = np.where(np.abs(denom) > 1e-12, denom, 1.0)
    z = np.zeros(len(d))
    for _ in range(8 if shape is not None else 1):
        lam = np.where(np.abs(denom) > 1e-12, (n @ pose.t + z) / safe, -1.0)
        X = d * lam[:, None]
        P = (X - pose.t) @ pose.R  # R^T (X - t)
        if shape is not None:
            P[:, 1] = shape.nominal_y(P[:, 1])
            z = shape.z(np.clip(P[:, 0], -10, 10), np.clip(P[:, 1], -10, 10))  # rays far off the sheet stay finite
    valid = (lam > 0).reshape(h, w)
    # the inverse map is only trustworthy where distortion is monotonic: check by reprojection
    back = camera.project(X[lam > 0]) if np.any(lam > 0) else np.zeros((0, 2))
    ok = np.zeros(len(uv), bool)
    ok[lam > 0] = np.linalg.norm(back - uv[lam > 0], axis=1) < 1e-3
    valid &= ok.reshape(h, w)
    return P[:, 0].reshape(h, w), P[:, 1].reshape(h, w), valid


def _soft_step(d_plane: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Coverage of {d < 0} for a signed plane distance d with pixel gradient (gx, gy)."""
    g = np.maximum(np.hypot(gx, gy), 1e-12)
    return np.clip(0.5 - d_plane / g, 0.0, 1.0)


def reflectance(target: Target, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Anti-aliased reflectance of the sheet at plane coordinates (x, y) given on a pixel grid,
    and the sheet's coverage of each pixel."""
    xu, xv = np.gradient(x, axis=1), np.gradient(x, axis=0)
    yu, yv = np.gradient(y, axis=1), np.gradient(y, axis=0)

    def pix_grad(dx: np.ndarray | float, dy: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        return dx * xu + dy * yu, dx * xv + dy * yv

    dark = np.zeros_like(x)
    for ring in target.rings:
        for r, sign in ((ring.outer_radius, 1.0), (ring.inner_radius, -1.0)):
            dx, dy = x - ring.center[0], y - ring.center[1]
            rho = np.maximum(np.hypot(dx, dy), 1e-15)
            dark += sign * _soft_step(rho - r, *pix_grad(dx / rho, dy / rho))
    for disc in target.discs:
        dx, dy = x - disc.center[0], y - disc.center[1]
        rho = np.maximum(np.hypot(dx, dy), 1e-15)
        dark += _soft_step(rho - disc.radius, *pix_grad(dx / rho, dy / rho))
    for g in target.grids:
        # nearest lattice centre of every pixel: O(1) per pixel whatever the number of circles
        col = np.clip(np.round((x - g.origin[0]) / g.pitch), 0, g.cols - 1)
        row = np.clip(np.round((y - g.origin[1]) / g.pitch), 0, g.rows - 1)
        dx, dy = x - (g.origin[0] + col * g.pitch), y - (g.origin[1] + row * g.pitch)
        rho = np.maximum(np.hypot(dx, dy), 1e-15)
        gu, gv = pix_grad(dx / rho, dy / rho)
        dark += _soft_step(rho - g.outer_radius, gu, gv)
        if g.kind == "ring":
            dark -= _soft_step(rho - g.inner_radius, gu, gv)
    for b in target.checkerboards:
        fx = (x - b.origin[0]) / b.square_size
        fy = (y - b.origin[1]) / b.square_size
        kx, ky = np.round(fx), np.round(fy)
        ex, ey = (fx - kx) * b.square_size, (fy - ky) * b.square_size
        # soft sign of each axis' cell parity: (-1)^k * clip(2 e_px, -1, 1)
        sx = np.where(kx % 2 == 0, 1.0, -1.0) * (1 - 2 * _soft_step(ex, *pix_grad(1.0, 0.0)))
        sy = np.where(ky % 2 == 0, 1.0, -1.0) * (1 - 2 * _soft_step(ey, *pix_grad(0.0, 1.0)))
        pattern = (1 + sx * sy) / 2 if b.first_square == "black" else (1 - sx * sy) / 2
        x0, y0, x1, y1 = b.extent
        inside = (_soft_step(x0 - x, *pix_grad(-1.0, 0.0)) * _soft_step(x - x1, *pix_grad(1.0, 0.0))
                  * _soft_step(y0 - y, *pix_grad(0.0, -1.0)) * _soft_step(y - y1, *pix_grad(0.0, 1.0)))
        dark += pattern * inside
    for board in target.boards:
        if board.kind != "checkerboard":
            for lattice in board.lattices():
                dark += lattice_darkness(lattice, x, y, pix_grad)
    w, h = target.sheet
    sheet = (_soft_step(-x, *pix_grad(-1.0, 0.0)) * _soft_step(x - w, *pix_grad(1.0, 0.0))
             * _soft_step(-y, *pix_grad(0.0, -1.0)) * _soft_step(y - h, *pix_grad(0.0, 1.0)))
    return WHITE - (WHITE - BLACK) * np.clip(dark, 0.0, 1.0), sheet


def _nearest_boundary(rel: np.ndarray, lat: ModuleLattice, count: int) -> np.ndarray:
    """Position (from the lattice's origin, along one axis) of the module edge nearest to ``rel``,
    over the cell of ``rel`` and its two neighbours."""
    n = lat.bits.shape[2]
    c0 = np.floor(rel / lat.pitch)
    best, where = np.full(rel.shape, np.inf), np.zeros_like(rel)
    for dc in (-1, 0, 1):
        c = np.clip(c0 + dc, 0, count - 1)
        j = np.clip(np.round((rel - c * lat.pitch - lat.offset) / lat.module), 0, n)
        pos = c * lat.pitch + lat.offset + j * lat.module
        closer = np.abs(rel - pos) < best
        best, where = np.where(closer, np.abs(rel - pos), best), np.where(closer, pos, where)
    return where


def _bit_at(lat: ModuleLattice, rx: np.ndarray, ry: np.ndarray) -> np.ndarray:
    """Whether the module at (rx, ry) (from the lattice's origin) is dark; outside every module: no."""
    rows, cols, n, _ = lat.bits.shape
    cx, cy = np.floor(rx / lat.pitch).astype(int), np.floor(ry / lat.pitch).astype(int)
    j = np.floor((rx - cx * lat.pitch - lat.offset) / lat.module).astype(int)
    i = np.floor((ry - cy * lat.pitch - lat.offset) / lat.module).astype(int)
    inside = (cx >= 0) & (cx < cols) & (cy >= 0) & (cy < rows) & (i >= 0) & (i < n) & (j >= 0) & (j < n)
    return lat.bits[np.clip(cy, 0, rows - 1), np.clip(cx, 0, cols - 1), np.clip(i, 0, n - 1),
                    np.clip(j, 0, n - 1)] & inside


def lattice_darkness(lat: ModuleLattice, x: np.ndarray, y: np.ndarray,
                     pix_grad: Callable[[float, float], tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Anti-aliased darkness of a lattice of dark modules (:class:`ModuleLattice`) at plane
    coordinates (x, y): for the module edge nearest to the pixel along x and along y (in its cell
    or a neighbouring one), the box-filter coverage of either side (the soft steps of the
    checkerboard above) times whether the module on that side is dark; exact for straight edges
    longer than a pixel, as the checkerboard's."""
    rows, cols = lat.bits.shape[:2]
    rx, ry = x - lat.origin[0], y - lat.origin[1]
    out = np.zeros_like(x)
    # only the pixels over the lattice (and a module around it) can be dark
    near = ((rx > -lat.module) & (rx < cols * lat.pitch + lat.module)
            & (ry > -lat.module) & (ry < rows * lat.pitch + lat.module))
    rx, ry = rx[near], ry[near]
    gxx, gxy = (np.asarray(g)[near] for g in pix_grad(1.0, 0.0))
    gyx, gyy = (np.asarray(g)[near] for g in pix_grad(0.0, 1.0))
    bx, by = _nearest_boundary(rx, lat, cols), _nearest_boundary(ry, lat, rows)
    wx = _soft_step(bx - rx, gxx, gxy)  # share of the pixel beyond the x edge
    wy = _soft_step(by - ry, gyx, gyy)
    h = 0.5 * lat.module
    dark = np.zeros_like(rx)
    for sx, fx in ((h, wx), (-h, 1 - wx)):
        for sy, fy in ((h, wy), (-h, 1 - wy)):
            dark += _bit_at(lat, bx + sx, by + sy) * fx * fy
    out[near] = dark
    return out


def _background(h: int, w: int, amplitude: float, rng: np.random.Generator) -> np.ndarray:
    small = rng.uniform(-1, 1, size=(max(h // 64, 2), max(w // 64, 2)))
    return BACKGROUND + amplitude * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def apply_sensor(radiance: np.ndarray, sensor: SensorModel, rng: np.random.Generator) -> np.ndarray:
    """Vignetting, blur (linear light), gamma, noise, quantisation, JPEG -> uint8."""
    h, w = radiance.shape
    img = radiance.astype(np.float64)
    if sensor.vignetting:
        yy, xx = np.mgrid[0:h, 0:w]
        r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
        img = img * (1 - sensor.vignetting * r2)
    if sensor.blur_sigma > 0:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), sensor.blur_sigma, borderType=cv2.BORDER_REFLECT), float)
    img = np.clip(img, 0, 1) ** (1 / sensor.gamma) * 255.0
    if sensor.noise_sigma > 0:
        img = img + rng.normal(0, sensor.noise_sigma, img.shape)
    out = np.clip(np.round(img), 0, 255).astype(np.uint8)
    if sensor.jpeg_quality:
        _ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(sensor.jpeg_quality)])
        decoded = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
        if decoded is None:
            raise RuntimeError("JPEG round trip failed")
        out = np.asarray(decoded, np.uint8)
    return out


def render_view(target: Target, camera: Camera, pose: Pose | None, sensor: SensorModel = SensorModel(),
                shape: SheetShape | None = None) -> RenderedView:
    """Render one grey image of the target at ``pose`` (None: a view without any target), on a
    sheet printed and bent as ``shape`` says (None: flat and true to scale)."""
    rng = np.random.default_rng(sensor.seed)
    h, w = camera.height, camera.width
    radiance = _background(h, w, sensor.background_texture, rng)
    if pose is not None:
        x, y, valid = plane_coordinates(camera, pose, shape)
        x = np.where(valid, x, -1e3)
        y = np.where(valid, y, -1e3)
        refl, sheet = reflectance(target, x, y)
        sheet = np.where(valid, sheet, 0.0)
        radiance = sheet * refl + (1 - sheet) * radiance
    return RenderedView(apply_sensor(radiance, sensor, rng), camera, pose, sensor, target.name)


def write_view(view: RenderedView, path: str | Path) -> Path:
    """Write the image (PNG, or JPEG if the sensor used JPEG) and ``<name>.json`` ground truth."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(p), view.image):
        raise OSError(f"could not write {p}")
    p.with_suffix(".json").write_text(json.dumps(view.ground_truth(), indent=1))
    return p


def look_at_pose(target: Target, camera: Camera, pixel: tuple[float, float], size_fraction: float,
                 tilt_deg: float, tilt_axis_deg: float, roll_deg: float,
                 anchor: tuple[float, float] | None = None) -> Pose:
    """Pose that puts the target's anchor (default: centre of its features) at ``pixel``, tilted
    by ``tilt_deg`` about an in-plane axis at ``tilt_axis_deg``, rolled by ``roll_deg``, at a
    distance where the sheet's feature extent spans ``size_fraction`` of the image width."""
    if anchor is None:
        anchor = feature_centre(target)
    a = np.radians(tilt_axis_deg)
    R = rodrigues(np.radians(tilt_deg) * np.array([np.cos(a), np.sin(a), 0.0])) @ rodrigues(
        np.array([0.0, 0.0, np.radians(roll_deg)]))
    extent = feature_extent(target)
    Z = camera.K[0, 0] * extent / (size_fraction * camera.width)
    ray = camera.unproject(np.array([pixel], float))[0]
    # pinhole lenses: at depth Z; fisheye: at distance Z along the ray (which may point sideways,
    # even backwards), the sheet turned to face the camera along that ray before the tilt
    if camera.lens.wide:
        centre_cam = Z * ray
        axis = np.cross([0.0, 0.0, 1.0], ray)
        s_ = float(np.linalg.norm(axis))
        turn = rodrigues(axis / s_ * np.arctan2(s_, float(ray[2]))) if s_ > 1e-9 else np.eye(3)
        R = turn @ R
    else:
        centre_cam = Z * ray / ray[2]
    t = centre_cam - R @ np.array([anchor[0], anchor[1], 0.0])
    return Pose(R, t)


def feature_centre(target: Target) -> tuple[float, float]:
    pts = feature_outline(target, 16)
    lo, hi = pts.min(0), pts.max(0)
    return (float(lo[0] + hi[0]) / 2, float(lo[1] + hi[1]) / 2)


def feature_extent(target: Target) -> float:
    pts = feature_outline(target, 16)
    return float(np.max(pts.max(0) - pts.min(0)))


def feature_outline(target: Target, n: int = 64) -> np.ndarray:
    """Points on every circle and the checkerboard outline (target plane, (N, 2))."""
    pts = []
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    for c in target.circles[: 2 * len(target.rings) + len(target.discs)]:
        pts.append(np.stack([c.center[0] + c.radius * np.cos(t), c.center[1] + c.radius * np.sin(t)], 1))
    boxes: list[tuple[float, float, float, float]] = [b.extent for b in target.boards]
    boxes += [g.extent for g in target.grids]
    for x0, y0, x1, y1 in boxes:
        pts.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
    return np.concatenate(pts)


def features_in_image(target: Target, camera: Camera, pose: Pose, margin: float = 3.0) -> bool:
    """True if every feature outline projects inside the image with ``margin`` px to spare."""
    P = feature_outline(target)
    X = (pose.R @ np.concatenate([P, np.zeros((len(P), 1))], 1).T).T + pose.t
    if not camera.lens.wide and np.any(X[:, 2] <= 0):
        return False
    uv = camera.project(X)
    # reject poses where distortion folds (projection not invertible near the corners)
    back = camera.unproject(uv)
    if not np.all(np.isfinite(back)) or np.max(np.abs(back - X / np.linalg.norm(X, axis=1, keepdims=True))) > 1e-6:
        return False
    return bool(np.all((uv[:, 0] >= margin) & (uv[:, 0] <= camera.width - 1 - margin)
                       & (uv[:, 1] >= margin) & (uv[:, 1] <= camera.height - 1 - margin)))


def random_poses(target: Target, camera: Camera, n: int, rng: np.random.Generator,
                 tilt_range: tuple[float, float] = (15.0, 50.0), size_range: tuple[float, float] = (0.3, 0.6),
                 margin: float = 10.0, max_tries: int = 2000,
                 pixel_range: tuple[float, float] = (0.2, 0.8)) -> list[Pose]:
    """A capture session: n poses with the whole target in view, varied position (the anchor
    within ``pixel_range`` of the width and height), size, tilt."""
    poses: list[Pose] = []
    tries = 0
    while len(poses) < n:
        tries += 1
        if tries > max_tries:
            raise RuntimeError("could not place the target in view; widen the ranges")
        pixel = (rng.uniform(*pixel_range) * camera.width, rng.uniform(*pixel_range) * camera.height)
        pose = look_at_pose(target, camera, pixel, rng.uniform(*size_range), rng.uniform(*tilt_range),
                            rng.uniform(0, 360), rng.uniform(-30, 30))
        if features_in_image(target, camera, pose, margin):
            poses.append(pose)
    return poses


def board_visible_fraction(target: Target, camera: Camera, pose: Pose, margin: float = 5.0) -> float:
    """Share of the board's corners that project inside the image with ``margin`` px to spare (0
    for a target without a board, or one the lens folds)."""
    if target.board is None:
        return 0.0
    P = target.board.corner_points()
    X = (pose.R @ np.c_[P, np.zeros(len(P))].T).T + pose.t
    if not camera.lens.wide and np.any(X[:, 2] <= 0):
        return 0.0
    uv = camera.project(X)
    inside = ((uv[:, 0] >= margin) & (uv[:, 0] <= camera.width - 1 - margin)
              & (uv[:, 1] >= margin) & (uv[:, 1] <= camera.height - 1 - margin))
    return float(np.mean(inside))


def partial_poses(target: Target, camera: Camera, n: int, rng: np.random.Generator,
                  visible: tuple[float, float] = (0.3, 0.8), tilt_range: tuple[float, float] = (15.0, 45.0),
                  size_range: tuple[float, float] = (0.6, 1.0), max_tries: int = 4000) -> list[Pose]:
    """Poses where the board hangs partly out of the frame (a ``visible`` share of its corners in
    view), its centre near the image's borders and corners: the views a marker board allows and a
    whole board cannot give."""
    poses: list[Pose] = []
    for _ in range(max_tries):
        if len(poses) == n:
            return poses
        side = rng.uniform(-0.1, 0.25)  # the centre this far from a border (fraction of the image)
        u, v = rng.uniform(0, 1), rng.choice([side, 1 - side])
        pixel = (u, v) if rng.uniform() < 0.5 else (v, u)
        pose = look_at_pose(target, camera, (pixel[0] * camera.width, pixel[1] * camera.height),
                            rng.uniform(*size_range), rng.uniform(*tilt_range), rng.uniform(0, 360),
                            rng.uniform(-30, 30))
        if visible[0] <= board_visible_fraction(target, camera, pose) <= visible[1]:
            poses.append(pose)
    raise RuntimeError("could not place the board partly in view; widen the ranges")
