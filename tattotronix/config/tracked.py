"""The params DVC tracks for a stage.

A stage run by ``dvc repro`` reruns exactly when its command, its deps or its own params
change. Its outputs must therefore depend on nothing else, or a clean clone writes other
bytes than the committed ``dvc.lock`` says, and a cached result carries a config it was
not made with. The provenance every artifact records holds the config, so under DVC the
stage runner records only the stage's ``params`` (:func:`tracked_params`) and the keys
its command overrides (:func:`override_keys`); what upstream stages were run with comes
with their outputs, from the provenance those record
(:func:`tattotronix.io.provenance.provenance_json`).

``dvc.yaml`` is read as DVC reads it, for the parts this project uses: ``vars`` given
inline, ``${...}`` interpolation from ``params.yaml`` and the vars, and ``foreach`` over a
mapping or a list (``name@key``). A ``dvc.yaml`` using anything else (``matrix``, vars
files) is refused by name rather than half-read.
"""

from __future__ import annotations

import json
import posixpath
import re
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from tattotronix.errors import ConfigError
from tattotronix.io.codegraph import write_stamp_folder
from tattotronix.io.outputs import override_key
from tattotronix.io.provenance import fixed_code_version, recorded_keys

__all__ = ["DVC_FILE", "PARAM_STAMPS", "as_stage", "definition_params", "override_keys",
           "param_stamps", "stage_names", "tracked_params", "write_param_stamps"]

#: the pipeline file, at the project root
DVC_FILE = "dvc.yaml"
#: where the param stamps go, under ``paths.data``
PARAM_STAMPS = "params"

_REF = re.compile(r"\$\{\s*([^}\s]+)\s*\}")


def _lookup(context: Mapping[str, Any], ref: str, where: str) -> Any:
    value: Any = context
    for part in ref.split("."):
        if not isinstance(value, Mapping) or part not in value:
            raise ConfigError(f"{DVC_FILE}: {where}: ${{{ref}}} names nothing in params.yaml "
                              "or the vars")
        value = value[part]
    return value


def _interpolate(value: Any, context: Mapping[str, Any], where: str) -> Any:
    """``value`` with every ``${ref}`` resolved; a string that is one reference keeps the
    referenced value's type (as DVC does: ``foreach: ${artworks}`` is a mapping)."""
    if isinstance(value, str):
        whole = _REF.fullmatch(value.strip())
        if whole:
            return _lookup(context, whole.group(1), where)
        return _REF.sub(lambda m: str(_lookup(context, m.group(1), where)), value)
    if isinstance(value, list):
        return [_interpolate(v, context, where) for v in value]
    if isinstance(value, dict):
        return {_interpolate(k, context, where): _interpolate(v, context, where)
                for k, v in value.items()}
    return value


def _params(entries: Any, where: str) -> list[str]:
    out: list[str] = []
    for entry in entries or []:
        if isinstance(entry, str):
            out.append(entry)
        elif isinstance(entry, Mapping):
            for file, keys in entry.items():
                if posixpath.basename(str(file)) != "params.yaml":
                    raise ConfigError(f"{DVC_FILE}: {where}: params from {file}; only "
                                      "params.yaml is read")
                out += [str(k) for k in keys or []]
        else:
            raise ConfigError(f"{DVC_FILE}: {where}: a param is a key, not {entry!r}")
    return out


def _listed(body: Mapping[str, Any]) -> Any:
    """A stage's params: DVC's own ``params:`` or, stamped, ``meta: {params: ...}``."""
    meta = body.get("meta")
    stamped = meta.get("params") if isinstance(meta, Mapping) else None
    return [*(body.get("params") or []), *(stamped or [])]


def _stage_params(doc: Mapping[str, Any], params: Mapping[str, object]) -> dict[str, list[str]]:
    """Every stage's own params, by name (``name@key`` for each item of a ``foreach``)."""
    context: dict[str, Any] = dict(params)
    for entry in doc.get("vars") or []:
        if not isinstance(entry, Mapping):
            raise ConfigError(f"{DVC_FILE}: vars entry {entry!r}: only inline vars are read")
        context.update(entry)
    stages: dict[str, list[str]] = {}
    for name, body in (doc.get("stages") or {}).items():
        if not isinstance(body, Mapping) or "matrix" in body:
            raise ConfigError(f"{DVC_FILE}: stage {name}: only plain and foreach stages "
                              "are read")
        if "foreach" not in body:
            stages[str(name)] = _params(_interpolate(_listed(body), context, name), name)
            continue
        items = _interpolate(body["foreach"], context, str(name))
        pairs = items.items() if isinstance(items, Mapping) else ((v, v) for v in items)
        for key, item in pairs:
            full = f"{name}@{key}"
            ctx = {**context, "key": key, "item": item}
            stages[full] = _params(_interpolate(_listed(body["do"]), ctx, full), full)
    return stages


def _read(root: Path) -> Mapping[str, Any]:
    file = root / DVC_FILE
    try:
        # libyaml's loader where the wheel has it: every stage run by DVC reads the file
        doc = yaml.load(file.read_text(encoding="utf-8"), Loader=_LOADER)
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"cannot read {file}: {exc}") from None
    return doc if isinstance(doc, Mapping) else {}


_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def tracked_params(stage: str, root: Path, params: Mapping[str, object]) -> tuple[str, ...]:
    """The params ``dvc.yaml`` lists for ``stage`` (``name`` or ``name@key``, as
    ``DVC_STAGE`` names it).

    Args:
        stage: the stage's name.
        root: the folder of ``dvc.yaml``.
        params: ``params.yaml``'s values (for ``${paths.data}`` and the like).

    Raises:
        ConfigError: no ``dvc.yaml``, no such stage, or a form of it this reader refuses.
    """
    stages = _stage_params(_read(root), params)
    name = stage.rsplit(":", 1)[-1]  # "sub/dvc.yaml:name" when run from elsewhere
    if name not in stages:
        raise ConfigError(f"{root / DVC_FILE} has no stage {name!r} (DVC_STAGE)")
    return tuple(stages[name])


def definition_params(definition: str, root: Path, params: Mapping[str, object]
                      ) -> tuple[str, ...]:
    """The params ``dvc.yaml`` lists for the stage ``definition`` (a plain stage, or any item
    of a ``foreach``: its items list the same).

    Raises:
        ConfigError: as :func:`tracked_params`, or no such stage.
    """
    stages = _stage_params(_read(root), params)
    for name, keys in stages.items():
        if name.split("@")[0] == definition:
            return tuple(keys)
    raise ConfigError(f"{root / DVC_FILE} has no stage {definition!r}")


@contextmanager
def as_stage(keys: Sequence[str], overrides: Sequence[str], version: str | None
             ) -> Iterator[None]:
    """Within the block, every provenance records what a DVC stage's does: the params it
    tracks (``keys``) and those its command line sets (``overrides``), and the code
    ``version`` (its stamp's; None: as computed now). The stage runner runs each stage
    body in it, and the Python API each step of a plan it saves, so both write the same
    bytes from the same inputs."""
    with recorded_keys((*keys, *override_keys(overrides))), fixed_code_version(version):
        yield


def stage_names(root: Path, params: Mapping[str, object] | None = None) -> list[str]:
    """Every stage of ``root/dvc.yaml`` as DVC names it (``name@key`` for foreach items);
    ``params`` is ``params.yaml``'s values (read from ``root`` if None)."""
    if params is None:
        params = _params_yaml(root)
    return list(_stage_params(_read(root), params))


def param_stamps(root: Path, params: Mapping[str, object] | None = None) -> dict[str, str]:
    """stage -> its param stamp: the JSON of the values of the params ``meta: {params:
    ...}`` lists for it in ``root/dvc.yaml`` (a foreach stage's items share one), from
    ``params`` (``params.yaml``'s values, read from ``root`` if None).

    A stage depends on its stamp (``<paths.data>/params/<stage>.json``) instead of listing
    its params for DVC, which would parse the whole ``params.yaml`` once per stage on every
    ``dvc status`` and ``dvc repro`` and record every value in ``dvc.lock``.
    """
    from tattotronix.io.provenance import only_keys

    if params is None:
        params = _params_yaml(root)
    doc = _read(root)
    out: dict[str, str] = {}
    for name, keys in _stage_params(doc, params).items():
        definition = name.split("@")[0]
        body = (doc.get("stages") or {}).get(definition) or {}
        body = body.get("do", body)
        meta = body.get("meta")
        if not isinstance(meta, Mapping) or "params" not in meta:
            continue
        text = json.dumps(only_keys(params, keys), sort_keys=True, indent=1) + "\n"
        if out.setdefault(definition, text) != text:
            raise ConfigError(f"{DVC_FILE}: the items of stage {definition} track different "
                              "params; a param stamp is one per stage")
    return out


def write_param_stamps(folder: Path, root: Path,
                       params: Mapping[str, object] | None = None) -> list[str]:
    """Write every stage's param stamp into ``folder`` (:func:`write_stamp_folder`); the
    stages whose stamp changed."""
    return write_stamp_folder(folder, param_stamps(root, params), ".json")


def _params_yaml(root: Path) -> Mapping[str, object]:
    try:
        loaded = yaml.load((root / "params.yaml").read_text(encoding="utf-8"), Loader=_LOADER)
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"cannot read {root / 'params.yaml'}: {exc}") from None
    return loaded if isinstance(loaded, Mapping) else {}


def override_keys(overrides: Sequence[str]) -> tuple[str, ...]:
    """The keys a command line's ``key=value`` overrides set (``+``/``~``/``++`` dropped)."""
    return tuple(override_key(o) for o in overrides if "=" in o)
