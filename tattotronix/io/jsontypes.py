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

__all__ = ["JsonDict", "JsonValue", "json_floats", "json_number", "json_object"]

#: one JSON value (read-only containers: a ``list[float]`` is one)
JsonValue: TypeAlias = (
    "None | bool | int | float | str | Sequence[JsonValue] | Mapping[str, JsonValue]"
)
#: a JSON object: a metrics file, a summary, a report
JsonDict: TypeAlias = dict[str, JsonValue]


def json_number(value: JsonValue) -> float:
    """A number read back from a JSON value (a metric to print).

    Raises:
        TypeError: the value is not a number.
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"expected a number, got {value!r}")
    return float(value)


def json_floats(value: JsonValue) -> list[float]:
    """A list of numbers read back from a JSON value.

    Raises:
        TypeError: the value is not a sequence of numbers.
    """
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise TypeError(f"expected a list of numbers, got {value!r}")
    return [json_number(v) for v in value]


def json_object(value: JsonValue) -> Mapping[str, JsonValue]:
    """A JSON object read back from a JSON value.

    Raises:
        TypeError: the value is not an object.
    """
    if not isinstance(value, Mapping):
        raise TypeError(f"expected an object, got {value!r}")
    return value
