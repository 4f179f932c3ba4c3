"""Compose ``conf/`` into ``params.yaml``, and refuse to run on a stale one.

DVC composes ``conf/`` only in ``dvc exp run``, never in ``dvc repro`` (by design in DVC;
README, "Configuration"). So ``params.yaml`` can silently fall behind an edit under
``conf/``. We close that gap from both sides:

* the ``config`` stage depends on ``conf/`` and runs first; under ``dvc repro`` it
  recomposes ``conf/`` and stops, naming the keys that differ, when ``params.yaml`` is
  stale (``dvc exp run`` recomposes it itself, so there it has nothing to do);
* every stage run by DVC makes the same check before it reads ``params.yaml``, unless
  the gate's ``config.hash`` holds the hash of these very bytes of ``conf/`` and
  ``params.yaml`` (then the gate has checked them, and composing ``conf/`` again would
  only cost time).

``tattotronix-params`` (``python -m tattotronix.config.params``) rewrites ``params.yaml``;
``--check`` only compares. Both first refuse a ``conf/`` whose composition has a key out
of its range (:func:`to_settings`).
"""

from __future__ import annotations

import argparse
import functools
import os
import re
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from tattotronix.config.schema import Config, NotExact, Plain, build_exact, out_of_range, to_dict
from tattotronix.errors import ConfigError

__all__ = [
    "PROJECT_ROOT",
    "StaleParamsError",
    "compose",
    "compose_settings",
    "diff",
    "hand_settings",
    "load_params",
    "load_settings",
    "main",
    "one_line",
    "params_text",
    "stale_message",
    "to_settings",
    "with_overrides",
]

PROJECT_ROOT = Path(__file__).resolve().parents[2]
CONF_DIR = PROJECT_ROOT / "conf"
PARAMS_FILE = "params.yaml"
RECOMPOSE_HINT = "tattotronix-params  (or: python -m tattotronix.config.params)"


class StaleParamsError(ConfigError):
    """``params.yaml`` does not equal the composition of ``conf/``."""


#: lines of Hydra's and OmegaConf's messages that say nothing to the user
_NOISE = ("full_key:", "reference_type=", "object_type=", "See https://", "Set the environment",
          "To append to your config", "LexerNoViableAltException", "Error parsing override")
#: a message template OmegaConf keeps in the chain beside its formatted copy
_TEMPLATE = re.compile(r"\$[A-Z_]+")


def one_line(exc: BaseException) -> str:
    """A Hydra/OmegaConf error chain as one line: each distinct message once, without
    OmegaConf's unformatted templates (``Value '$VALUE' ...``) or its detail lines, with the
    key it names (``full_key``); a listing (Hydra's available options) is joined by commas."""
    parts: list[str] = []
    key = ""
    cur: BaseException | None = exc
    seen: set[int] = set()
    while cur is not None and id(cur) not in seen:
        seen.add(id(cur))
        listing = False
        for ln in (ln.strip() for ln in str(cur).splitlines()):
            if ln.startswith("Config search path"):
                break
            if ln.startswith("full_key:"):
                key = key or ln.split(":", 1)[1].strip()
            if (not ln or ln == "None" or ln.startswith(_NOISE) or _TEMPLATE.search(ln)
                    or set(ln) <= {"^", " "}):
                continue
            if listing:
                parts[-1] += (" " if parts[-1].endswith(":") else ", ") + ln
            elif not any(ln in p for p in parts):
                parts.append(ln)
                listing = ln.endswith(":")
        cur = cur.__cause__ or cur.__context__
    text = "; ".join(p.rstrip(".") for p in parts) or type(exc).__name__
    override = getattr(exc, "override", None)  # Hydra's OverrideParseException
    if isinstance(override, str) and override not in text:
        text = f"cannot parse the override {override!r}: {text}"
    if key and key not in text:
        text += f" (key {key})"
    return text


def _root_cause(exc: BaseException) -> str:
    """The Hydra/OmegaConf error chain as one line that names the key (:func:`one_line`)."""
    return one_line(exc)


def compose(
    overrides: Sequence[str] = (), conf_dir: Path = CONF_DIR, config_name: str = "config"
) -> DictConfig:
    """Compose ``conf/`` with Hydra override strings, validated against the schemas.

    Raises:
        ConfigError: a key is unknown or a value has the wrong type or is not allowed.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from tattotronix.config.schema import register

    register()
    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(str(Path(conf_dir).resolve()), version_base="1.3"):
            cfg = hydra_compose(config_name=config_name, overrides=list(overrides))
    except Exception as exc:  # Hydra wraps the OmegaConf error that names the key
        raise ConfigError(f"bad configuration: {_root_cause(exc)}") from None
    return cfg


def to_settings(cfg: DictConfig) -> Config:
    """The typed settings of a composed config: a frozen :class:`~.schema.Config`.

    The stage runner calls this once per run; the library takes the result (or a
    section of it), never the ``DictConfig``.

    Every numeric key is checked against the range its schema field declares
    (:func:`tattotronix.config.schema.out_of_range`), so no stage starts work on a value
    it cannot use.

    Raises:
        ConfigError: a key is unknown, missing, or has a value of the wrong type or out of
            its range (the message names the full key, the value and the range).
    """
    try:  # exactly, when every value has its field's type (:func:`~.schema.build_exact`)
        plain = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
        exact: Config | None = build_exact(Config, plain)
    except NotExact:
        exact = None
    except Exception as exc:
        raise ConfigError(f"bad configuration: {_root_cause(exc)}") from None
    if exact is not None:
        return _checked(exact)
    try:  # OmegaConf's way: it converts a value, or refuses it with its message
        typed = cfg if OmegaConf.get_type(cfg) is Config else OmegaConf.merge(
            OmegaConf.structured(Config), OmegaConf.to_container(cfg, resolve=True))
        obj = OmegaConf.to_object(typed)
    except Exception as exc:
        raise ConfigError(f"bad configuration: {_root_cause(exc)}") from None
    assert isinstance(obj, Config)
    return _checked(obj)


def _checked(obj: Config) -> Config:
    """``obj`` if every numeric key is within its range, else :class:`ConfigError`."""
    problems = out_of_range(obj)
    if problems:
        raise ConfigError("; ".join(problems))
    return obj


@functools.cache
def _yaml_loader() -> type:
    """OmegaConf's YAML rules (a float needs no dot: ``1e-3``; no timestamps) on
    libyaml's parser where it is built: ``params.yaml`` in 20 ms instead of 300."""
    import yaml
    from omegaconf._utils import get_yaml_loader

    rules = get_yaml_loader()
    base = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    return type("_ParamsLoader", (base,), {
        "yaml_implicit_resolvers": rules.yaml_implicit_resolvers,
        "construct_mapping": _unique_keys_mapping})


def _unique_keys_mapping(loader: Any, node: Any, deep: bool = False) -> Any:
    """A YAML mapping that refuses a repeated key (as OmegaConf's loader does)."""
    import yaml

    scalar = yaml.resolver.BaseResolver.DEFAULT_SCALAR_TAG
    keys = [k.value for k, _ in node.value if k.tag == scalar]
    if len(keys) != len(set(keys)):
        raise NotExact("a repeated key")
    return yaml.constructor.SafeConstructor.construct_mapping(loader, node, deep=deep)


def _yaml_scalar(text: str) -> object:
    """A dotlist value as :meth:`OmegaConf.from_dotlist` reads it; a mapping is not
    taken (it would merge into the key's mapping, which is OmegaConf's to do)."""
    import yaml

    try:
        value = yaml.load(text, Loader=_yaml_loader())
    except (yaml.YAMLError, NotExact):
        raise NotExact(text) from None
    if isinstance(value, dict):
        raise NotExact(text)
    return value


def _set_existing(plain: dict[str, Plain], key: str, value: object) -> None:
    """Set dotted ``key`` in ``plain``, where every part of it is already a key."""
    *parents, last = key.split(".")
    node: object = plain
    for part in parents:
        node = node.get(part) if isinstance(node, dict) else None
    if not isinstance(node, dict) or last not in node or isinstance(node[last], dict):
        raise NotExact(key)
    node[last] = value


def with_overrides(cfg: Config, overrides: Sequence[str]) -> Config:
    """``cfg`` with dotted ``key=value`` overrides applied (a study's case from the stage's
    settings), checked as :func:`to_settings` checks.

    Raises:
        ConfigError: an unknown key, or a value of the wrong type or out of range.
    """
    try:  # the exact way when every value has its field's type already (milliseconds)
        plain = to_dict(cfg)
        for item in overrides:
            key, sep, text = item.partition("=")
            if not sep:
                raise NotExact(item)
            _set_existing(plain, key, _yaml_scalar(text))
        exact: Config | None = build_exact(Config, plain)
    except NotExact:
        exact = None  # OmegaConf's way: it converts the value, or refuses it with its message
    if exact is not None:
        return _checked(exact)
    try:
        merged = OmegaConf.merge(OmegaConf.structured(Config), to_dict(cfg),
                                 OmegaConf.from_dotlist(list(overrides)))
    except Exception as exc:
        raise ConfigError(f"bad configuration: {_root_cause(exc)}") from None
    assert isinstance(merged, DictConfig)
    return to_settings(merged)


def compose_settings(overrides: Sequence[str] = (), conf_dir: Path = CONF_DIR) -> Config:
    """:func:`compose` then :func:`to_settings`: the settings of ``conf/`` plus overrides."""
    return to_settings(compose(overrides, conf_dir=conf_dir))


def params_text(cfg: DictConfig) -> str:
    """The YAML DVC writes for a composed config (resolved, ``hydra`` node excluded)."""
    plain = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True, enum_to_str=True))
    return OmegaConf.to_yaml(plain)


def _flatten(node: Plain, prefix: str = "") -> Iterator[tuple[str, Plain]]:
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _flatten(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _flatten(v, f"{prefix}[{i}]")
    else:
        yield prefix, node


def diff(a: Plain, b: Plain) -> list[tuple[str, Plain, Plain]]:
    """Keys whose values differ between two plain configs: ``(key, a_value, b_value)``."""
    fa, fb = dict(_flatten(a)), dict(_flatten(b))
    out = []
    for key in sorted(set(fa) | set(fb)):
        va, vb = fa.get(key), fb.get(key)  # a missing key reads None
        if key not in fa or key not in fb or va != vb:
            out.append((key, va, vb))
    return out


def _plain(cfg: DictConfig) -> Plain:
    plain = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    assert isinstance(plain, dict)
    return {str(k): v for k, v in plain.items()}


def stale_message(root: Path = PROJECT_ROOT) -> str | None:
    """None when ``params.yaml`` equals the composition of ``conf/``, else a message."""
    path = root / PARAMS_FILE
    composed = _plain(compose(conf_dir=root / "conf"))
    if not path.exists():
        return f"{path} is missing. Compose it with: {RECOMPOSE_HINT}"
    stored = _plain(OmegaConf.load(path))  # type: ignore[arg-type]
    changes = diff(stored, composed)
    if not changes:
        return None
    lines = [f"  {k}: params.yaml={a!r}  conf/={b!r}" for k, a, b in changes[:12]]
    more = f"\n  ... and {len(changes) - 12} more" if len(changes) > 12 else ""
    return (
        "params.yaml is stale: it differs from the composition of conf/ in "
        f"{len(changes)} key(s):\n" + "\n".join(lines) + more + "\n"
        f"Recompose it with: {RECOMPOSE_HINT}\nthen run `dvc repro` again "
        "(or use `dvc exp run`, which recomposes it itself)."
    )


#: what the ``config`` gate writes into its hash file when ``params.yaml`` is fresh (its
#: stamp, ``config.ok``, which stages depend on, never changes: a new param reruns only
#: the stages whose param stamps change)
_FRESH = "params.yaml is the composition of conf/: "
#: the gate's hash file, beside its stamp
GATE_HASH = "config.hash"


def _fingerprint(root: Path) -> str:
    """A hash of the bytes of ``conf/`` and ``params.yaml`` (paths relative to ``root``)."""
    import hashlib

    h = hashlib.sha256()
    files = sorted(p for p in (root / "conf").rglob("*") if p.is_file())
    for path in [*files, root / PARAMS_FILE]:
        if path.is_file():
            h.update(path.relative_to(root).as_posix().encode() + b"\0")
            h.update(hashlib.sha256(path.read_bytes()).digest())
    return "sha256:" + h.hexdigest()


def _gate_stamp(root: Path, name: str = "config.ok") -> Path | None:
    """The ``config`` gate's stamp (or another of its files) for the pipeline
    ``params.yaml`` names."""
    import yaml

    try:
        params = yaml.load((root / PARAMS_FILE).read_text(encoding="utf-8"),
                           Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        data = params["paths"]["data"]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return None
    return root / str(data) / name if isinstance(data, str) else None


def _gate_passed(root: Path) -> bool:
    """True when the ``config`` gate checked these very bytes of ``conf/`` and
    ``params.yaml`` (so a stage need not compose ``conf/`` again)."""
    stamp = _gate_stamp(root, GATE_HASH)
    try:
        text = stamp.read_text(encoding="utf-8") if stamp else ""
    except OSError:
        return False
    return text == _FRESH + _fingerprint(root) + "\n"


def load_settings(overrides: Sequence[str] = (), root: Path = PROJECT_ROOT) -> Config:
    """:func:`to_settings` of :func:`load_params`: the settings a DVC-run stage uses, in a
    tenth of a second instead of one or two (each stage of the pipeline starts with this).

    ``params.yaml`` is read with libyaml, and the overrides (Hydra's grammar, parsed by
    Hydra) are set on it, when each one changes a key the file has; the result is built
    exactly (:func:`~.schema.build_exact`). Anything else (an append, a delete, a value
    OmegaConf would have to convert, a bad key) goes Hydra's and OmegaConf's way, which
    builds the same settings or refuses with their message;
    ``tests/test_exact_settings.py`` holds the two ways equal on every stage of ``dvc.yaml``.

    Raises:
        StaleParamsError: ``params.yaml`` is behind ``conf/`` under ``dvc repro``.
        ConfigError: a bad override, key or value.
    """
    if not os.environ.get("DVC_EXP_NAME") and not _gate_passed(root):
        msg = stale_message(root)
        if msg:
            raise StaleParamsError(msg)
    exact = _exact_settings(overrides, root)
    return exact if exact is not None else to_settings(_compose_params(overrides, root))


def hand_settings(overrides: Sequence[str], root: Path) -> Config | None:
    """The settings of a stage run by hand, without Hydra's composition of ``conf/`` (a
    second of every run), when that composition is known to give them: ``params.yaml``
    plus ``overrides``, built exactly (:func:`load_settings`' way), where the ``config``
    gate has checked that ``params.yaml`` is the composition of these very bytes of
    ``conf/`` and every override sets a value of the type its key has. None otherwise
    (a flag such as ``-m`` or ``--cfg``, a group's choice such as ``surface=forearm``, a
    ``hydra.`` key, an append or delete, a value to convert, a bad key or value, a
    ``params.yaml`` behind ``conf/``): Hydra composes, and refuses with its own words.
    ``tests/test_exact_settings.py`` holds the two ways equal.
    """
    if any(a.startswith("-") or a.partition("=")[0].lstrip("+~").split(".")[0] == "hydra"
           or (root / "conf" / a.partition("=")[0]).is_dir() for a in overrides):
        return None
    if not _gate_passed(root):
        return None
    try:
        return _exact_settings(overrides, root)
    except ConfigError:
        return None


def _exact_settings(overrides: Sequence[str], root: Path) -> Config | None:
    """``params.yaml`` plus ``overrides`` built exactly and checked; None where they
    cannot be built so (:class:`NotExact`: Hydra's and OmegaConf's way is then needed).

    Raises:
        ConfigError: a value out of its range.
    """
    try:
        exact = build_exact(Config, _params_with(overrides, root))
    except NotExact:
        return None
    return _checked(exact)


def _params_with(overrides: Sequence[str], root: Path) -> dict[str, Plain]:
    """``params.yaml`` as plain containers with Hydra ``overrides`` that each change a
    key it has (else :class:`NotExact`)."""
    import yaml
    from hydra.errors import HydraException

    try:
        plain = yaml.load((root / PARAMS_FILE).read_text(encoding="utf-8"),
                          Loader=_yaml_loader())
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        raise NotExact(PARAMS_FILE) from None
    if not isinstance(plain, dict):
        raise NotExact(PARAMS_FILE)
    if overrides:
        from hydra.core.override_parser.overrides_parser import OverridesParser

        try:
            parsed = OverridesParser.create().parse_overrides(list(overrides))
        except HydraException:
            raise NotExact("an override") from None
        for o in parsed:
            if (o.package is not None or o.is_delete() or o.is_add() or o.is_force_add()
                    or o.is_sweep_override()):
                raise NotExact(o.input_line or "")
            value = o.value()
            if isinstance(value, dict):
                raise NotExact(o.key_or_group)
            _set_existing(plain, o.key_or_group, value)
    return plain


def load_params(overrides: Sequence[str] = (), root: Path = PROJECT_ROOT) -> DictConfig:
    """The configuration a DVC-run stage uses: ``params.yaml`` plus command-line overrides.

    Under ``dvc repro`` the file is first checked against ``conf/``; under ``dvc exp run``
    (``DVC_EXP_NAME`` set) DVC has just composed it, with the experiment's overrides.

    Raises:
        StaleParamsError: ``params.yaml`` is behind ``conf/`` under ``dvc repro``.
    """
    if not os.environ.get("DVC_EXP_NAME") and not _gate_passed(root):
        msg = stale_message(root)
        if msg:
            raise StaleParamsError(msg)
    return _compose_params(overrides, root)


#: the name ``params.yaml`` is composed under (a node of Hydra's ConfigStore)
_PARAMS_NODE = "_tattotronix_params"


def _compose_params(overrides: Sequence[str], root: Path) -> DictConfig:
    """``params.yaml`` plus ``overrides`` (Hydra's grammar), as a node of Hydra's
    ConfigStore: no folder is on the search path, so no folder of the project (an ``art/``
    beside ``params.yaml``, named like a key) can pass for a config group."""
    from hydra import compose as hydra_compose
    from hydra import initialize
    from hydra.core.config_store import ConfigStore
    from hydra.core.global_hydra import GlobalHydra

    from tattotronix.config.schema import Config

    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    try:
        stored = OmegaConf.load(root / PARAMS_FILE)
        ConfigStore.instance().store(name=_PARAMS_NODE, node=stored)
        with initialize(config_path=None, version_base="1.3"):
            raw = hydra_compose(config_name=_PARAMS_NODE, overrides=list(overrides))
        schema = OmegaConf.structured(Config)
        cfg = OmegaConf.merge(schema, OmegaConf.to_container(raw, resolve=True))
    except Exception as exc:
        raise ConfigError(f"bad configuration: {_root_cause(exc)}") from None
    assert isinstance(cfg, DictConfig)
    return cfg


def write_params(root: Path = PROJECT_ROOT, overrides: Sequence[str] = ()) -> Path:
    """Compose ``conf/`` (plus overrides) and write ``params.yaml`` atomically."""
    path = root / PARAMS_FILE
    text = params_text(compose(overrides, conf_dir=root / "conf"))
    tmp = path.with_suffix(".yaml.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


def _stamp_params(root: Path, folder: Path) -> None:
    from tattotronix.config.tracked import write_param_stamps

    changed = write_param_stamps(folder, root)
    print(f"new params for {', '.join(changed)}" if changed else
          "every stage's params are as stamped")


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: recompose ``params.yaml`` (default) or ``--check`` it."""
    ap = argparse.ArgumentParser(prog="tattotronix-params", description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only compare; exit 1 when stale")
    ap.add_argument("--stamp", type=Path, default=None,
                    help="with --check: write this file when fresh (the DVC gate), and the "
                         "hash of conf/ and params.yaml beside it (config.hash)")
    ap.add_argument("--param-stamps", type=Path, default=None, metavar="DIR",
                    help="with --check: write each stage's param stamp into DIR when fresh")
    ap.add_argument("--root", type=Path, default=Path.cwd(),
                    help="project root (default: the current directory, as DVC runs it)")
    args = ap.parse_args(argv)
    try:
        if args.check and os.environ.get("DVC_STAGE"):
            # the first stage of every repro: never build on a cut-short dvc.lock
            from tattotronix.config.dvclock import guard
            from tattotronix.config.tracked import stage_names

            guard(args.root, stage_names(args.root))
        # a value out of its range stops here, before any stage (one line, naming the key)
        compose_settings(conf_dir=args.root / "conf")
        if args.check:
            # Under `dvc exp run` DVC has just composed params.yaml, overrides included.
            if os.environ.get("DVC_EXP_NAME"):
                msg, ok = None, "params.yaml was just composed by dvc exp run"
            else:
                msg, ok = stale_message(args.root), "params.yaml equals the composition of conf/"
            if msg:
                print(msg, file=sys.stderr)
                return 1
            print(ok)
            if args.param_stamps:
                _stamp_params(args.root, args.param_stamps)
            if args.stamp:
                args.stamp.parent.mkdir(parents=True, exist_ok=True)
                args.stamp.write_text("params.yaml is fresh\n", encoding="utf-8")
                # the stages trust these bytes without composing conf/ again (a params.yaml
                # an experiment composed is not the composition of conf/: no hash)
                (args.stamp.parent / GATE_HASH).write_text(
                    ok + "\n" if os.environ.get("DVC_EXP_NAME")
                    else _FRESH + _fingerprint(args.root) + "\n", encoding="utf-8")
            return 0
        path = write_params(args.root)
        print(f"wrote {path}")
        # the stamps too, so that `dvc status` names the stages whose params changed
        stamps = _gate_stamp(args.root)
        if stamps is not None and (args.root / "dvc.yaml").is_file():
            _stamp_params(args.root, stamps.parent / "params")
        return 0
    except ConfigError as exc:
        print(exc, file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
