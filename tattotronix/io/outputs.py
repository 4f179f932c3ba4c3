"""Atomic stage outputs: every file a stage writes lands together, or not at all."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from tattotronix.errors import StageInputMissing

__all__ = ["Outputs"]


#: overrides that say where outputs go, not what they are: never part of a name
_WHERE_KEYS = ("paths.data",)


class Outputs:
    """Where a stage writes, with every file written atomically as one transaction.

    Files go to temporary names next to their targets; only when the stage body returns
    are they renamed into place. A stage interrupted half-way leaves nothing that looks
    finished (the temporaries are removed, and the folders made for them when empty).
    """

    def __init__(self, data: str | Path, sweep_overrides: list[str] | None = None):
        self.data = Path(data)
        #: in a Hydra multirun, this job's overrides (``key=value``); None otherwise
        self.sweep_overrides = sweep_overrides
        self._pending: list[tuple[Path, Path]] = []
        self._removals: list[Path] = []  # files that go at the commit
        self._made: list[Path] = []  # folders made for the temporaries, outermost first

    def sweep_suffix(self, ignore: tuple[str, ...] = ()) -> str:
        """In a multirun, ``@k=v,k=v`` from this job's overrides (keys in ``ignore`` left
        out), so that the jobs of a sweep never write the same file; "" otherwise."""
        if not self.sweep_overrides:
            return ""
        skip = (*ignore, *_WHERE_KEYS)
        keep = [o.replace("/", "_") for o in self.sweep_overrides
                if o.split("=", 1)[0].lstrip("+~") not in skip
                and not o.startswith("hydra")]
        return "@" + ",".join(sorted(keep)) if keep else ""

    def path(self, *parts: str) -> Path:
        """A path under ``paths.data``."""
        return self.data.joinpath(*parts)

    def require(self, path: Path, stage: str) -> Path:
        """Return ``path`` if it exists, else stop naming the stage that makes it."""
        if not path.exists():
            raise StageInputMissing(path, stage)
        return path

    def _tmp(self, target: Path) -> Path:
        """Register a temporary next to ``target`` (same suffix, for writers that check it)."""
        missing = [p for p in (target.parent, *target.parent.parents) if not p.exists()]
        target.parent.mkdir(parents=True, exist_ok=True)
        self._made.extend(reversed(missing))
        tmp = target.with_name(f".{target.stem}.tmp{os.getpid()}{target.suffix}")
        self._pending.append((tmp, target))
        return tmp

    def write_text(self, target: Path, text: str) -> Path:
        """Stage a text file."""
        self._tmp(target).write_text(text, encoding="utf-8")
        return target

    def write_bytes(self, target: Path, data: bytes) -> Path:
        """Stage a binary file."""
        self._tmp(target).write_bytes(data)
        return target

    def write_json(self, target: Path, obj: object) -> Path:
        """Stage a JSON file (sorted keys, 2-space indent, trailing newline)."""
        return self.write_text(target, json.dumps(obj, indent=2, sort_keys=True) + "\n")

    def write_timings(self, stage: str, name: str, timings: Mapping[str, float]) -> Path:
        """Stage the wall times of a run: ``timings/<stage>/<name>.json`` under the data
        folder. They vary from run to run, so they are kept apart from the metrics (which
        must be byte-identical for the same inputs) and are not tracked by DVC or git."""
        return self.write_json(self.path("timings", stage, f"{name}.json"),
                               {k: float(v) for k, v in timings.items()})

    def tmp_path(self, target: Path) -> Path:
        """A temporary path for a writer that needs a file name (npz, png, ...)."""
        return self._tmp(target)

    def remove(self, target: Path) -> None:
        """Stage the removal of a file (it goes at the commit; an abort keeps it)."""
        self._removals.append(target)

    def commit(self) -> None:
        """Remove the files staged for removal, then rename every staged file into place."""
        for target in self._removals:
            target.unlink(missing_ok=True)
        for tmp, target in self._pending:
            tmp.replace(target)
        self._pending.clear()
        self._removals.clear()
        self._made.clear()

    def abort(self) -> None:
        """Remove every staged temporary."""
        for tmp, _ in self._pending:
            if tmp.is_dir():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                tmp.unlink(missing_ok=True)
        self._pending.clear()
        self._removals.clear()
        for folder in reversed(self._made):  # innermost first; only the empty ones go
            try:
                folder.rmdir()
            except OSError:
                pass
        self._made.clear()

    @contextmanager
    def transaction(self) -> Iterator[Outputs]:
        """Commit on success, abort on any exception (including Ctrl-C)."""
        try:
            yield self
        except BaseException:
            self.abort()
            raise
        self.commit()
