"""Calibration targets loaded from YAML and validated.

Frame: origin at the sheet's top-left corner, x to the right, y down, z into the sheet; metres.
A target is a flat sheet carrying features: ``ring`` (black annulus, two concentric circles),
``disc`` (black filled circle), ``checkerboard``, grids of rings or discs, and the marker boards
people own, ``charuco`` and ``aprilgrid`` (:mod:`.target_boards`). Kalibr's own target YAML is read
as it is. See ``config/targets/*.yaml`` and docs/targets.md.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .errors import PascalCalibError
from .target_boards import (
    AprilGrid,
    BoardError,
    CharucoBoard,
    ModuleLattice,
    from_kalibr_yaml,
    parse_aprilgrid,
    parse_charuco,
)


class TargetError(PascalCalibError):
    """The target description is invalid; the message says what to fix."""


@dataclass(frozen=True)
class Circle:
    """One printed circle edge: centre (x, y) on the sheet, radius, and which side is dark.

    ``dark_inside`` is True for the outer edge of a ring and for a disc's edge, False for the
    inner edge of a ring. It fixes the sign of the edge-offset nuisance parameter.
    """

    center: tuple[float, float]
    radius: float
    dark_inside: bool
    feature: str  # e.g. "ring/outer", "ring/inner", "disc"


@dataclass(frozen=True)
class Ring:
    center: tuple[float, float]
    outer_radius: float
    inner_radius: float

    @property
    def circles(self) -> tuple[Circle, Circle]:
        return (
            Circle(self.center, self.outer_radius, True, "ring/outer"),
            Circle(self.center, self.inner_radius, False, "ring/inner"),
        )


@dataclass(frozen=True)
class Disc:
    center: tuple[float, float]
    radius: float

    @property
    def circles(self) -> tuple[Circle]:
        return (Circle(self.center, self.radius, True, "disc"),)


@dataclass(frozen=True)
class Checkerboard:
    origin: tuple[float, float]
    squares: tuple[int, int]  # squares along x, y
    square_size: float
    first_square: str  # "black" | "white"

    kind = "checkerboard"

    @property
    def inner_corners(self) -> tuple[int, int]:
        """Inner corners along x, y (OpenCV's pattern size)."""
        return (self.squares[0] - 1, self.squares[1] - 1)

    def corner_points(self) -> np.ndarray:
        """Inner corners on the sheet, (N, 2), row-major along x then y (OpenCV order)."""
        nx, ny = self.inner_corners
        xs = self.origin[0] + self.square_size * np.arange(1, nx + 1)
        ys = self.origin[1] + self.square_size * np.arange(1, ny + 1)
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx.ravel(), gy.ravel()], axis=1)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        x0, y0 = self.origin
        return (x0, y0, x0 + self.squares[0] * self.square_size, y0 + self.squares[1] * self.square_size)

    @property
    def corner_clearance(self) -> float:
        """Radius (m) about an inner corner that holds only its own two edges."""
        return self.square_size

    @property
    def corner_spacing(self) -> float:
        return self.square_size

    @property
    def module_size(self) -> float:
        """The smallest printed element the detector must resolve (m): a square."""
        return self.square_size

    def lattices(self) -> tuple[ModuleLattice, ...]:
        """The black squares."""
        jj, ii = np.mgrid[0:self.squares[1], 0:self.squares[0]]
        black = ((ii + jj) % 2 == 0) == (self.first_square == "black")
        return (ModuleLattice(self.origin, self.square_size, 0.0, self.square_size, black[:, :, None, None]),)

    def describe(self) -> str:
        return f"checkerboard {self.squares[0]}x{self.squares[1]} squares of {1000 * self.square_size:g} mm"


Board = Checkerboard | CharucoBoard | AprilGrid  # a board of corners, each with its own id (its row)


@dataclass(frozen=True)
class CircleGrid:
    """rows x cols rings (``kind`` "ring") or discs ("disc") on a square lattice.

    ``origin`` is the centre of the circle in row 0, column 0; column index along +x, row index
    along +y, ``pitch`` between neighbouring centres."""

    kind: str
    origin: tuple[float, float]
    rows: int
    cols: int
    pitch: float
    outer_radius: float
    inner_radius: float = 0.0  # rings only

    def center(self, row: int, col: int) -> tuple[float, float]:
        return (self.origin[0] + col * self.pitch, self.origin[1] + row * self.pitch)

    def centers(self) -> np.ndarray:
        """(rows * cols, 2) centres, row-major."""
        r, c = np.mgrid[0 : self.rows, 0 : self.cols]
        return np.stack([self.origin[0] + c.ravel() * self.pitch, self.origin[1] + r.ravel() * self.pitch], 1)

    @property
    def circles_per_element(self) -> int:
        return 2 if self.kind == "ring" else 1

    @property
    def extent(self) -> tuple[float, float, float, float]:
        r = self.outer_radius
        x0, y0 = self.origin
        return (x0 - r, y0 - r, x0 + (self.cols - 1) * self.pitch + r, y0 + (self.rows - 1) * self.pitch + r)


Feature = Ring | Disc | Board | CircleGrid


@dataclass(frozen=True)
class Target:
    name: str
    sheet: tuple[float, float]
    rings: tuple[Ring, ...] = ()
    discs: tuple[Disc, ...] = ()
    boards: tuple[Board, ...] = ()
    source: str = field(default="", compare=False)
    grids: tuple[CircleGrid, ...] = ()

    @cached_property
    def circles(self) -> tuple[Circle, ...]:
        """Every circle edge of the target: rings first (outer, inner), then discs, then each
        grid row-major (a ring grid element contributes outer then inner)."""
        out: list[Circle] = []
        for r in self.rings:
            out.extend(r.circles)
        for d in self.discs:
            out.extend(d.circles)
        for g in self.grids:
            for k, (x, y) in enumerate(g.centers()):
                tag = f"{g.kind}_grid[{k // g.cols},{k % g.cols}]"
                outer_tag = tag + "/outer" if g.kind == "ring" else tag
                out.append(Circle((float(x), float(y)), g.outer_radius, True, outer_tag))
                if g.kind == "ring":
                    out.append(Circle((float(x), float(y)), g.inner_radius, False, tag + "/inner"))
        return tuple(out)

    def grid_circle_index(self, grid: int, row: int, col: int) -> int:
        """Index in :attr:`circles` of the (outer) circle of a grid element."""
        base = 2 * len(self.rings) + len(self.discs)
        for g in self.grids[:grid]:
            base += g.rows * g.cols * g.circles_per_element
        g = self.grids[grid]
        return base + (row * g.cols + col) * g.circles_per_element

    @property
    def board(self) -> Board | None:
        """The board whose corners are measured (the first one)."""
        return self.boards[0] if self.boards else None

    @property
    def checkerboards(self) -> tuple[Checkerboard, ...]:
        """The plain checkerboards among the boards."""
        return tuple(b for b in self.boards if isinstance(b, Checkerboard))

    @property
    def checkerboard(self) -> Checkerboard | None:
        """The board if it is a plain checkerboard (what OpenCV's chessboard finder looks for)."""
        return self.board if isinstance(self.board, Checkerboard) else None

    @property
    def local_origin(self) -> tuple[float, float]:
        """The origin (sheet coordinates, m) of the frame the calibration poses the target in: the
        first circle's centre, or the middle of the board's corners."""
        if self.circles:
            return self.circles[0].center
        if self.board is not None:
            c = self.board.corner_points()
            mid = (c.min(0) + c.max(0)) / 2
            return float(mid[0]), float(mid[1])
        return (0.0, 0.0)

    def default_method(self) -> str:
        """The method a user gets without ``--method``."""
        if self.grids:
            return "grid"
        if self.rings:
            return "ring"
        if len(self.discs) >= 2:
            return "huang"
        if self.boards:
            return "zhang"
        raise TargetError(f"target {self.name!r} has no feature any method can use")

    def methods(self) -> tuple[str, ...]:
        """Methods this target supports."""
        out = ["grid"] if self.grids else []
        ring_grid = any(g.kind == "ring" for g in self.grids)
        if self.rings or ring_grid:
            out += ["ring", "pt2", "pt1"]
        if len(self.rings) + len(self.discs) >= 2 or self.grids:
            out.append("huang")
        if self.boards:
            out.append("zhang")
        return tuple(out)


def _floats(value: Any, n: int, where: str) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise TargetError(f"{where}: expected a list of {n} numbers, got {value!r}")
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise TargetError(f"{where}: expected numbers, got {value!r}") from None
    if not all(np.isfinite(out)):
        raise TargetError(f"{where}: numbers must be finite, got {value!r}")
    return out


def _positive(value: Any, where: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TargetError(f"{where}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise TargetError(f"{where}: must be a positive length in metres, got {value!r}")
    if v > 10:
        raise TargetError(f"{where}: {v} m is implausible; target units are metres")
    return v


def _require(d: dict[str, Any], key: str, where: str) -> Any:
    if key not in d:
        raise TargetError(f"{where}: missing key {key!r}")
    return d[key]


def parse_target(data: Any, source: str = "<dict>") -> Target:
    """Build a validated :class:`Target` from parsed YAML."""
    if not isinstance(data, dict):
        raise TargetError(f"{source}: a target file is a mapping with name, sheet, features")
    if "target_type" in data and "features" not in data:
        try:
            data = from_kalibr_yaml(data, source)
        except BoardError as e:
            raise TargetError(str(e)) from None
    name = str(_require(data, "name", source))
    sheet_d = _require(data, "sheet", source)
    if not isinstance(sheet_d, dict):
        raise TargetError(f"{source}: sheet must be {{width: .., height: ..}}")
    sheet = (
        _positive(_require(sheet_d, "width", f"{source}: sheet"), f"{source}: sheet.width"),
        _positive(_require(sheet_d, "height", f"{source}: sheet"), f"{source}: sheet.height"),
    )
    feats = _require(data, "features", source)
    if not isinstance(feats, list) or not feats:
        raise TargetError(f"{source}: features must be a non-empty list")
    rings: list[Ring] = []
    discs: list[Disc] = []
    boards: list[Board] = []
    grids: list[CircleGrid] = []
    for i, f in enumerate(feats):
        where = f"{source}: features[{i}]"
        if not isinstance(f, dict):
            raise TargetError(f"{where}: expected a mapping with a 'type'")
        kind = f.get("type")
        if kind == "ring":
            c = _floats(_require(f, "center", where), 2, f"{where}.center")
            ro, ri = _ring_radii(f, where, "ring")
            rings.append(Ring((c[0], c[1]), ro, ri))
        elif kind == "disc":
            c = _floats(_require(f, "center", where), 2, f"{where}.center")
            r = _positive(_require(f, "radius", where), f"{where}.radius")
            discs.append(Disc((c[0], c[1]), r))
        elif kind == "checkerboard":
            o = _floats(_require(f, "origin", where), 2, f"{where}.origin")
            sq = _require(f, "squares", where)
            if not (isinstance(sq, list) and len(sq) == 2 and all(isinstance(s, int) for s in sq)):
                raise TargetError(f"{where}.squares: expected two integers [nx, ny], got {sq!r}")
            if min(sq) < 3:
                raise TargetError(f"{where}.squares: need at least 3 squares per side, got {sq!r}")
            size = _positive(_require(f, "square_size", where), f"{where}.square_size")
            first = str(f.get("first_square", "black"))
            if first not in ("black", "white"):
                raise TargetError(f"{where}.first_square: 'black' or 'white', got {first!r}")
            boards.append(Checkerboard((o[0], o[1]), (sq[0], sq[1]), size, first))
        elif kind in ("ring_grid", "disc_grid"):
            grids.append(_parse_grid(f, kind, where))
        elif kind in ("charuco", "aprilgrid"):
            o = _floats(_require(f, "origin", where), 2, f"{where}.origin")
            try:
                parse = parse_charuco if kind == "charuco" else parse_aprilgrid
                boards.append(parse(f, (o[0], o[1]), where))
            except BoardError as e:
                raise TargetError(str(e)) from None
        else:
            raise TargetError(f"{where}: unknown feature type {kind!r} "
                              "(ring, disc, checkerboard, ring_grid, disc_grid, charuco, aprilgrid)")
    target = Target(name, sheet, tuple(rings), tuple(discs), tuple(boards), source, tuple(grids))
    _check_layout(target)
    return target


def _ring_radii(f: dict[str, Any], where: str, noun: str) -> tuple[float, float]:
    """Validated (outer_radius, inner_radius) of a ring or ring grid feature."""
    ro = _positive(_require(f, "outer_radius", where), f"{where}.outer_radius")
    ri = _positive(_require(f, "inner_radius", where), f"{where}.inner_radius")
    if ri >= ro:
        raise TargetError(f"{where}: inner_radius {ri} must be smaller than outer_radius {ro}")
    if ri / ro > 0.9:
        raise TargetError(f"{where}: {noun} too thin (inner/outer = {ri / ro:.2f} > 0.9) to detect both edges")
    return ro, ri


def _parse_grid(f: dict[str, Any], kind: str, where: str) -> CircleGrid:
    o = _floats(_require(f, "origin", where), 2, f"{where}.origin")
    dims = []
    for key in ("rows", "cols"):
        v = _require(f, key, where)
        if not isinstance(v, int) or isinstance(v, bool) or v < 2:
            raise TargetError(f"{where}.{key}: an integer >= 2, got {v!r}")
        dims.append(v)
    pitch = _positive(_require(f, "pitch", where), f"{where}.pitch")
    if kind == "ring_grid":
        ro, ri = _ring_radii(f, where, "rings")
    else:
        ro, ri = _positive(_require(f, "radius", where), f"{where}.radius"), 0.0
    if 2 * ro >= pitch:
        raise TargetError(f"{where}: circles of radius {ro} overlap at pitch {pitch} (need 2 r < pitch)")
    if 2 * ro > 0.8 * pitch:
        raise TargetError(f"{where}: circles of radius {ro} nearly touch at pitch {pitch}; leave at least "
                          "20 % of the pitch between them so that edges can be measured")
    return CircleGrid("ring" if kind == "ring_grid" else "disc", (o[0], o[1]), dims[0], dims[1], pitch, ro, ri)


def _check_layout(t: Target) -> None:
    w, h = t.sheet
    shapes: list[tuple[str, tuple[float, float, float, float]]] = []
    for r in t.rings:
        x, y = r.center
        shapes.append(("ring", (x - r.outer_radius, y - r.outer_radius, x + r.outer_radius, y + r.outer_radius)))
    for d in t.discs:
        x, y = d.center
        shapes.append(("disc", (x - d.radius, y - d.radius, x + d.radius, y + d.radius)))
    for b in t.boards:
        shapes.append((b.kind, b.extent))
    for g in t.grids:
        shapes.append((f"{g.kind}_grid", g.extent))
    for name, (x0, y0, x1, y1) in shapes:
        if x0 < 0 or y0 < 0 or x1 > w or y1 > h:
            raise TargetError(f"{t.source}: {name} extends off the {w} x {h} m sheet")
    circles = [(r.center, r.outer_radius, "ring") for r in t.rings] + [(d.center, d.radius, "disc") for d in t.discs]
    for i in range(len(circles)):
        for j in range(i + 1, len(circles)):
            (c1, r1, n1), (c2, r2, n2) = circles[i], circles[j]
            if np.hypot(c1[0] - c2[0], c1[1] - c2[1]) <= r1 + r2:
                raise TargetError(f"{t.source}: {n1} and {n2} overlap; circles must be separated")
    for name, (x0, y0, x1, y1) in shapes[len(circles):]:
        for c, rad, n in circles:
            if x0 - rad < c[0] < x1 + rad and y0 - rad < c[1] < y1 + rad:
                raise TargetError(f"{t.source}: {n} overlaps the {name}")
    boxes = shapes[len(circles):]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            (n1, ba), (n2, bb) = boxes[i], boxes[j]
            if ba[0] < bb[2] and bb[0] < ba[2] and ba[1] < bb[3] and bb[1] < ba[3]:
                raise TargetError(f"{t.source}: {n1} and {n2} overlap")


def load_target(path: str | Path) -> Target:
    """Load and validate a target YAML file. Raises :class:`TargetError` with a clear message."""
    p = Path(path)
    if not p.is_file():
        raise TargetError(f"target file not found: {p}")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as e:
        raise TargetError(f"{p}: not valid YAML: {e}") from None
    return parse_target(data, str(p))


PACKAGE = "pascal_calib_ros"


def _config_dir_candidates() -> list[Path]:
    """Where ``config/`` may be, in order: the source tree (development: this module sits next to
    ``package.xml``), the package's share directory from the ament index (``colcon build`` /
    ``apt`` install: ``<prefix>/share/pascal_calib_ros/config``), ``sys.prefix/share`` (pip
    install of the wheel into a venv)."""
    here = Path(__file__).resolve().parent
    candidates: list[Path] = []
    if (here.parent / "package.xml").is_file():
        candidates.append(here.parent / "config")
    try:  # lazily: the pure-Python core must work without ROS
        from ament_index_python.packages import get_package_share_directory

        candidates.append(Path(get_package_share_directory(PACKAGE)) / "config")
    except (ImportError, LookupError, OSError, ValueError):  # no ament, no AMENT_PREFIX_PATH, not indexed
        pass
    candidates.append(Path(sys.prefix) / "share" / PACKAGE / "config")
    return candidates


def packaged_config_dir() -> Path:
    """``config/`` shipped with the package (``calibration_node.yaml``, ``targets/``)."""
    candidates = _config_dir_candidates()
    for c in candidates:
        if (c / "targets").is_dir():
            return c
    raise TargetError("packaged target files not found (looked in "
                      + ", ".join(str(c / "targets") for c in candidates)
                      + "; source install/setup.bash of the workspace, or set AMENT_PREFIX_PATH)")


def packaged_targets_dir() -> Path:
    """``config/targets`` shipped with the package (source tree or installed share dir)."""
    return packaged_config_dir() / "targets"


def resolve_target(name_or_path: str) -> Target:
    """Load a target by path, or by the name of a packaged target (e.g. ``ring_a4``)."""
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml") or p.exists():
        return load_target(p)
    return load_target(packaged_targets_dir() / f"{name_or_path}.yaml")
