"""What the artwork and mask stages stored for one artwork, read back for the stages that
plan from it (``toolpath``, ``fills``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tattotronix.art.grid import InkMask
from tattotronix.art.vector import VectorLines
from tattotronix.io.outputs import Outputs

__all__ = ["StoredArtwork", "stored_artwork"]


@dataclass(frozen=True)
class StoredArtwork:
    """What the artwork and mask stages stored for one artwork (:func:`stored_artwork`).

    Attributes:
        mask: the ink mask. vector: the SVG's own lines (``artwork.vector``), or None.
        inputs: the files read, by role (``mask``, ``lines``), for the provenance.
    """

    mask: InkMask
    vector: VectorLines | None
    inputs: dict[str, Path]


def stored_artwork(out: Outputs, name: str, vector: bool) -> StoredArtwork:
    """The mask stage's ``data/mask/<name>.npz`` and, with ``vector`` (``artwork.vector``),
    the artwork stage's ``data/artwork/<name>-lines.npz``.

    Raises:
        TattotronixError: a file is missing or corrupt (naming it and the stage to run).
    """
    inputs = {"mask": out.require(out.input("mask", f"{name}.npz"), "mask")}
    mask = InkMask.load(inputs["mask"])
    lines = None
    if vector:  # the SVG's own lines, from the artwork stage
        inputs["lines"] = out.require(out.input("artwork", f"{name}-lines.npz"), "artwork")
        lines = VectorLines.load(inputs["lines"])
    return StoredArtwork(mask, lines, inputs)
