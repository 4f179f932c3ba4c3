"""The types of the plain JSON values the library reports: metrics, summaries, reports.

A ``summary()`` or ``metrics()`` returns a :data:`JsonDict`; :meth:`Outputs.write_json
<tattotronix.io.outputs.Outputs.write_json>` writes one as is. Numbers are Python (or
numpy ``float64``, a ``float``) numbers, containers are sequences and mappings with
string keys, so a type checker, not only ``json.dumps``, refuses a numpy array or an
``int64`` in a metrics file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TypeAlias

__all__ = ["JsonDict", "JsonValue"]

#: one JSON value (read-only containers: a ``list[float]`` is one)
JsonValue: TypeAlias = (
    "None | bool | int | float | str | Sequence[JsonValue] | Mapping[str, JsonValue]"
)
#: a JSON object: a metrics file, a summary, a report
JsonDict: TypeAlias = dict[str, JsonValue]
