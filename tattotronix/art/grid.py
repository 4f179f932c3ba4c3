"""The ink mask on its grid: the contract between the ``mask`` and ``toolpath`` stages."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.art.place import Placement
from tattotronix.errors import StageInputMissing, TattotronixError
from tattotronix.io.npz import READ_ERRORS, save_npz
from tattotronix.io.provenance import PROVENANCE_KEY

__all__ = ["InkMask"]


@dataclass(frozen=True)
class InkMask:
    """A boolean ink mask with its panel coordinates.

    Attributes:
        ink: (H, W) bool, True where the needle marks. Row 0 is the top of the image.
        res_mm: grid pitch in mm.
        xs: (W,) panel x of each column, mm (increasing); centred on the drawing unless
            it was placed elsewhere.
        ys: (H,) panel y of each row, mm (decreasing: row 0 is +y).
        place: how the artwork's centred grid was put on the panel
            (:mod:`tattotronix.art.place`; the vector lines follow it).
    """

    ink: NDArray[np.bool_]
    res_mm: float
    xs: NDArray[np.float64]
    ys: NDArray[np.float64]
    place: Placement = Placement()

    @classmethod
    def centred(cls, ink: NDArray[np.bool_], res_mm: float) -> InkMask:
        """Grid coordinates as the original: ``xs = (arange(W) - W/2) * res``, ys reversed."""
        h, w = ink.shape
        xs = (np.arange(w) - w / 2) * res_mm
        ys = ((np.arange(h) - h / 2) * res_mm)[::-1].copy()
        return cls(np.asarray(ink, dtype=bool), float(res_mm), xs, ys)

    @cached_property
    def background_runs(self) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
        """Prefix counts of the background, for counting it along any run of a row or column.

        ``(col_runs, row_runs)``: ``col_runs[k, c]`` is the number of background pixels in
        column ``c`` above row ``k``, (H + 1, W); ``row_runs[k, r]`` the number in row
        ``r`` left of column ``k``, (W + 1, H). Computed once per mask.
        """
        bg = (~self.ink).astype(np.int32)
        h, w = bg.shape
        col_runs = np.zeros((h + 1, w), np.int32)
        np.cumsum(bg, axis=0, out=col_runs[1:])
        row_runs = np.zeros((w + 1, h), np.int32)
        np.cumsum(bg.T, axis=0, out=row_runs[1:])
        return col_runs, row_runs

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width, height) of the grid in mm."""
        h, w = self.ink.shape
        return w * self.res_mm, h * self.res_mm

    def save(self, path: Path, provenance: str | None = None) -> None:
        """Write as an npz (no pickles), with ``provenance``
        (:func:`tattotronix.io.artifacts.make_provenance`) when given."""
        arrays: dict[str, ArrayLike] = {"ink": self.ink, "res_mm": self.res_mm, "xs": self.xs,
                                        "ys": self.ys, "place": self.place.as_array()}
        if provenance is not None:
            arrays[PROVENANCE_KEY] = np.array(provenance)
        save_npz(path, arrays)

    @classmethod
    def load(cls, path: Path) -> InkMask:
        """Read what :meth:`save` wrote (``data/mask/<name>.npz``).

        Raises:
            TattotronixError: the file is missing (run the ``mask`` stage), or truncated,
                corrupt or not a mask (re-run it); the message names the file.
        """
        def refuse(why: str) -> TattotronixError:
            return TattotronixError(f"cannot read {path} ({why}): re-run the 'mask' stage")

        try:
            loaded = np.load(path, allow_pickle=False)
            if not isinstance(loaded, np.lib.npyio.NpzFile):
                raise refuse("not an npz archive")
            with loaded as z:
                missing = [k for k in ("ink", "res_mm", "xs", "ys") if k not in z.files]
                if missing:
                    raise refuse(f"missing {', '.join(missing)}")
                ink, res, xs, ys = z["ink"], z["res_mm"], z["xs"], z["ys"]
                place = z["place"] if "place" in z.files else np.zeros(3)
        except TattotronixError:
            raise
        except FileNotFoundError:
            raise StageInputMissing(Path(path), "mask") from None
        except READ_ERRORS as exc:
            raise refuse(f"{type(exc).__name__}: {exc}") from None
        if (ink.ndim != 2 or ink.dtype.kind not in "biu" or res.size != 1
                or res.dtype.kind not in "iuf" or xs.shape != (ink.shape[1],)
                or ys.shape != (ink.shape[0],) or xs.dtype.kind != "f"
                or ys.dtype.kind != "f"):
            raise refuse(f"ink {ink.shape} {ink.dtype}, res_mm {res.shape}, xs {xs.shape}, "
                         f"ys {ys.shape}: not a mask grid")
        res_mm = float(res)
        if not (math.isfinite(res_mm) and res_mm > 0 and np.all(np.isfinite(xs))
                and np.all(np.isfinite(ys))):
            raise refuse(f"res_mm={res_mm:g} or its coordinates are not finite and positive")
        if place.shape != (3,) or place.dtype.kind != "f" or not np.all(np.isfinite(place)):
            raise refuse(f"place {place.shape} {place.dtype}: not [rotate_deg, u, v]")
        return cls(ink.astype(bool), res_mm, xs, ys, Placement.from_array(place))
