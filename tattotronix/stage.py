"""What every ``stages/<name>.py`` shares: config loading, errors, atomic outputs.

A stage script is thin::

    from tattotronix.stage import run_stage

    def main(cfg, io): ...           # calls the library, writes through ``io``

    if __name__ == "__main__":
        run_stage("robot", main)

* Run by hand (``python stages/robot.py robot.mass_model=box``), the config is Hydra's
  composition of ``conf/`` plus the overrides; ``-m`` sweeps work as in any Hydra app.
* Run by DVC (``DVC_STAGE`` is set), the config is ``params.yaml`` plus any overrides in
  the command, after checking that ``params.yaml`` is not stale against ``conf/``.
* A :class:`TattotronixError` (bad input, unreachable drawing, ...) ends the run with its
  one-line message and exit code 2; no traceback, and no partial output.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from tattotronix.config.params import ConfigError, load_params

__all__ = ["Outputs", "StageInputMissing", "TattotronixError", "code_version", "logs_to_stderr",
           "run_stage"]

log = logging.getLogger("tattotronix")


class TattotronixError(Exception):
    """An error the user can act on. The message says what, which value, and what to do."""


class StageInputMissing(TattotronixError):
    """A stage's input does not exist yet; the message names the stage to run first."""

    def __init__(self, path: Path, stage: str):
        super().__init__(
            f"missing input {path}: run the '{stage}' stage first "
            f"(python stages/{stage}.py, or dvc repro)"
        )


def code_version(root: Path | None = None) -> str:
    """The git commit of the code (with ``-dirty`` when the tree has changes), or unknown."""
    root = root or Path(__file__).resolve().parents[1]
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root, capture_output=True, text=True, check=True,
        ).stdout.strip()
        return rev + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


#: overrides that say where outputs go, not what they are: never part of a name
_WHERE_KEYS = ("paths.data",)


class Outputs:
    """Where a stage writes, with every file written atomically as one transaction.

    Files go to temporary names next to their targets; only when the stage body returns
    are they renamed into place. A stage interrupted half-way leaves nothing that looks
    finished (the temporaries are removed).
    """

    def __init__(self, cfg: DictConfig, sweep_overrides: list[str] | None = None):
        self.cfg = cfg
        self.data = Path(cfg.paths.data)
        #: in a Hydra multirun, this job's overrides (``key=value``); None otherwise
        self.sweep_overrides = sweep_overrides
        self._pending: list[tuple[Path, Path]] = []

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
        target.parent.mkdir(parents=True, exist_ok=True)
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

    def write_json(self, target: Path, obj: Any) -> Path:
        """Stage a JSON file (sorted keys, 2-space indent, trailing newline)."""
        return self.write_text(target, json.dumps(obj, indent=2, sort_keys=True) + "\n")

    def tmp_path(self, target: Path) -> Path:
        """A temporary path for a writer that needs a file name (npz, png, ...)."""
        return self._tmp(target)

    def commit(self) -> None:
        """Rename every staged file into place."""
        for tmp, target in self._pending:
            tmp.replace(target)
        self._pending.clear()

    def abort(self) -> None:
        """Remove every staged temporary."""
        for tmp, _ in self._pending:
            if tmp.is_dir():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                tmp.unlink(missing_ok=True)
        self._pending.clear()

    @contextmanager
    def transaction(self) -> Iterator[Outputs]:
        """Commit on success, abort on any exception (including Ctrl-C)."""
        try:
            yield self
        except BaseException:
            self.abort()
            raise
        self.commit()


def logs_to_stderr() -> None:
    """Send every log line to stderr, so stdout carries only what a stage prints for
    scripts (``collision.py pose=...`` prints one JSON object)."""
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.StreamHandler) and not isinstance(
                handler, logging.FileHandler):
            handler.setStream(sys.stderr)


def _setup_logging() -> None:
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.INFO, format="[%(name)s] %(message)s")
    log.setLevel(logging.INFO)


def _execute(name: str, body: Callable[[DictConfig, Outputs], None], cfg: DictConfig,
             sweep_overrides: list[str] | None = None) -> None:
    _setup_logging()
    t0 = time.perf_counter()
    out = Outputs(cfg, sweep_overrides)
    try:
        with out.transaction():
            body(cfg, out)
    except (TattotronixError, ConfigError) as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    log.info("%s: done in %.2f s", name, time.perf_counter() - t0)


def _validated(cfg: DictConfig) -> DictConfig:
    """Merge into the root schema (a second guard for configs Hydra did not type)."""
    from tattotronix.config.schema import Config

    try:
        plain = OmegaConf.to_container(cfg, resolve=True)
        merged = OmegaConf.merge(OmegaConf.structured(Config), plain)
    except Exception as exc:
        raise ConfigError(f"bad configuration: {exc}") from None
    assert isinstance(merged, DictConfig)
    OmegaConf.set_readonly(merged, True)
    return merged


def run_stage(name: str, body: Callable[[DictConfig, Outputs], None]) -> None:
    """Run a stage body with its config. See the module docstring."""
    argv = sys.argv[1:]
    if os.environ.get("DVC_STAGE"):
        try:
            cfg = load_params(argv, root=Path.cwd())
        except ConfigError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr)
            raise SystemExit(2) from None
        OmegaConf.set_readonly(cfg, True)  # load_params has merged it into the schema
        _execute(name, body, cfg)
        return

    import hydra

    conf_dir = Path(sys.argv[0]).resolve().parent.parent / "conf"
    if not conf_dir.is_dir():
        from tattotronix.config.params import CONF_DIR

        conf_dir = CONF_DIR

    @hydra.main(config_path=str(conf_dir), config_name="config", version_base="1.3")
    def _main(cfg: DictConfig) -> None:
        try:
            checked = _validated(cfg)
        except ConfigError as exc:
            print(f"{name}: error: {exc}", file=sys.stderr)
            raise SystemExit(2) from None
        _execute(name, body, checked, _sweep_overrides())

    _main()


def _sweep_overrides() -> list[str] | None:
    """This job's overrides when Hydra runs it as part of a multirun (``-m``)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    try:
        hc = HydraConfig.get()
    except ValueError:
        return None
    if hc.mode != RunMode.MULTIRUN:
        return None
    return [str(o) for o in hc.overrides.task]
