"""Write ``.npz`` files whose bytes depend only on their arrays.

``numpy.savez_compressed`` stamps every member with the wall-clock time, so the same
arrays written twice give different bytes: DVC then sees a changed output, reruns every
stage downstream of it, and a metric that records an input's hash (the collision stage's
``trajectory_sha256``) moves with no change in the physics. :func:`save_npz` writes the
same format (a zip of ``.npy`` members, deflated) with a fixed member time, so
``numpy.load`` reads it as before and equal arrays give equal files.

:data:`READ_ERRORS` is what reading a damaged one can raise; every reader turns them into
a refusal that names the file and the stage that writes it.
"""

from __future__ import annotations

import io
import struct
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["READ_ERRORS", "save_npz"]

#: what a failed read of a damaged npz raises inside numpy, zipfile and zlib: truncated,
#: not a zip, a bad member, a corrupt deflate stream, flipped flag bits ("encrypted",
#: "compressed patched data"), a header claiming an impossible shape
READ_ERRORS: tuple[type[Exception], ...] = (
    OSError, EOFError, ValueError, KeyError, IndexError, RuntimeError, NotImplementedError,
    OverflowError, MemoryError, struct.error, zipfile.BadZipFile, zlib.error)

#: the member time of every file (the earliest a zip can hold)
_EPOCH = (1980, 1, 1, 0, 0, 0)


def save_npz(file: str | Path, arrays: Mapping[str, ArrayLike]) -> None:
    """Write ``arrays`` to ``file`` as a compressed npz, byte-for-byte reproducible.

    Arrays are stored without pickling (``numpy.load(..., allow_pickle=False)`` reads
    them); members are written in the order given.
    """
    with zipfile.ZipFile(file, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key, value in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            # the member is made in memory and written with its sizes known: a streamed
            # member (``zf.open(..., force_zip64=True)``, as numpy.savez) gets a local
            # header that CPython changed in 3.11.4, so Debian's 3.11.2 wrote other bytes
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(value), allow_pickle=False)
            zf.writestr(info, buf.getbuffer())
