"""Convex collision shapes of the links: mesh hulls, or committed k-DOP polytopes.

With ``robot.cad_dir`` set, a link collides as the convex hull of its CAD mesh (coal's
qhull). A convex hull encloses the mesh, so a clearance measured on hulls is a lower bound
on the true one; and convex-convex distance (GJK) costs microseconds where mesh-mesh
distance on the raw triangle soups costs tens of milliseconds.

A fresh clone has no meshes, and the links' bounding boxes (``robot.box``) are too coarse:
at the zero pose the upper arm's box and the wrist's overlap by 2.1 mm though the meshes
are 8 mm apart. So the fallback geometry is a **k-DOP** per link: the polytope bounded by
``k`` planes whose normals are fixed (:func:`directions`, a Fibonacci sphere) and whose
offsets are the mesh's extreme extent along each normal, rounded outward. It encloses the
mesh exactly as the bounding box does (the box is the 6-DOP) but far more tightly. The
offsets are derived data, like the printed inertial table: ``python -m
tattotronix.devtools.tables kdops --cad-dir ../shared/cad/meshes --write`` regenerates
:data:`KDOP_FILE`, and a test holds the committed file to the meshes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.robot.stl import mesh_dir_files, read_stl

__all__ = ["KDOP_DIRECTIONS", "KDOP_FILE", "KDOP_ROUND_M", "directions", "kdop_offsets",
           "kdop_vertices", "load_kdops", "mesh_vertices", "write_kdops"]

Array = NDArray[np.float64]
#: the committed k-DOP offsets of each link (m, link frame), generated from the CAD meshes
KDOP_FILE = Path(__file__).with_name("kdop.json")
#: planes per k-DOP
KDOP_DIRECTIONS = 128
KDOP_ROUND_M = 1e-5  # offsets are rounded up to 0.01 mm, so the polytope still encloses


def directions(k: int = KDOP_DIRECTIONS) -> Array:
    """``k`` unit normals spread evenly over the sphere (a Fibonacci lattice), (k, 3)."""
    if k < 4:
        raise TattotronixError(f"a k-DOP needs at least 4 directions, got {k}")
    i = np.arange(k) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / k)
    azimuth = math.pi * (1.0 + math.sqrt(5.0)) * i
    return np.column_stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar),
                            np.cos(polar)])


def mesh_vertices(stl: str | Path, scale: float | Iterable[float]) -> Array:
    """The unique vertices of a binary STL, scaled to metres, (m, 3)."""
    pts = read_stl(stl).reshape(-1, 3) * np.asarray(scale, dtype=np.float64)
    return np.unique(pts, axis=0)


def kdop_offsets(points: Array, k: int = KDOP_DIRECTIONS) -> Array:
    """The extent of ``points`` along each of the ``k`` directions, rounded outward, (k,)."""
    ext = (np.asarray(points, dtype=np.float64) @ directions(k).T).max(axis=0)
    return np.ceil(ext / KDOP_ROUND_M) * KDOP_ROUND_M


def kdop_vertices(offsets: Array) -> Array:
    """The corners of the polytope ``{x : d_i . x <= offsets_i}``, (m, 3).

    Raises:
        TattotronixError: the offsets bound no solid (a corrupt table).
    """
    from scipy.spatial import HalfspaceIntersection, QhullError

    off = np.asarray(offsets, dtype=np.float64)
    d = directions(len(off))
    centre = _interior(d, off)
    try:
        hs = HalfspaceIntersection(np.column_stack([d, -off]), centre)
    except QhullError as exc:
        raise TattotronixError(f"k-DOP offsets bound no solid: {exc}") from None
    return np.asarray(hs.intersections, dtype=np.float64)


def _interior(d: Array, off: Array) -> Array:
    """A point strictly inside ``{x : d x <= off}``: the Chebyshev centre (a small LP)."""
    from scipy.optimize import linprog

    norms = np.linalg.norm(d, axis=1)
    res = linprog(c=[0, 0, 0, -1], A_ub=np.column_stack([d, norms]), b_ub=off,
                  bounds=[(None, None)] * 3 + [(0, None)], method="highs")
    if not res.success or res.x[3] <= 0:
        raise TattotronixError("k-DOP offsets bound no solid (empty polytope)")
    return np.asarray(res.x[:3], dtype=np.float64)


def load_kdops(file: str | Path = KDOP_FILE) -> dict[str, Array]:
    """``{link: offsets (k,) m}`` from the committed table (empty when there is none).

    Raises:
        TattotronixError: the file is not a k-DOP table.
    """
    path = Path(file)
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
        k = int(data["directions"])
        out = {str(link): np.asarray(v, dtype=np.float64) for link, v in data["links"].items()}
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise TattotronixError(f"{path} is not a k-DOP table: {exc}") from None
    for link, v in out.items():
        if v.shape != (k,) or not np.all(np.isfinite(v)):
            raise TattotronixError(f"{path}: link {link} needs {k} finite offsets")
    return out


def write_kdops(cad_dir: str | Path, links: Iterable[str], scale: float,
                file: str | Path = KDOP_FILE, k: int = KDOP_DIRECTIONS) -> dict[str, Array]:
    """Compute every link's k-DOP from its mesh and write the table (JSON, mm-rounded m)."""
    files = mesh_dir_files(cad_dir, list(links))
    table = {link: kdop_offsets(mesh_vertices(f, scale), k) for link, f in files.items()}
    doc = {"generated_by": "python -m tattotronix.devtools.tables kdops --cad-dir DIR --write",
           "units": "m, link frame", "directions": k,
           "links": {link: [round(float(v), 5) for v in off] for link, off in table.items()}}
    Path(file).write_text(json.dumps(doc, indent=1) + "\n")
    return table
