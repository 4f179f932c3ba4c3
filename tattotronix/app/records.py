"""What the stages from ``artwork`` to ``trajectory`` write, written in one place.

The stage scripts and the Python API's :meth:`tattotronix.app.api.Plan.save` call these
writers with the same results, and the API runs each under the provenance rules of the
stage that writes the file (:func:`tattotronix.config.tracked.as_stage`): so a plan made in
a notebook and one made by ``dvc repro`` from the same inputs are byte-identical files.

Each writer stages its file in ``out`` (:meth:`tattotronix.io.outputs.Outputs.tmp_path`)
and returns the path it lands at when ``out``'s transaction commits.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tattotronix.io.artifacts import IkRecord, ToolpathRecord, TrajectoryRecord
from tattotronix.io.outputs import Outputs

if TYPE_CHECKING:
    from tattotronix.art.artwork import Artwork
    from tattotronix.art.grid import InkMask
    from tattotronix.art.vector import VectorLines
    from tattotronix.path.plan import Toolpath
    from tattotronix.trajectory import Trajectory

__all__ = ["MM_PER_INCH", "save_artwork", "save_ik", "save_mask", "save_toolpath",
           "save_trajectory", "toolpath_record"]

MM_PER_INCH = 25.4


def save_artwork(out: Outputs, name: str, art: Artwork, lines: VectorLines
                 ) -> tuple[Path, Path]:
    """The ``artwork`` stage's raster (``artwork/<name>.png``, 8-bit grey at the grid's
    DPI) and vector lines (``artwork/<name>-lines.npz``; empty unless ``artwork.vector``);
    their paths."""
    from PIL import Image

    npz = out.path("artwork", f"{name}-lines.npz")
    lines.save(out.tmp_path(npz))
    png = out.path("artwork", f"{name}.png")
    dpi = MM_PER_INCH / art.res_mm
    Image.fromarray(art.as_uint8(), mode="L").save(out.tmp_path(png), format="PNG",
                                                   dpi=(dpi, dpi))
    return png, npz


def save_mask(out: Outputs, cfg: object, name: str, mask: InkMask, artwork_png: Path) -> Path:
    """The ``mask`` stage's ink mask (``mask/<name>.npz``), made from ``artwork_png``."""
    npz = out.path("mask", f"{name}.npz")
    mask.save(out.tmp_path(npz), out.provenance(cfg, {"artwork": artwork_png}))
    return npz


def toolpath_record(tp: Toolpath) -> ToolpathRecord:
    """The ``toolpath`` stage's record of a planned toolpath (in our drawing order)."""
    seq = tp.order.sequence
    return ToolpathRecord(
        uvz_mm=tp.path.uvz_mm, kind=tp.path.kind, xyz_m=tp.xyz_m, stroke=tp.path.stroke,
        t_s=tp.t_s, stroke_kind=tp.drawing.kinds[seq],
        stroke_region=tp.drawing.region_of[seq].astype(np.int32),
        stroke_width_mm=tp.drawing.width_mm[seq])


def save_toolpath(out: Outputs, cfg: object, name: str, tp: Toolpath,
                  inputs: Mapping[str, Path]) -> Path:
    """The ``toolpath`` stage's path (``toolpaths/<name>.npz``), planned from ``inputs``
    (``mask``, and ``lines`` in vector mode)."""
    npz = ToolpathRecord.path(out.root, name=name)
    toolpath_record(tp).save(out.tmp_path(npz), out.provenance(cfg, inputs))
    return npz


def save_ik(out: Outputs, cfg: object, name: str, joints: Sequence[str],
            q: NDArray[np.float64], tcp: NDArray[np.float64], residual: NDArray[np.float64],
            toolpath: ToolpathRecord, inputs: Mapping[str, Path]) -> Path:
    """The ``ik`` stage's joint path (``ik/<name>.npz``) of ``toolpath``, solved from
    ``inputs`` (``toolpath``, ``urdf``)."""
    npz = IkRecord.path(out.root, name=name)
    IkRecord(joints=tuple(joints), q=q, tcp=tcp, residual=residual, uvz_mm=toolpath.uvz_mm,
             xyz_m=toolpath.xyz_m, kind=toolpath.kind, stroke=toolpath.stroke).save(
        out.tmp_path(npz), out.provenance(cfg, inputs))
    return npz


def save_trajectory(out: Outputs, cfg: object, name: str, traj: Trajectory,
                    inputs: Mapping[str, Path]) -> Path:
    """The ``trajectory`` stage's timed path (``trajectories/<name>.npz``), planned from
    ``inputs`` (``ik``, ``urdf``)."""
    npz = TrajectoryRecord.path(out.root, name=name)
    traj.save(out.tmp_path(npz), out.provenance(cfg, inputs))
    return npz
