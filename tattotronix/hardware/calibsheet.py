"""The calibration sheet (issue 34, item 4; docs/servos.md, "Identification from a drawn
sheet"): four ArUco markers at known places on the panel, the test pattern the arm draws
between them, and a photo of the drawn sheet read back into ink on the panel.

* :data:`MARKERS`: the markers (OpenCV's ``DICT_4X4_50``, ids 0 to 3), their centres in
  panel mm (``u`` right, ``v`` up, the origin at the panel's centre) and their side;
* :func:`pattern_strokes`: the test pattern, polylines in panel mm: lines in four
  directions (the pulse maps' bends and the links' sag), a reversal ladder (backlash and
  the dead band: every leg turns each joint back) and two circles (every direction, and
  the lag at a steady turn);
* :func:`sheet_image`: the sheet to print at 1:1 (the markers on white), on its grid;
* :func:`synthetic_photo`: what a phone's camera makes of a drawn sheet: in perspective,
  blurred, lit unevenly, noisy, on textured paper (the tests' photo, made without
  hardware);
* :func:`read_photo`: find the four markers, rectify the photo onto the sheet's grid
  (a homography from the markers' 16 corners), level its light and extract the ink.

A photo where a marker is not found is refused with one line naming the markers found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.path.fidelity import InkGrid

__all__ = ["MARKERS", "SHEET_RES_MM", "Marker", "pattern_strokes", "read_photo",
           "sheet_grid", "sheet_image", "synthetic_photo"]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
Gray = NDArray[np.uint8]


@dataclass(frozen=True)
class Marker:
    """One fiducial: its ArUco id, its centre in panel mm and its side, mm."""

    id: int
    u_mm: float
    v_mm: float
    side_mm: float

    def corners_mm(self) -> Array:
        """(4, 2) its corners in panel mm in ArUco's order: top-left, top-right,
        bottom-right, bottom-left, as printed (``v`` up)."""
        h = self.side_mm / 2
        return np.array([[self.u_mm - h, self.v_mm + h], [self.u_mm + h, self.v_mm + h],
                         [self.u_mm + h, self.v_mm - h], [self.u_mm - h, self.v_mm - h]])


#: the sheet's markers: 12 mm squares near the panel's corners, clear of the pattern
MARKERS = (Marker(0, -70.0, 50.0, 12.0), Marker(1, 70.0, 50.0, 12.0),
           Marker(2, 70.0, -50.0, 12.0), Marker(3, -70.0, -50.0, 12.0))
#: the sheet's pixel when it is printed or a photo is read back, mm
SHEET_RES_MM = 0.1
#: the sheet's extent, panel mm: the markers and a margin (u_min, u_max, v_min, v_max)
_EXTENT = (-80.0, 80.0, -60.0, 60.0)
_DICTIONARY = cv2.aruco.DICT_4X4_50
#: marker pixels within this of a marker's square are never ink, mm (its white border)
_MARKER_CLEAR_MM = 2.0


def _dictionary() -> cv2.aruco.Dictionary:
    return cv2.aruco.getPredefinedDictionary(_DICTIONARY)


def pattern_strokes() -> list[Array]:
    """The test pattern, polylines in panel mm (each ``(n, 2)``), within 45 x 32 mm of the
    panel's centre: every stroke apart from the others, so each one's ink is its own."""
    strokes: list[Array] = [
        np.array([[-40.0, 28.0], [40.0, 28.0]]),      # across
        np.array([[-44.0, -24.0], [-44.0, 20.0]]),    # up
        np.array([[-34.0, -26.0], [-4.0, 4.0]]),      # diagonal
        np.array([[4.0, 4.0], [34.0, -26.0]]),        # the other diagonal
    ]
    # the ladder: a zigzag along u, each leg turning back every joint that moves it
    u = np.linspace(-30.0, 30.0, 13)
    v = np.where(np.arange(13) % 2 == 0, 12.0, 20.0)
    strokes.append(np.column_stack([u, v]))
    for (cu, cv), r in (((0.0, -18.0), 6.0), ((38.0, 4.0), 5.0)):
        a = np.linspace(0.0, 2 * math.pi, 97)
        strokes.append(np.column_stack([cu + r * np.cos(a), cv + r * np.sin(a)]))
    return strokes


def sheet_grid(res_mm: float = SHEET_RES_MM) -> InkGrid:
    """The sheet's grid (pixel centres on ``res_mm``, row 0 at the top)."""
    u0, u1, v0, v1 = _EXTENT
    cols = int(round((u1 - u0) / res_mm)) + 1
    rows = int(round((v1 - v0) / res_mm)) + 1
    return InkGrid(u0_mm=u0, v0_mm=v1, res_mm=float(res_mm), shape=(rows, cols))


def _tile(m: Marker, grid: InkGrid) -> tuple[int, int, int]:
    """Where a marker's image sits on ``grid``: its top-left pixel (col, row) and its side,
    px (the sheet as printed is this image: these are the markers' true places)."""
    side = int(round(m.side_mm / grid.res_mm))
    col, row = grid.to_px(m.corners_mm()[:1])[0]
    return int(math.floor(col + 0.5)), int(math.floor(row + 0.5)), side


def _marker_px(m: Marker, grid: InkGrid) -> Array:
    """(4, 2) a marker's corners in ``grid``'s pixel coordinates (pixel centres on the
    integers, so the square's corners are on half pixels), in ArUco's order."""
    c, r, side = _tile(m, grid)
    lo_c, lo_r, hi_c, hi_r = c - 0.5, r - 0.5, c + side - 0.5, r + side - 0.5
    return np.array([[lo_c, lo_r], [hi_c, lo_r], [hi_c, hi_r], [lo_c, hi_r]])


def sheet_image(grid: InkGrid | None = None) -> Gray:
    """The sheet to print at 1:1 (``grid``'s pixel; white, the markers black)."""
    grid = grid or sheet_grid()
    img = np.full(grid.shape, 255, np.uint8)
    for m in MARKERS:
        c, r, side = _tile(m, grid)
        img[r:r + side, c:c + side] = cv2.aruco.generateImageMarker(_dictionary(), m.id,
                                                                    side)
    return img


def _marker_area(grid: InkGrid) -> Mask:
    """The markers' squares and their clear border, on ``grid``."""
    out = np.zeros(grid.shape, bool)
    pad = _MARKER_CLEAR_MM / grid.res_mm
    for m in MARKERS:
        px = grid.to_px(m.corners_mm())
        c0, r0 = np.floor(px.min(axis=0) - pad).astype(int)
        c1, r1 = np.ceil(px.max(axis=0) + pad).astype(int)
        out[max(r0, 0):r1 + 1, max(c0, 0):c1 + 1] = True
    return out


def synthetic_photo(ink: Mask, grid: InkGrid, rng: np.random.Generator, *,
                    size: tuple[int, int] = (2000, 1500), tilt: float = 0.06,
                    blur_px: float = 1.2, noise: float = 4.0) -> Gray:
    """A phone's photo of the drawn sheet: ``ink`` (on the sheet's ``grid``) and the
    markers on paper with a texture, seen in perspective (each corner of the sheet moved
    by up to ``tilt`` of the frame at random), blurred by ``blur_px``, lit by a gradient
    and a vignette, with Gaussian noise of ``noise`` grey levels, on a dark table.

    Args:
        size: the photo's (width, height), px.
    """
    w, h = size
    sheet = sheet_image(grid).astype(np.float64)
    texture = cv2.GaussianBlur(rng.normal(0.0, 1.0, grid.shape), (0, 0), 3.0)
    sheet *= 1.0 + 0.04 * texture / max(float(np.abs(texture).max()), 1e-9)
    sheet[ink] = 45.0  # the ink: dark, not quite black
    rows, cols = grid.shape
    src = np.array([[0, 0], [cols - 1, 0], [cols - 1, rows - 1], [0, rows - 1]], np.float32)
    margin = 0.1
    base = np.array([[margin * w, margin * h], [(1 - margin) * w, margin * h],
                     [(1 - margin) * w, (1 - margin) * h], [margin * w, (1 - margin) * h]])
    dst = (base + rng.uniform(-tilt, tilt, (4, 2)) * np.array([w, h])).astype(np.float32)
    homography = cv2.getPerspectiveTransform(src, dst)
    photo = cv2.warpPerspective(sheet, homography, (w, h), flags=cv2.INTER_AREA,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=60.0)
    photo = cv2.GaussianBlur(photo, (0, 0), blur_px)
    yy, xx = np.mgrid[0:h, 0:w] / np.array([h, w])[:, None, None]
    angle = rng.uniform(0, 2 * math.pi)
    light = 0.85 + 0.2 * (np.cos(angle) * (xx - 0.5) + np.sin(angle) * (yy - 0.5))
    light *= 1.0 - 0.25 * ((xx - 0.5) ** 2 + (yy - 0.5) ** 2)
    photo = photo * light + rng.normal(0.0, noise, photo.shape)
    return np.clip(np.rint(photo), 0, 255).astype(np.uint8)


def _gray(photo: Gray | Path | str) -> Gray:
    """A photo as one grey channel (a file is read; colour is converted)."""
    if isinstance(photo, str | Path):
        path = Path(photo)
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE) if path.is_file() else None
        if img is None:
            raise TattotronixError(f"photo={path}: not a readable image (PNG or JPEG)")
        return np.asarray(img, dtype=np.uint8)
    arr = np.asarray(photo, dtype=np.uint8)
    if arr.ndim == 3:
        arr = np.asarray(cv2.cvtColor(arr, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    if arr.ndim != 2 or arr.size == 0:
        raise TattotronixError(f"a photo is a grey or colour image, not an array of shape "
                               f"{arr.shape}")
    return np.asarray(arr, dtype=np.uint8)


def read_photo(photo: Gray | Path | str, grid: InkGrid | None = None,
               name: str = "the photo") -> Mask:
    """The ink of a photographed sheet, on the sheet's ``grid``.

    The four markers give a homography (their 16 corners, least squares) from the photo
    onto the grid; the rectified sheet is divided by its own light (a wide median: the
    paper), and the ink is what is darker than half the paper's brightness, away from
    the markers.

    Raises:
        TattotronixError: an unreadable file, or a marker not found (the line names the
            markers found and those missing).
    """
    grid = grid or sheet_grid()
    gray = _gray(photo)
    detector = cv2.aruco.ArucoDetector(_dictionary(), cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(gray)
    found = {int(i): c.reshape(4, 2) for i, c in zip(
        (ids.ravel() if ids is not None else []), corners, strict=True)}
    missing = [m.id for m in MARKERS if m.id not in found]
    if missing:
        seen = ", ".join(str(i) for i in sorted(found)) or "none"
        raise TattotronixError(
            f"{name}: the calibration sheet's markers {', '.join(map(str, missing))} are "
            f"not found (found: {seen}); photograph the whole sheet, flat and in focus, "
            "all four corner markers in the frame")
    src = np.concatenate([found[m.id] for m in MARKERS]).astype(np.float32)
    dst = np.concatenate([_marker_px(m, grid) for m in MARKERS]).astype(np.float32)
    homography, _ = cv2.findHomography(src, dst, 0)
    if homography is None:
        raise TattotronixError(f"{name}: the markers do not give a homography")
    rows, cols = grid.shape
    rect = cv2.warpPerspective(gray, homography, (cols, rows), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    paper = cv2.medianBlur(rect, 31).astype(np.float64)
    level = rect.astype(np.float64) / np.maximum(paper, 1.0)
    ink = (level < 0.65) & (paper > 30.0)
    ink &= ~_marker_area(grid)
    return ink
