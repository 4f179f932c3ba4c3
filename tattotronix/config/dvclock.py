"""Never build on a ``dvc.lock`` that an interrupt cut short.

DVC rewrites the whole ``dvc.lock`` in place after every stage it runs:
``Lockfile.dump_stages`` (``dvc/dvcfile.py``) goes through ``modify_yaml`` to
``_dump_data`` (``dvc/utils/serialize/_common.py``), which opens the file with
``open(path, "w+")``, truncating it, and lets ruamel.yaml stream the document into it.
An interrupt (Ctrl-C) that lands while it streams leaves the file cut short: empty, cut
mid-line (DVC then refuses every command, "failed validation"), or cut between two
stages, which DVC takes for stages never run. The next ``dvc repro TARGET`` reruns those
it needs and writes a lock that has lost the records of every other stage. (Related
upstream reports of DVC's state files cut short by an interrupt: treeverse/dvc#814,
#2942, #7615; none for ``dvc.lock`` itself.)

The window is as long as the dump: stamping each stage's code and params
(:mod:`tattotronix.devtools.codedeps`) made the lock 5.7 times smaller (12,029 lines to
2,120) and the dump 6 times shorter (``benchmarks/bench_lock.py``). What is left, this
module closes: every command DVC runs for this project calls :func:`guard` first, which

* refuses a lock that does not parse, is cut mid-line, or whose entries lack their
  command, naming the fix, and
* refuses a lock that has lost the record of a stage the last whole lock held (the
  stage still in ``dvc.yaml``), naming the stages lost and the fix,
* and otherwise keeps the lock as the last whole one (``.dvc/tmp/tattotronix/``), to
  restore from: ``python -m tattotronix.config.dvclock --restore``.

A cut at a line's end inside the last stage of the file leaves that one stage with a
partial record, which DVC takes for a stage whose outputs changed and reruns: nothing is
lost there, and nothing is refused.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from tattotronix.errors import ConfigError

__all__ = ["BACKUP", "LOCK_FILE", "DamagedLockError", "guard", "main", "restore"]

LOCK_FILE = "dvc.lock"
#: the last whole lock this project saw, beside DVC's own temporary files
BACKUP = Path(".dvc") / "tmp" / "tattotronix" / "dvc.lock.whole"


class DamagedLockError(ConfigError):
    """``dvc.lock`` is cut short; the message names what is lost and how to mend it."""


def _fix(root: Path) -> str:
    backup = root / BACKUP
    if backup.is_file():
        return ("restore the last whole one with `python -m tattotronix.config.dvclock "
                "--restore` (or `git checkout dvc.lock` for the committed one), then run "
                "`dvc repro` again")
    return "restore it with `git checkout dvc.lock`, then run `dvc repro` again"


def _load(text: str) -> Any:
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    return yaml.load(text, Loader=loader)


def _stages_of(text: str) -> dict[str, Any] | None:
    """The stage entries of a lock's text (None: not a whole lock: DVC's dump always ends
    with a newline, so a cut mid-line is caught even where what is left still parses)."""
    if not text.endswith("\n"):
        return None
    try:
        doc = _load(text)
    except yaml.YAMLError:
        return None
    if not isinstance(doc, Mapping) or not isinstance(doc.get("stages", {}), Mapping):
        return None
    stages = dict(doc.get("stages") or {})
    if any(not isinstance(e, Mapping) or "cmd" not in e for e in stages.values()):
        return None
    return stages


def guard(root: Path, stages: Iterable[str]) -> None:
    """Refuse a cut-short ``root/dvc.lock``; keep a whole one as the backup.

    Args:
        root: the folder of ``dvc.yaml`` and ``dvc.lock``.
        stages: every stage of ``dvc.yaml`` (``name@key`` for foreach items).

    Raises:
        DamagedLockError: the lock does not parse, has an entry without its command, or
            lacks a stage the last whole lock held.
    """
    lock = root / LOCK_FILE
    backup = root / BACKUP
    try:
        text = lock.read_text(encoding="utf-8")
    except FileNotFoundError:
        backup.unlink(missing_ok=True)  # a fresh start (or one on purpose): nothing to lose
        return
    current = _stages_of(text)
    if current is None:
        raise DamagedLockError(
            f"{lock} is cut short ({len(text.encode())} bytes, not a whole lock file): an "
            "interrupted dvc repro left it half-written (DVC rewrites it in place after "
            f"each stage); {_fix(root)}")
    try:
        before = _stages_of(backup.read_text(encoding="utf-8")) or {}
    except FileNotFoundError:
        before = {}
    lost = sorted((set(before) & set(stages)) - set(current))
    if lost:
        named = ", ".join(lost[:6]) + (f" and {len(lost) - 6} more" if len(lost) > 6 else "")
        raise DamagedLockError(
            f"{lock} has lost the records of {len(lost)} stage(s) it held before ({named}): "
            "an interrupted dvc repro cut it short (DVC rewrites it in place after each "
            f"stage); {_fix(root)}. If you removed them on purpose, delete {BACKUP}")
    backup.parent.mkdir(parents=True, exist_ok=True)
    tmp = backup.with_name(f".{backup.name}.tmp{os.getpid()}")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, backup)


def restore(root: Path) -> str:
    """Put the last whole lock back as ``root/dvc.lock``; what was done."""
    backup = root / BACKUP
    if not backup.is_file():
        raise DamagedLockError(f"no whole lock saved at {backup}: restore dvc.lock with "
                               "`git checkout dvc.lock`")
    lock = root / LOCK_FILE
    tmp = lock.with_name(f".{lock.name}.tmp{os.getpid()}")
    tmp.write_bytes(backup.read_bytes())
    os.replace(tmp, lock)
    return (f"restored {lock} from {backup}; `dvc repro` remakes any output a refused run "
            "removed")


def main(argv: list[str] | None = None) -> int:
    """``--check`` (exit 2 naming the fix when the lock is cut short) or ``--restore``."""
    from tattotronix.config.tracked import stage_names

    ap = argparse.ArgumentParser(prog="python -m tattotronix.config.dvclock",
                                 description="Check dvc.lock, or restore the last whole one.")
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="is dvc.lock whole?")
    mode.add_argument("--restore", action="store_true", help="put the last whole one back")
    args = ap.parse_args(argv)
    root = Path.cwd()
    try:
        if args.restore:
            print(restore(root))
        else:
            guard(root, stage_names(root))
            print(f"{root / LOCK_FILE}: whole")
    except ConfigError as exc:
        print(f"dvclock: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
