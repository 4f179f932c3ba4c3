"""The ink mask on its grid: the contract between the ``mask`` and ``toolpath`` stages."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.io.npz import save_npz

__all__ = ["InkMask"]


@dataclass(frozen=True)
class InkMask:
    """A boolean ink mask with its panel coordinates.

    Attributes:
        ink: (H, W) bool, True where the needle marks. Row 0 is the top of the image.
        res_mm: grid pitch in mm.
        xs: (W,) panel x of each column, mm, centred on the drawing (increasing).
        ys: (H,) panel y of each row, mm, centred (decreasing: row 0 is +y).
    """

    ink: NDArray[np.bool_]
    res_mm: float
    xs: NDArray[np.float64]
    ys: NDArray[np.float64]

    @classmethod
    def centred(cls, ink: NDArray[np.bool_], res_mm: float) -> InkMask:
        """Grid coordinates as the original: ``xs = (arange(W) - W/2) * res``, ys reversed."""
        h, w = ink.shape
        xs = (np.arange(w) - w / 2) * res_mm
        ys = ((np.arange(h) - h / 2) * res_mm)[::-1].copy()
        return cls(np.asarray(ink, dtype=bool), float(res_mm), xs, ys)

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width, height) of the grid in mm."""
        h, w = self.ink.shape
        return w * self.res_mm, h * self.res_mm

    def save(self, path: Path) -> None:
        """Write as an uncompressed-safe npz (no pickles)."""
        save_npz(path, {"ink": self.ink, "res_mm": self.res_mm, "xs": self.xs, "ys": self.ys})

    @classmethod
    def load(cls, path: Path) -> InkMask:
        """Read what :meth:`save` wrote."""
        with np.load(path, allow_pickle=False) as z:
            return cls(z["ink"].astype(bool), float(z["res_mm"]), z["xs"], z["ys"])
