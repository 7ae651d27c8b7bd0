"""Marker boards people already own: OpenCV's ChArUco (current and legacy pattern) and Kalibr's
AprilGrid, as feature types of a target; their layout, marker bits and corner order.

Both are laid out exactly as their own tools draw them, so that a board printed by either is
detected with the right ids and corners:

- :class:`CharucoBoard` follows ``cv2.aruco.CharucoBoard`` (OpenCV 4.6+ ``charuco.cpp``): squares
  along x then y from the board's top-left corner; the top-left square is black, markers sit in the
  white squares, centred, numbered row-major from ``first_id``. OpenCV's *legacy* pattern (boards
  made before 4.6, calib.io's) starts with a white square when the number of rows is even. The
  inner corners are numbered row-major, corner k at ``origin + square_size * (k % (nx - 1) + 1,
  k // (nx - 1) + 1)`` (``getChessboardCorners``). Marker bits from the dictionary with a one-bit
  black border (``generateImageMarker``).
- :class:`AprilGrid` follows Kalibr's ``kalibr_create_target_pdf`` and its grid
  (``GridCalibrationTargetAprilgrid``): tag36h11 tags of ``tag_size`` with a two-bit black border,
  tag 0 at the bottom left, ids row-major along x then up; a black square of side
  ``tag_spacing * tag_size`` at every tag corner. The corners are Kalibr's points: point
  ``r * 2 tag_cols + c`` is in corner row r counted from the bottom and corner column c from the
  left. OpenCV's ``DICT_APRILTAG_36h11`` holds the same codes, its marker image turned by 180
  degrees against Kalibr's print (``test/targets/test_target_boards.py`` checks both).

Sheet frame as for every target: x to the right, y down, metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import cv2
import numpy as np

from .errors import PascalCalibError

APRILGRID_DICTIONARY = "DICT_APRILTAG_36h11"
APRILGRID_BORDER_BITS = 2


class BoardError(PascalCalibError):
    """A marker board's description is invalid; the message says what to fix."""


def aruco_dictionary(name: str) -> Any:
    """OpenCV's predefined dictionary called ``name`` (``DICT_5X5_100`` ...)."""
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        known = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
        raise BoardError(f"unknown marker dictionary {name!r}; OpenCV's names: {', '.join(known)}")
    return cv2.aruco.getPredefinedDictionary(code)


def marker_bits(dictionary: str, marker_id: int, border_bits: int) -> np.ndarray:
    """(n, n) bool, True where marker ``marker_id`` is dark, border included, row 0 at the top, as
    ``cv2.aruco.generateImageMarker`` draws it (one pixel per bit)."""
    d = aruco_dictionary(dictionary)
    n = d.markerSize + 2 * border_bits
    img = cv2.aruco.generateImageMarker(d, int(marker_id), n, borderBits=border_bits)
    return np.asarray(img) < 128


@dataclass(frozen=True)
class ModuleLattice:
    """Dark modules on a lattice of cells, what a renderer and a printer draw: cell (r, c) starts
    at ``origin + pitch * (c, r)``; in it a square of n x n modules of side ``module`` starts
    ``offset`` from the cell's corner along x and y; ``bits[r, c, i, j]`` is True where module
    (row i, column j) is dark."""

    origin: tuple[float, float]
    pitch: float
    offset: float
    module: float
    bits: np.ndarray  # (rows, cols, n, n) bool

    def rectangles(self) -> np.ndarray:
        """(M, 4) dark modules as (x, y, width, height) on the sheet."""
        r, c, i, j = np.nonzero(self.bits)
        x = self.origin[0] + c * self.pitch + self.offset + j * self.module
        y = self.origin[1] + r * self.pitch + self.offset + i * self.module
        return np.stack([x, y, np.full(len(x), self.module), np.full(len(x), self.module)], 1)


@dataclass(frozen=True)
class CharucoBoard:
    origin: tuple[float, float]  # top-left corner of the board (its first square) on the sheet
    squares: tuple[int, int]  # squares along x, y
    square_size: float
    marker_size: float
    dictionary: str = "DICT_5X5_100"
    legacy: bool = False
    first_id: int = 0

    kind = "charuco"
    border_bits = 1

    @property
    def inner_corners(self) -> tuple[int, int]:
        return (self.squares[0] - 1, self.squares[1] - 1)

    def corner_points(self) -> np.ndarray:
        """(N, 2) inner corners on the sheet, row-major (OpenCV's ChArUco corner ids)."""
        nx, ny = self.inner_corners
        gx, gy = np.meshgrid(np.arange(1, nx + 1), np.arange(1, ny + 1))
        return np.stack([self.origin[0] + self.square_size * gx.ravel(),
                         self.origin[1] + self.square_size * gy.ravel()], 1)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        x0, y0 = self.origin
        return (x0, y0, x0 + self.squares[0] * self.square_size, y0 + self.squares[1] * self.square_size)

    def square_has_marker(self) -> np.ndarray:
        """(ny, nx) bool: squares (row y, column x) holding a marker (``charuco.cpp``)."""
        yy, xx = np.mgrid[0:self.squares[1], 0:self.squares[0]]
        if self.legacy and self.squares[1] % 2 == 0:
            return (yy + 1) % 2 != xx % 2
        return yy % 2 != xx % 2

    @cached_property
    def marker_ids(self) -> np.ndarray:
        """(ny, nx) marker id of every square, -1 for a black square."""
        has = self.square_has_marker()
        ids = np.full(has.shape, -1)
        ids[has] = self.first_id + np.arange(int(has.sum()))
        return ids

    def marker_corners(self) -> dict[int, np.ndarray]:
        """Every marker's corners on the sheet, (4, 2): top-left, top-right, bottom-right,
        bottom-left, as ``getObjPoints`` and the detector give them."""
        d = (self.square_size - self.marker_size) / 2
        m = self.marker_size
        out = {}
        for (y, x), k in np.ndenumerate(self.marker_ids):
            if k >= 0:
                x0, y0 = self.origin[0] + x * self.square_size + d, self.origin[1] + y * self.square_size + d
                out[int(k)] = np.array([[x0, y0], [x0 + m, y0], [x0 + m, y0 + m], [x0, y0 + m]])
        return out

    @property
    def corner_clearance(self) -> float:
        """Radius (m) about an inner corner about which the image is point-symmetric: the markers in
        the two diagonal squares are, with their black borders, up to their first data bits,
        sqrt(2) (margin + one bit) away (margin = (square - marker) / 2)."""
        bit = self.marker_size / (aruco_dictionary(self.dictionary).markerSize + 2 * self.border_bits)
        margin = (self.square_size - self.marker_size) / 2
        return float(min(self.square_size, np.sqrt(2) * (margin + bit)))

    @property
    def corner_spacing(self) -> float:
        return self.square_size

    @property
    def module_size(self) -> float:
        """The smallest printed element the detector must resolve (m): one bit of a marker."""
        return self.marker_size / (aruco_dictionary(self.dictionary).markerSize + 2 * self.border_bits)

    def lattices(self) -> tuple[ModuleLattice, ...]:
        """The black squares, then the markers."""
        has = self.square_has_marker()
        squares = ModuleLattice(self.origin, self.square_size, 0.0, self.square_size, (~has)[:, :, None, None])
        n = aruco_dictionary(self.dictionary).markerSize + 2 * self.border_bits
        bits = np.zeros((*has.shape, n, n), bool)
        for (y, x), k in np.ndenumerate(self.marker_ids):
            if k >= 0:
                bits[y, x] = marker_bits(self.dictionary, int(k), self.border_bits)
        markers = ModuleLattice(self.origin, self.square_size, (self.square_size - self.marker_size) / 2,
                                self.marker_size / n, bits)
        return (squares, markers)

    def describe(self) -> str:
        legacy = " (legacy pattern)" if self.legacy else ""
        first = f", first id {self.first_id}" if self.first_id else ""
        return (f"ChArUco {self.squares[0]}x{self.squares[1]} squares of {1000 * self.square_size:g} mm, "
                f"markers {1000 * self.marker_size:g} mm {self.dictionary}{legacy}{first}")


@dataclass(frozen=True)
class AprilGrid:
    origin: tuple[float, float]  # top-left of the bounding box, corner squares included
    tag_cols: int
    tag_rows: int
    tag_size: float  # black border edge to edge
    tag_spacing: float  # gap between tags / tag_size

    kind = "aprilgrid"
    dictionary = APRILGRID_DICTIONARY
    border_bits = APRILGRID_BORDER_BITS
    first_id = 0

    @property
    def pitch(self) -> float:
        return (1 + self.tag_spacing) * self.tag_size

    @property
    def gap(self) -> float:
        return self.tag_spacing * self.tag_size

    @property
    def inner_corners(self) -> tuple[int, int]:
        """Kalibr's grid of tag corners: 2 tag_cols x 2 tag_rows."""
        return (2 * self.tag_cols, 2 * self.tag_rows)

    def _to_sheet(self, xk: np.ndarray, yk: np.ndarray) -> np.ndarray:
        """Kalibr's target frame (origin at tag 0's bottom-left corner, y up) to the sheet's."""
        height = self.tag_rows * self.pitch - self.gap
        return np.stack([self.origin[0] + self.gap + xk, self.origin[1] + self.gap + height - yk], -1)

    def corner_points(self) -> np.ndarray:
        """(N, 2) tag corners on the sheet in Kalibr's point order."""
        nc, nr = self.inner_corners
        r, c = np.divmod(np.arange(nc * nr), nc)
        xk = (c // 2) * self.pitch + (c % 2) * self.tag_size
        yk = (r // 2) * self.pitch + (r % 2) * self.tag_size
        return self._to_sheet(xk.astype(float), yk.astype(float))

    def tag_corner_indices(self, tag_id: int) -> np.ndarray:
        """Kalibr's point indices of tag ``tag_id``'s corners: bottom-left, bottom-right, top-right,
        top-left (as printed)."""
        nc = 2 * self.tag_cols
        base = (tag_id // self.tag_cols) * 2 * nc + (tag_id % self.tag_cols) * 2
        return np.array([base, base + 1, base + nc + 1, base + nc])

    @property
    def marker_ids(self) -> np.ndarray:
        """(tag_rows, tag_cols) tag ids as laid on the sheet (row 0 at the top)."""
        return (np.arange(self.tag_rows * self.tag_cols).reshape(self.tag_rows, self.tag_cols))[::-1]

    def marker_corners(self) -> dict[int, np.ndarray]:
        """Every tag's corners on the sheet, (4, 2), in the order OpenCV's detector returns them for
        a Kalibr print (its marker image is Kalibr's turned by 180 degrees): bottom-right,
        bottom-left, top-left, top-right as printed."""
        pts = self.corner_points()
        return {k: pts[self.tag_corner_indices(k)[[1, 0, 3, 2]]]
                for k in range(self.tag_rows * self.tag_cols)}

    @property
    def extent(self) -> tuple[float, float, float, float]:
        x0, y0 = self.origin
        return (x0, y0, x0 + self.tag_cols * self.pitch + self.gap, y0 + self.tag_rows * self.pitch + self.gap)

    @property
    def corner_clearance(self) -> float:
        """Radius (m) about a tag corner holding only its own two edges: the corner square's far
        sides (gap) and the inner corner of the tag's two-bit border (0.2 sqrt(2) tag_size)."""
        return float(min(self.gap, 0.2 * np.sqrt(2) * self.tag_size))

    @property
    def corner_spacing(self) -> float:
        return float(min(self.tag_size, self.gap))

    @property
    def module_size(self) -> float:
        """The smallest printed element the detector must resolve (m): one bit of a tag."""
        return self.tag_size / (aruco_dictionary(self.dictionary).markerSize + 2 * self.border_bits)

    def lattices(self) -> tuple[ModuleLattice, ...]:
        """The corner squares, then the tags (each drawn as Kalibr draws it: OpenCV's marker
        image turned by 180 degrees)."""
        squares = ModuleLattice(self.origin, self.pitch, 0.0, self.gap,
                                np.ones((self.tag_rows + 1, self.tag_cols + 1, 1, 1), bool))
        n = aruco_dictionary(self.dictionary).markerSize + 2 * self.border_bits
        bits = np.zeros((self.tag_rows, self.tag_cols, n, n), bool)
        for (r, c), k in np.ndenumerate(self.marker_ids):
            bits[r, c] = np.rot90(marker_bits(self.dictionary, int(k), self.border_bits), 2)
        tags = ModuleLattice(self.origin, self.pitch, self.gap, self.tag_size / n, bits)
        return (squares, tags)

    def describe(self) -> str:
        return (f"AprilGrid {self.tag_cols}x{self.tag_rows} tag36h11 tags of {1000 * self.tag_size:g} mm, "
                f"spacing {self.tag_spacing:g}")


MarkerBoard = CharucoBoard | AprilGrid


def _int(f: dict[str, Any], key: str, where: str, low: int, default: int | None = None) -> int:
    v = f.get(key, default)
    if v is None:
        raise BoardError(f"{where}: missing key {key!r}")
    if not isinstance(v, int) or isinstance(v, bool) or v < low:
        raise BoardError(f"{where}.{key}: an integer >= {low}, got {v!r}")
    return v


def _length(f: dict[str, Any], key: str, where: str) -> float:
    if key not in f:
        raise BoardError(f"{where}: missing key {key!r}")
    try:
        v = float(f[key])
    except (TypeError, ValueError):
        raise BoardError(f"{where}.{key}: expected a number, got {f[key]!r}") from None
    if not np.isfinite(v) or v <= 0 or v > 10:
        raise BoardError(f"{where}.{key}: a positive length in metres, got {f[key]!r}")
    return v


def parse_charuco(f: dict[str, Any], origin: tuple[float, float], where: str) -> CharucoBoard:
    sq = f.get("squares")
    if not (isinstance(sq, list) and len(sq) == 2 and all(isinstance(s, int) and not isinstance(s, bool) for s in sq)):
        raise BoardError(f"{where}.squares: expected two integers [nx, ny], got {sq!r}")
    if min(sq) < 3:
        raise BoardError(f"{where}.squares: need at least 3 squares per side, got {sq!r}")
    size, marker = _length(f, "square_size", where), _length(f, "marker_size", where)
    if marker >= size:
        raise BoardError(f"{where}: marker_size {marker} must be smaller than square_size {size}")
    name = str(f.get("dictionary", "DICT_5X5_100"))
    legacy = f.get("legacy", False)
    if not isinstance(legacy, bool):
        raise BoardError(f"{where}.legacy: true or false, got {legacy!r}")
    board = CharucoBoard(origin, (sq[0], sq[1]), size, marker, name, legacy, _int(f, "first_id", where, 0, 0))
    available = aruco_dictionary(name).bytesList.shape[0]
    last = board.first_id + int((board.marker_ids >= 0).sum()) - 1
    if last >= available:
        raise BoardError(f"{where}: the board needs marker ids {board.first_id}..{last}; {name} has {available} "
                         "(a larger dictionary, or a smaller first_id)")
    return board


def parse_aprilgrid(f: dict[str, Any], origin: tuple[float, float], where: str) -> AprilGrid:
    cols, rows = _int(f, "tag_cols", where, 1), _int(f, "tag_rows", where, 1)
    if cols * rows < 2:
        raise BoardError(f"{where}: an AprilGrid needs at least 2 tags")
    spacing = f.get("tag_spacing")
    if not isinstance(spacing, (int, float)) or isinstance(spacing, bool) or not 0 < spacing <= 1:
        raise BoardError(f"{where}.tag_spacing: the gap between tags over tag_size, in (0, 1], got {spacing!r}")
    if cols * rows > aruco_dictionary(APRILGRID_DICTIONARY).bytesList.shape[0]:
        raise BoardError(f"{where}: {cols * rows} tags exceed tag36h11's 587")
    return AprilGrid(origin, cols, rows, _length(f, "tag_size", where), float(spacing))


KALIBR_MARGIN = 0.01  # m of white paper around a board read from Kalibr's YAML


def from_kalibr_yaml(data: dict[str, Any], source: str) -> dict[str, Any]:
    """A target mapping (name, sheet, features) for Kalibr's own target YAML: ``target_type:
    aprilgrid`` (tagCols, tagRows, tagSize, tagSpacing) or ``checkerboard`` (targetCols/targetRows
    inner corners, rowSpacingMeters/colSpacingMeters); the sheet is the board with a 1 cm margin."""
    kind = data.get("target_type")
    where = f"{source} (Kalibr target)"
    m = KALIBR_MARGIN
    name = str(data.get("name", f"kalibr_{kind}"))
    if kind == "aprilgrid":
        try:
            cols, rows = int(data["tagCols"]), int(data["tagRows"])
            size, spacing = float(data["tagSize"]), float(data["tagSpacing"])
        except (KeyError, TypeError, ValueError) as e:
            raise BoardError(f"{where}: needs tagCols, tagRows, tagSize, tagSpacing ({e})") from None
        feature = {"type": "aprilgrid", "origin": [m, m], "tag_cols": cols, "tag_rows": rows, "tag_size": size,
                   "tag_spacing": spacing}
        grid = AprilGrid((m, m), cols, rows, size, spacing)
        width, height = grid.extent[2] + m, grid.extent[3] + m
    elif kind == "checkerboard":
        try:
            cols, rows = int(data["targetCols"]), int(data["targetRows"])
            dx, dy = float(data["colSpacingMeters"]), float(data["rowSpacingMeters"])
        except (KeyError, TypeError, ValueError) as e:
            raise BoardError(f"{where}: needs targetCols, targetRows, rowSpacingMeters, colSpacingMeters ({e})"
                             ) from None
        if abs(dx - dy) > 1e-9:
            raise BoardError(f"{where}: rectangular squares ({dx} x {dy} m) are not supported")
        feature = {"type": "checkerboard", "origin": [m, m], "squares": [cols + 1, rows + 1], "square_size": dx}
        width, height = 2 * m + (cols + 1) * dx, 2 * m + (rows + 1) * dy
    else:
        raise BoardError(f"{where}: target_type {kind!r} is not supported (aprilgrid, checkerboard)")
    return {"name": name, "sheet": {"width": width, "height": height}, "features": [feature]}
