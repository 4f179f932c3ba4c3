"""What every ``stages/<name>.py`` shares: config loading, errors, atomic outputs.

A stage script is thin::

    from tattotronix.stage import run_stage

    def main(cfg: Config, out: Outputs) -> None: ...  # calls the library, writes via out

    if __name__ == "__main__":
        run_stage("robot", main)

* Run by hand (``python stages/robot.py robot.mass_model=box``), the config is Hydra's
  composition of ``conf/`` plus the overrides; ``-m`` sweeps work as in any Hydra app.
  Where that composition is known to be ``params.yaml`` (the ``config`` gate checked
  these bytes of ``conf/``) and every override sets a value of its key's type, the
  settings are built from ``params.yaml`` directly, the same settings a second sooner
  (:func:`~tattotronix.config.params.hand_settings`).
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
* A stop signal ends it with one line and exit code 128 + the signal's number, as a shell
  reports it: Ctrl-C (SIGINT) 130, SIGTERM (``kill``, a service manager) 143, SIGHUP (a
  closed terminal) 129; the outputs staged so far are removed
  (:meth:`Outputs.transaction`). A run that stops itself safely on a signal (the arm lifts
  the needle and saves where it stopped) raises :class:`~tattotronix.errors.Interrupted`,
  whose message says so, and ends the same way. A Ctrl-C while the stage script is still
  importing its libraries (before :func:`run_stage`) also ends in one line with 130
  (``tattotronix/__init__.py``).
* Inputs are read under ``paths.data``; outputs go where
  :func:`~tattotronix.io.outputs.write_root` says (``paths.data`` under DVC, ``runs/``
  for a run by hand on the pipeline's data, or ``paths.out``), and the run ends with one
  line naming what it wrote. The jobs of a ``-m`` sweep run without progress bars,
  each writing under a folder of its own (:class:`~tattotronix.io.outputs.Outputs`).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType

from omegaconf import DictConfig

from tattotronix import end_import_guard
from tattotronix.config.dvclock import guard as guard_lock
from tattotronix.config.params import hand_settings, load_settings, one_line, to_settings
from tattotronix.config.schema import Config
from tattotronix.config.tracked import as_stage, stage_names, tracked_params
from tattotronix.errors import ConfigError, Interrupted, TattotronixError
from tattotronix.io.outputs import Outputs, use_command_line, write_root
from tattotronix.io.provenance import (
    fixed_code_version,
    plain_config,
    stamp_version,
)

__all__ = ["StageBody", "StopSignal", "exit_code", "logs_to_stderr", "run_stage", "signal_name",
           "stop_signals"]

#: a stage's body: ``main(cfg, out)`` of ``stages/<name>.py``
StageBody = Callable[[Config, Outputs], None]

log = logging.getLogger("tattotronix")

#: the exit code of a run stopped by Ctrl-C (128 + SIGINT, as a shell reports it); any stop
#: signal exits with 128 + its number (:func:`exit_code`: SIGTERM 143, SIGHUP 129)
EXIT_INTERRUPTED = 130
#: the signals that stop a stage as Ctrl-C does (SIGINT itself raises KeyboardInterrupt)
_STOP_SIGNALS = ("SIGTERM", "SIGHUP")
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


def _hand_logging() -> None:
    """What ``conf/``'s ``hydra/job_logging: stdout`` sets up for a run Hydra starts: the
    messages alone, on standard output, from INFO."""
    root = logging.getLogger()
    if not root.handlers:
        handler = logging.StreamHandler(sys.stdout)
        handler.setFormatter(logging.Formatter("%(message)s"))
        root.addHandler(handler)
    root.setLevel(logging.INFO)


def exit_code(signum: int) -> int:
    """The exit code of a run stopped by signal ``signum``: 128 + its number, as a shell
    reports a process the signal ended (130 for Ctrl-C, 143 for SIGTERM)."""
    return 128 + int(signum)


def signal_name(signum: int) -> str:
    """``Ctrl-C`` for SIGINT, else the signal's name (``SIGTERM``)."""
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name


class StopSignal(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the stage was, as Ctrl-C raises KeyboardInterrupt:
    whatever cleans up after a Ctrl-C (the outputs' transaction, a pool of workers) cleans
    up after these too."""

    def __init__(self, signum: int):
        super().__init__(signal_name(signum))
        self.signum = int(signum)


@contextmanager
def stop_signals() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`StopSignal` inside the block (main thread only;
    an ignored one stays ignored, as under ``nohup``); the previous handlers after it.

    A process forked inside the block (a study's workers) inherits the handler; there it
    does what the signal would have done (the parent's pool ends its workers with SIGTERM).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    owner = os.getpid()

    def _raise(signum: int, frame: FrameType | None) -> None:
        if os.getpid() != owner:  # a forked worker: the signal's default action
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        raise StopSignal(signum)

    previous: dict[int, signal.Handlers | int | Callable[..., object] | None] = {}
    for sig_name in _STOP_SIGNALS:
        sig = getattr(signal, sig_name, None)
        if sig is None or signal.getsignal(sig) == signal.SIG_IGN:
            continue
        previous[sig] = signal.getsignal(sig)
        signal.signal(sig, _raise)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


def _interrupted(name: str, signum: int, message: str) -> SystemExit:
    print(f"{name}: {message}", file=sys.stderr)
    return SystemExit(exit_code(signum))


def _execute(name: str, body: StageBody, cfg: DictConfig | Config,
             sweep_overrides: list[str] | None = None) -> None:
    _setup_logging()
    t0 = time.perf_counter()
    try:  # the one conversion: typed and frozen from here on
        settings = cfg if isinstance(cfg, Config) else to_settings(cfg)
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
    except Interrupted as exc:  # stopped safely on a signal; the message says how it ended
        raise _interrupted(name, exc.signum, f"interrupted: {exc}") from None
    except (TattotronixError, ConfigError) as exc:
        raise _refuse(name, str(exc)) from None
    except MemoryError as exc:  # numpy's ArrayMemoryError says how much it wanted
        raise _refuse(name, f"out of memory ({one_line(exc)}): nothing written; use "
                      "coarser settings (toolpath.pitch_mm, toolpath.step_mm, mask.res_mm) "
                      "or a smaller drawing") from None
    log.info("%s", out.report(name))
    log.info("%s: done in %.2f s", name, time.perf_counter() - t0)


def run_stage(name: str, body: StageBody) -> None:
    """Run a stage body with its config. See the module docstring."""
    # Ctrl-C raises KeyboardInterrupt again (tattotronix/__init__.py ended the process at
    # once while the script imported: there was nothing to clean up yet)
    end_import_guard()
    try:
        with stop_signals():
            _run(name, body)
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, StopSignal) else signal.SIGINT
        raise _interrupted(name, signum, f"interrupted ({signal_name(signum)}): stopped, "
                           "nothing written") from None


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
            settings = load_settings(argv, root=Path.cwd())
            params = plain_config(settings)
            keys = tracked_params(stage, Path.cwd(), params)
            # never build on a dvc.lock an interrupt cut short (config/dvclock.py)
            guard_lock(Path.cwd(), stage_names(Path.cwd(), params))
        except ConfigError as exc:
            raise _refuse(name, str(exc)) from None
        # what DVC reruns the stage on is all its outputs may record: its params
        # (config/tracked.py) and its code, the stamp it depends on (devtools/codedeps.py)
        definition = stage.rpartition(":")[2].split("@")[0]
        stamp = Path(settings.paths.data) / "code" / f"{definition}.txt"
        with as_stage(keys, argv, stamp_version(stamp)):
            _execute(name, body, settings)
        return

    conf_dir = Path(sys.argv[0]).resolve().parent.parent / "conf"
    if not conf_dir.is_dir():
        from tattotronix.config.params import CONF_DIR

        conf_dir = CONF_DIR

    # Hydra's composition gives what params.yaml already holds (the gate checked it):
    # set the overrides on it, the exact way, and skip a second of every run
    quick = hand_settings(argv, conf_dir.parent)
    if quick is not None:
        _hand_logging()
        use_command_line(argv)
        with fixed_code_version():
            _execute(name, body, quick)
        return

    import hydra
    from hydra.errors import HydraException, OverrideParseException
    from omegaconf.errors import OmegaConfBaseException

    started = False

    @hydra.main(config_path=str(conf_dir), config_name="config", version_base="1.3")
    def _main(cfg: DictConfig) -> None:
        nonlocal started
        started = True
        _execute(name, body, cfg, _sweep_overrides())

    # Hydra reports a bad command line (an override it cannot parse, an unknown key, a
    # value of the wrong type) over several lines; with HYDRA_FULL_ERROR it raises the
    # error instead, and we say it in one line. Errors of the stage body are not ours to
    # shorten: they keep their traceback.
    full_error = os.environ.get("HYDRA_FULL_ERROR")
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        # computed once: every job and worker records it
        with fixed_code_version(), _one_compose(argv):
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


@contextmanager
def _one_compose(argv: list[str]) -> Iterator[None]:
    """Hydra composes the whole config twice for a run: first only to read ``hydra.mode``
    (``Hydra.get_mode``), then for the job. ``conf/`` never sets ``hydra.mode``, so that
    first compose reads ``None`` (as it does when composing fails) and the command line
    decides (``-m`` or not): answer ``None`` without composing, which saves about a second
    of every run by hand. An override that sets ``hydra.mode`` keeps Hydra's own way."""
    if any(a.lstrip("+").startswith("hydra.mode=") for a in argv):
        yield
        return
    from hydra._internal.hydra import Hydra

    own = Hydra.__dict__["get_mode"]
    setattr(Hydra, "get_mode", lambda self, config_name, overrides: None)  # noqa: B010
    try:
        yield
    finally:
        setattr(Hydra, "get_mode", own)  # noqa: B010


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
