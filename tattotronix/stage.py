"""What every ``stages/<name>.py`` shares: config loading, errors, atomic outputs.

A stage script is thin::

    from tattotronix.stage import run_stage

    def main(cfg: Config, out: Outputs) -> None: ...  # calls the library, writes via out

    if __name__ == "__main__":
        run_stage("robot", main)

* Run by hand (``python stages/robot.py robot.mass_model=box``), the config is Hydra's
  composition of ``conf/`` plus the overrides; ``-m`` sweeps work as in any Hydra app.
* Run by DVC (``DVC_STAGE`` is set), the config is ``params.yaml`` plus any overrides in
  the command, after checking that ``params.yaml`` is not stale against ``conf/``. The
  provenance of its outputs then records only what DVC reruns it on: its params in
  ``dvc.yaml`` (:mod:`tattotronix.config.tracked`) and its command's overrides, completed
  by what its input artifacts record. So its outputs' bytes move exactly when DVC reruns
  it.
* Either way the composed config is validated, then turned once into the typed, frozen
  settings (:class:`~tattotronix.config.schema.Config`) the body gets; the library takes
  those (or one section of them), never a ``DictConfig``.
* A :class:`TattotronixError` (bad input, unreachable drawing, ...) ends the run with its
  one-line message and exit code 2; no traceback, and no partial output. So does a bad
  command line (an override Hydra cannot parse, an unknown key, a value of the wrong type
  or out of its range), and running out of memory.
* Ctrl-C (``KeyboardInterrupt``) ends it with one line and exit code 130; the outputs
  staged so far are removed (:meth:`Outputs.transaction`).
* Inputs are read under ``paths.data``; outputs go where
  :func:`~tattotronix.io.outputs.write_root` says (``paths.data`` under DVC, ``runs/``
  for a run by hand on the pipeline's data, or ``paths.out``), and the run ends with one
  line naming what it wrote. The jobs of a ``-m`` sweep run without progress bars.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from tattotronix.config.dvclock import guard as guard_lock
from tattotronix.config.params import load_params, one_line, to_settings
from tattotronix.config.schema import Config
from tattotronix.config.tracked import override_keys, stage_names, tracked_params
from tattotronix.errors import ConfigError, TattotronixError
from tattotronix.io.outputs import Outputs, write_root
from tattotronix.io.provenance import (
    fixed_code_version,
    plain_config,
    recorded_keys,
    stamp_version,
)

__all__ = ["StageBody", "logs_to_stderr", "run_stage"]

#: a stage's body: ``main(cfg, out)`` of ``stages/<name>.py``
StageBody = Callable[[Config, Outputs], None]

log = logging.getLogger("tattotronix")

#: the exit code of a run stopped by Ctrl-C (128 + SIGINT, as a shell reports it)
EXIT_INTERRUPTED = 130
#: the exit code of a refused run (bad input, bad configuration)
EXIT_REFUSED = 2


def _refuse(name: str, message: str) -> SystemExit:
    print(f"{name}: error: {message}", file=sys.stderr)
    return SystemExit(EXIT_REFUSED)


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


def _execute(name: str, body: StageBody, cfg: DictConfig,
             sweep_overrides: list[str] | None = None) -> None:
    _setup_logging()
    t0 = time.perf_counter()
    try:
        settings = to_settings(cfg)  # the one conversion: typed and frozen from here on
    except ConfigError as exc:
        raise _refuse(name, str(exc)) from None
    if sweep_overrides is not None and settings.draw.progress:
        # the jobs of a -m sweep run side by side: their bars would interleave into
        # garbage, so each job says its one line at the end instead
        settings = dataclasses.replace(
            settings, draw=dataclasses.replace(settings.draw, progress=False))
    out = Outputs(settings.paths.data, sweep_overrides,
                  root=write_root(settings.paths.data, settings.paths.out))
    try:
        with out.transaction():
            body(settings, out)
    except (TattotronixError, ConfigError) as exc:
        raise _refuse(name, str(exc)) from None
    except MemoryError as exc:  # numpy's ArrayMemoryError says how much it wanted
        raise _refuse(name, f"out of memory ({one_line(exc)}): nothing written; use "
                      "coarser settings (toolpath.pitch_mm, toolpath.step_mm, mask.res_mm) "
                      "or a smaller drawing") from None
    log.info("%s", out.report(name))
    log.info("%s: done in %.2f s", name, time.perf_counter() - t0)


def _validated(cfg: DictConfig) -> DictConfig:
    """Merge into the root schema (a second guard for configs Hydra did not type)."""
    try:
        plain = OmegaConf.to_container(cfg, resolve=True)
        merged = OmegaConf.merge(OmegaConf.structured(Config), plain)
    except Exception as exc:
        raise ConfigError(f"bad configuration: {one_line(exc)}") from None
    assert isinstance(merged, DictConfig)
    OmegaConf.set_readonly(merged, True)
    return merged


def run_stage(name: str, body: StageBody) -> None:
    """Run a stage body with its config. See the module docstring."""
    try:
        _run(name, body)
    except KeyboardInterrupt:
        print(f"{name}: interrupted (Ctrl-C): stopped, nothing written", file=sys.stderr)
        raise SystemExit(EXIT_INTERRUPTED) from None


def _parse_hint(exc: BaseException) -> str:
    """How to quote an override Hydra's grammar refuses (README, "Configuration")."""
    override = getattr(exc, "override", None)
    if not isinstance(override, str) or "=" not in override:
        return ""
    key, value = override.split("=", 1)
    if value.isascii() and not set(value) & set("()\\"):
        return ""
    quoted = f"{key}='{value}'" if "'" not in value else f'{key}="{value}"'
    return (f"; quote a value with non-ASCII letters or special characters: \"{quoted}\" "
            "(README, \"Configuration\")")


def _run(name: str, body: StageBody) -> None:
    argv = sys.argv[1:]
    stage = os.environ.get("DVC_STAGE")
    if stage:
        try:
            cfg = load_params(argv, root=Path.cwd())
            params = plain_config(cfg)
            keys = tracked_params(stage, Path.cwd(), params) + override_keys(argv)
            # never build on a dvc.lock an interrupt cut short (config/dvclock.py)
            guard_lock(Path.cwd(), stage_names(Path.cwd(), params))
        except ConfigError as exc:
            raise _refuse(name, str(exc)) from None
        OmegaConf.set_readonly(cfg, True)  # load_params has merged it into the schema
        # what DVC reruns the stage on is all its outputs may record: its params
        # (config/tracked.py) and its code, the stamp it depends on (devtools/codedeps.py)
        definition = stage.rpartition(":")[2].split("@")[0]
        stamp = Path(str(cfg.paths.data)) / "code" / f"{definition}.txt"
        with recorded_keys(keys), fixed_code_version(stamp_version(stamp)):
            _execute(name, body, cfg)
        return

    import hydra

    conf_dir = Path(sys.argv[0]).resolve().parent.parent / "conf"
    if not conf_dir.is_dir():
        from tattotronix.config.params import CONF_DIR

        conf_dir = CONF_DIR

    from hydra.errors import HydraException, OverrideParseException
    from omegaconf.errors import OmegaConfBaseException

    started = False

    @hydra.main(config_path=str(conf_dir), config_name="config", version_base="1.3")
    def _main(cfg: DictConfig) -> None:
        nonlocal started
        started = True
        try:
            checked = _validated(cfg)
        except ConfigError as exc:
            raise _refuse(name, str(exc)) from None
        _execute(name, body, checked, _sweep_overrides())

    # Hydra reports a bad command line (an override it cannot parse, an unknown key, a
    # value of the wrong type) over several lines; with HYDRA_FULL_ERROR it raises the
    # error instead, and we say it in one line. Errors of the stage body are not ours to
    # shorten: they keep their traceback.
    full_error = os.environ.get("HYDRA_FULL_ERROR")
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        with fixed_code_version():  # computed once: every job and worker records it
            _main()
    except (HydraException, OmegaConfBaseException) as exc:
        if started:
            raise
        hint = _parse_hint(exc) if isinstance(exc, OverrideParseException) else ""
        raise _refuse(name, f"bad configuration: {one_line(exc)}{hint}") from None
    finally:
        if full_error is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = full_error


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
