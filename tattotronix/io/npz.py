"""Write ``.npz`` files whose bytes depend only on their arrays.

``numpy.savez_compressed`` stamps every member with the wall-clock time, so the same
arrays written twice give different bytes: DVC then sees a changed output, reruns every
stage downstream of it, and a metric that records an input's hash (the collision stage's
``trajectory_sha256``) moves with no change in the physics. :func:`save_npz` writes the
same format (a zip of ``.npy`` members, deflated) with a fixed member time, so
``numpy.load`` reads it as before and equal arrays give equal files.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["save_npz"]

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
            with zf.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
