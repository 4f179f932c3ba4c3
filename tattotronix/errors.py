"""The project's exceptions. This module imports nothing else of the project, so any
layer can raise them without pulling in another.

Every one is an error the user can act on: the message says what, which value or file,
and what to do. The stage runner (``tattotronix.stage``) prints it as one line and exits
with code 2; an :class:`Interrupted` run, with 128 + the signal's number (130 for Ctrl-C).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ConfigError", "Interrupted", "StageInputMissing", "TattotronixError"]


class TattotronixError(Exception):
    """An error the user can act on. The message says what, which value, and what to do."""


class ConfigError(TattotronixError, ValueError):
    """A configuration value or key is wrong; the message says which and what is allowed."""


class StageInputMissing(TattotronixError):
    """A stage's input does not exist yet; the message names the command to run first.

    Args:
        path: the missing input (under ``paths.data``).
        stage: the stage that writes it (its script is ``stages/<stage>.py``).
        command: the command that writes it with the current run's overrides
            (``python stages/artwork.py artwork.source=my.png``); the bare script if None.
        also: where a run by hand would have written it, also looked at.
    """

    def __init__(self, path: Path, stage: str, command: str | None = None,
                 also: Path | None = None):
        where = f"{path}" if also is None else f"{path} (nor {also}, where runs by hand write)"
        super().__init__(
            f"missing input {where}: run the '{stage}' stage first: "
            f"{command or f'python stages/{stage}.py'} (or dvc repro)"
        )


class Interrupted(TattotronixError):
    """The run stopped safely on a stop signal (Ctrl-C, SIGTERM, SIGHUP); the message says
    where it stopped and how to go on. The stage runner prints ``<stage>: interrupted:
    <message>`` and exits with 128 + ``signum`` (130 for Ctrl-C), as for any interrupt.

    Attributes:
        signum: the (first) signal that asked for the stop.
    """

    def __init__(self, message: str, signum: int):
        super().__init__(message)
        self.signum = int(signum)
