"""Binary STL reading (numpy only) and the per-link mesh directory.

A binary STL is an 80-byte header, a little-endian ``uint32`` triangle count and one
50-byte record per triangle: the facet normal (3 x float32, ignored here: orientation is
taken from the vertex order), three vertices (3 x 3 x float32) and a ``uint16`` attribute.
The file size is therefore exactly ``84 + 50 N``; anything else is refused.

Units are whatever the file holds (the TATTOTRONIX CAD meshes are in centimetres); the
caller scales (``robot.mesh_scale``).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from tattotronix.config.params import PROJECT_ROOT
from tattotronix.errors import TattotronixError

__all__ = ["HEADER_BYTES", "RECORD_DTYPE", "mesh_dir_files", "read_stl", "write_stl"]

HEADER_BYTES = 80
#: One 50-byte binary STL record (little-endian, packed).
RECORD_DTYPE = np.dtype(
    [("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")]
)
assert RECORD_DTYPE.itemsize == 50


def _looks_ascii(data: bytes) -> bool:
    """True when the bytes read like an ASCII STL (``solid`` ... ``facet`` ... text)."""
    head = data[:1024].lstrip()
    if not head[:5].lower() == b"solid":
        return False
    try:
        text = head.decode("ascii")
    except UnicodeDecodeError:
        return False
    return "facet" in text.lower() or "endsolid" in text.lower()


def read_stl(path: str | Path) -> np.ndarray:
    """Read the triangles of a binary STL file.

    Args:
        path: the ``.stl`` file.

    Returns:
        Triangles, shape ``(N, 3, 3)`` float64: triangle, vertex, coordinate, in the
        file's own units.

    Raises:
        TattotronixError: the file is missing, is an ASCII STL, is truncated or padded
            (its size is not ``84 + 50 N``), or holds no triangles.
    """
    path = Path(path)
    if not path.is_file():
        raise TattotronixError(f"STL file not found: {path}")
    data = path.read_bytes()
    if len(data) < HEADER_BYTES + 4:
        if _looks_ascii(data):
            raise TattotronixError(
                f"{path} is an ASCII STL; only binary STL is read (re-export it as binary)"
            )
        raise TattotronixError(
            f"{path} is not a binary STL: {len(data)} bytes, shorter than the 84-byte "
            "header and triangle count (empty or truncated file)"
        )
    count = int(np.frombuffer(data, dtype="<u4", count=1, offset=HEADER_BYTES)[0])
    expected = HEADER_BYTES + 4 + RECORD_DTYPE.itemsize * count
    if len(data) != expected:
        if _looks_ascii(data):
            raise TattotronixError(
                f"{path} is an ASCII STL; only binary STL is read (re-export it as binary)"
            )
        raise TattotronixError(
            f"{path} is truncated or corrupt: its header declares {count} triangles "
            f"({expected} bytes) but the file has {len(data)} bytes"
        )
    if count == 0:
        raise TattotronixError(f"{path} holds zero triangles")
    records = np.frombuffer(data, dtype=RECORD_DTYPE, count=count, offset=HEADER_BYTES + 4)
    tri = records["vertices"].astype(np.float64)
    if not np.all(np.isfinite(tri)):
        raise TattotronixError(f"{path} has non-finite vertex coordinates (corrupt file)")
    return tri


def write_stl(path: str | Path, triangles: np.ndarray, header: bytes = b"") -> Path:
    """Write triangles ``(N, 3, 3)`` as a binary STL (normals from the vertex order).

    Args:
        path: the file to write.
        triangles: triangle vertices, any units (stored as float32).
        header: up to 80 bytes of header text.

    Returns:
        The path written.
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    rec = np.zeros(len(tri), dtype=RECORD_DTYPE)
    rec["normal"] = n
    rec["vertices"] = tri
    head = header[:HEADER_BYTES].ljust(HEADER_BYTES, b"\0")
    path = Path(path)
    path.write_bytes(head + np.uint32(len(tri)).astype("<u4").tobytes() + rec.tobytes())
    return path


def resolve_cad_dir(cad_dir: str | Path) -> Path:
    """A CAD directory; a relative one is taken from the project root (beside ``conf/``)."""
    path = Path(cad_dir).expanduser()
    return (path if path.is_absolute() else PROJECT_ROOT / path).resolve()


def mesh_dir_files(cad_dir: str | Path, links: Iterable[str]) -> dict[str, Path]:
    """The mesh file ``<link>.stl`` of every link in ``cad_dir``.

    Args:
        cad_dir: the directory of the per-link STL meshes.
        links: link names, in the order wanted.

    Returns:
        ``{link: path}`` in the order of ``links``.

    Raises:
        TattotronixError: the directory is missing, or one or more meshes are absent
            (the message lists every missing file and the directory).
    """
    root = Path(cad_dir)
    if not root.is_dir():
        raise TattotronixError(
            f"CAD mesh directory not found: {root} (set robot.cad_dir to the folder of "
            "per-link STL meshes, or null to use the committed inertial table)"
        )
    files = {link: root / f"{link}.stl" for link in links}
    missing = [p.name for p in files.values() if not p.is_file()]
    if missing:
        raise TattotronixError(
            f"CAD mesh directory {root} lacks {len(missing)} mesh(es): "
            + ", ".join(missing)
            + " (one <link>.stl per link is required)"
        )
    return files
