"""Atomic stage outputs: every file a stage writes lands together, or not at all.

Where a run writes is not always where it reads. ``dvc repro`` reads and writes under
``paths.data``, but a run by hand (``python stages/...``, a ``-m`` sweep, a notebook)
whose ``paths.data`` is the pipeline's own folder writes under ``runs/`` beside it
instead, so it never changes what DVC tracks (:func:`write_root`). A run by hand reads
what the runs by hand wrote first, then ``paths.data`` (:meth:`Outputs.input`), so stages
run by hand one after another chain.

The jobs of a ``-m`` sweep run side by side with the same outputs in mind, so each job
writes under a folder of its own, ``sweeps/<its overrides>/`` under that root
(``runs/sweeps/toolpath.pitch_mm=1.0/toolpath/emblem.npz``), unless the stage names each
job's files itself (:meth:`Outputs.sweep_suffix`: ``draw.py`` and the studies' cases).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import shlex
import shutil
import sys
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

from tattotronix.errors import StageInputMissing

__all__ = ["HAND_RUNS", "PIPELINE_DATA", "PROJECT_ROOT", "SWEEP_JOBS", "Outputs", "override_key",
           "write_root"]

log = logging.getLogger("tattotronix")

#: the project's root folder (the checkout: conf/, stages/, dvc.yaml)
PROJECT_ROOT = Path(__file__).resolve().parents[2]
#: the pipeline's data folder (``paths.data``'s default, ``${paths.data}`` in dvc.yaml)
PIPELINE_DATA = "data"
#: where a run by hand writes instead, beside the pipeline's data folder (git-ignored)
HAND_RUNS = "runs"
#: the folder, under where a run writes, that holds a folder per job of a ``-m`` sweep
SWEEP_JOBS = "sweeps"
#: the longest job folder name (a file name has at most 255 bytes); longer ones are cut and
#: end in a hash of the whole
_MAX_JOB_NAME = 120


#: overrides that say where outputs go, not what they are: never part of a name
_WHERE_KEYS = ("paths.data", "paths.out")


def override_key(override: str) -> str:
    """The key a command line's override sets (``+a.b=1`` -> ``a.b``; ``~c`` -> ``c``)."""
    return override.split("=", 1)[0].lstrip("+~")


def _is_pipeline_data(data: Path) -> bool:
    return data.resolve() == (PROJECT_ROOT / PIPELINE_DATA).resolve()


def write_root(data: str | Path, out: str | Path | None = None) -> Path:
    """Where a run writes, given where it reads (``paths.data``) and ``paths.out``.

    * ``paths.out`` when it is set: the explicit choice (``paths.out=data`` writes into
      the pipeline's folder on purpose, and then ``dvc status`` calls its stages stale);
    * ``paths.data`` inside a DVC stage (``DVC_STAGE`` is set): ``dvc repro`` owns it;
    * ``paths.data`` when it is a folder of the user's own, not the pipeline's
      (``paths.data=/tmp/try``: a scratch pipeline);
    * otherwise, a run by hand on the pipeline's data: ``runs/`` beside it, with the
      same layout (``runs/metrics/runs/emblem-mujoco.json``, ``runs/figures/...``).
    """
    data = Path(data)
    if out is not None and str(out) != "":
        return Path(out)
    if os.environ.get("DVC_STAGE") or not _is_pipeline_data(data):
        return data
    return data.parent / HAND_RUNS


class Outputs:
    """Where a stage writes, with every file written atomically as one transaction.

    ``data`` is where the run reads (``paths.data``); ``root`` is where it writes
    (:func:`write_root`). :meth:`path` and the writers are under ``root``; inputs are read
    with :meth:`input`: what a run by hand wrote under ``root``, else under ``data``. A job
    of a ``-m`` sweep (``sweep_overrides`` given) writes under a folder of its own
    instead, ``<root>/sweeps/<its overrides>/``, unless its stage names the job's files
    itself (:meth:`sweep_suffix`).

    Files go to temporary names next to their targets; only when the stage body returns
    are they renamed into place. A stage interrupted half-way leaves nothing that looks
    finished (the temporaries are removed, and the folders made for them when empty).
    """

    def __init__(self, data: str | Path, sweep_overrides: list[str] | None = None,
                 root: str | Path | None = None, overrides: Sequence[str] | None = None):
        #: where the run reads its inputs (``paths.data``)
        self.data = Path(data)
        #: the run's command-line overrides, for the command a missing input names
        #: (:meth:`rerun_command`); None: Hydra's, else the command line's under DVC
        self.overrides = list(overrides) if overrides is not None else None
        self._hand_reads: set[Path] = set()  # inputs read from a run by hand (logged once)
        #: where runs write (``root`` if given, else :func:`write_root` of ``data``)
        self.shared_root = Path(root) if root is not None else write_root(self.data)
        #: in a Hydra multirun, this job's overrides (``key=value``); None otherwise
        self.sweep_overrides = sweep_overrides
        job = self._job_name()
        #: where this run writes: :attr:`shared_root`, or a sweep job's own folder in it
        self.root = self.shared_root / SWEEP_JOBS / job if job else self.shared_root
        #: every file the last commit put in place, in order
        self.written: list[Path] = []
        self._pending: list[tuple[Path, Path]] = []
        self._removals: list[Path] = []  # files that go at the commit
        self._made: list[Path] = []  # folders made for the temporaries, outermost first

    def _overrides_named(self, ignore: tuple[str, ...] = ()) -> list[str]:
        """This job's overrides that tell it from the other jobs (``/`` made ``_``), sorted:
        not where it writes, not Hydra's own, not the keys in ``ignore``."""
        skip = (*ignore, *_WHERE_KEYS)
        return sorted(o.replace("/", "_") for o in self.sweep_overrides or ()
                      if override_key(o) not in skip and not o.startswith("hydra"))

    def _job_name(self) -> str:
        """The folder of this sweep job (``toolpath.pitch_mm=1.0``); "" outside a sweep."""
        name = ",".join(self._overrides_named())
        if len(name) > _MAX_JOB_NAME:
            digest = hashlib.sha256(name.encode()).hexdigest()[:12]
            name = f"{name[:_MAX_JOB_NAME - 13]}~{digest}"
        return name

    def sweep_suffix(self, ignore: tuple[str, ...] = ()) -> str:
        """In a multirun, ``@k=v,k=v`` from this job's overrides (keys in ``ignore`` left
        out), so that the jobs of a sweep never write the same file; "" otherwise.

        A stage that calls this names each job's files itself (with the suffix, and the
        ignored keys in its names), so from then on the job writes under
        :attr:`shared_root`, beside the other jobs, not under a folder of its own. Call it
        before staging any file.
        """
        if not self.sweep_overrides:
            return ""
        if self._pending and self.root != self.shared_root:
            raise RuntimeError("sweep_suffix() after a file was staged under the job's folder")
        self.root = self.shared_root
        keep = self._overrides_named(ignore)
        return "@" + ",".join(keep) if keep else ""

    @property
    def by_hand(self) -> bool:
        """Whether this run writes somewhere other than where it reads."""
        return self.root.resolve() != self.data.resolve()

    def path(self, *parts: str) -> Path:
        """A path to write, under :attr:`root`."""
        return self.root.joinpath(*parts)

    def _hand_roots(self) -> list[Path]:
        """Where a run by hand's outputs are looked for before ``paths.data``: this run's
        own folder (a sweep job's), then where the runs write (:attr:`shared_root`);
        neither when it is ``paths.data`` itself (inside a DVC stage)."""
        roots: list[Path] = []
        for folder in (self.root, self.shared_root):
            if all(folder.resolve() != r.resolve() for r in (self.data, *roots)):
                roots.append(folder)
        return roots

    def input(self, *parts: str) -> Path:
        """A path to read: what a run by hand wrote there, else the one under ``paths.data``.

        A run by hand writes under :attr:`root` (``runs/``, or a sweep job's folder in it),
        so the next stage run by hand reads it there first (``python stages/artwork.py
        artwork.source=my.png`` then ``python stages/mask.py artwork.source=my.png``
        chain). Each file read from a run by hand is logged once. Inside a DVC stage, and
        for a ``paths.data`` of the user's own, the run writes where it reads, so this is
        ``paths.data`` joined with ``parts``.

        Args:
            parts: the path under ``paths.data`` (``"artwork", "emblem.png"``, or one
                ``/``-separated string).

        Returns:
            The first that exists of the run's own folder's, :attr:`shared_root`'s and
            ``paths.data``'s; ``paths.data``'s when none does (for :meth:`require`).
        """
        for folder in self._hand_roots():
            path = folder.joinpath(*parts)
            if path.exists():
                if path not in self._hand_reads:
                    self._hand_reads.add(path)
                    log.info("reading %s, which a run by hand wrote (not %s)", _shown(path),
                             _shown(self.data.joinpath(*parts)))
                return path
        return self.data.joinpath(*parts)

    def input_root(self, *parts: str) -> Path:
        """The folder :meth:`input` reads ``parts`` under (``runs/``, a sweep job's folder
        or ``paths.data``), for readers that take a data folder (``XRecord.load(root,
        ...)``).

        Args:
            parts: the path under ``paths.data``, as for :meth:`input`.
        """
        path = self.input(*parts)
        rel = Path(*parts)
        return Path(*path.parts[:len(path.parts) - len(rel.parts)])

    def rerun_command(self, stage: str) -> str:
        """The command that runs ``stage`` with this run's overrides (``python
        stages/artwork.py artwork.source=my.png``): what makes an input it lacks."""
        overrides = self.overrides if self.overrides is not None else _run_overrides()
        return " ".join(["python", f"stages/{stage}.py", *(shlex.quote(o) for o in overrides)])

    def require(self, path: Path, stage: str) -> Path:
        """Return ``path`` if it exists, else stop naming the command that makes it.

        Args:
            path: the input (from :meth:`input`).
            stage: the stage that writes it (its script is ``stages/<stage>.py``).

        Raises:
            StageInputMissing: ``path`` does not exist; the message names the command that
                writes it, with this run's overrides (:meth:`rerun_command`).
        """
        if not path.exists():
            also = None
            if self._hand_roots() and path.is_relative_to(self.data):
                also = self.shared_root / path.relative_to(self.data)
            raise StageInputMissing(path, stage, self.rerun_command(stage), also)
        return path

    def provenance(self, cfg: object, inputs: Mapping[str, str | Path]) -> str:
        """The provenance of a file this run writes from ``cfg`` and the files ``inputs``
        (:func:`tattotronix.io.artifacts.make_provenance`): an input under the data folder
        or a folder this run writes in is recorded by its path there (``ik/emblem.npz``),
        so the same files written elsewhere (a plan the Python API saved) record the same
        bytes."""
        from tattotronix.io.artifacts import make_provenance

        return make_provenance(cfg, inputs, roots=(self.data, self.root, self.shared_root))

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

    def write_csv(self, target: Path, rows: Sequence[Mapping[str, object]]) -> Path:
        """Stage a CSV table (a header from the first row's keys; floats with 6 significant
        digits, so equal numbers give equal bytes), as ``dvc plots`` reads it."""
        if not rows:
            raise ValueError(f"no rows for {target}")
        columns = list(rows[0])
        lines = [",".join(columns)]
        for row in rows:
            lines.append(",".join(_cell(row.get(c)) for c in columns))
        return self.write_text(target, "\n".join(lines) + "\n")

    def write_timings(self, stage: str, name: str, timings: Mapping[str, float]) -> Path:
        """Stage the wall times of a run: ``timings/<stage>/<name>.json`` under
        :attr:`root`. They vary from run to run, so they are kept apart from the metrics (which
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
        self.written = []
        for tmp, target in self._pending:
            tmp.replace(target)
            self.written.append(target)
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

    def report(self, name: str) -> str:
        """One line on where the last commit wrote (every stage ends with it)."""
        files = [p for p in self.written if "timings" not in p.parts]
        if not files:
            return f"{name}: wrote nothing"
        shown = ", ".join(_shown(p) for p in files[:4])
        more = f" and {len(files) - 4} more under {_shown(self.root)}/" if len(files) > 4 else ""
        line = f"{name}: wrote {shown}{more}"
        if self.by_hand and _is_pipeline_data(self.data):
            line += (f" (a run by hand: the pipeline's {_shown(self.data)}/ is untouched; "
                     "paths.out=data writes there)")
        return line

    @contextmanager
    def transaction(self) -> Iterator[Outputs]:
        """Commit on success, abort on any exception (including Ctrl-C)."""
        try:
            yield self
        except BaseException:
            self.abort()
            raise
        self.commit()


#: The command line's overrides of a stage run by hand whose settings Hydra did not
#: compose (:func:`tattotronix.config.params.hand_settings`), set by the stage runner.
_command_line: list[str] | None = None


def use_command_line(overrides: Sequence[str]) -> None:
    """Record a stage run's own overrides (a run by hand without Hydra's composition):
    what :meth:`Outputs.rerun_command` repeats."""
    global _command_line
    _command_line = list(overrides)


def _run_overrides() -> list[str]:
    """This run's command-line overrides: Hydra's (a run by hand, a sweep job's own), else
    the command line's inside a DVC stage or a run by hand Hydra did not compose; none in
    a notebook."""
    try:
        from hydra.core.hydra_config import HydraConfig

        if HydraConfig.initialized():
            return [str(o) for o in HydraConfig.get().overrides.task]
    except (ImportError, ValueError):  # pragma: no cover - hydra is a dependency
        pass
    if _command_line is not None:
        return list(_command_line)
    if os.environ.get("DVC_STAGE"):
        return [a for a in sys.argv[1:] if "=" in a]
    return []


def _shown(path: Path) -> str:
    """A path as a person reads it: relative to the working folder when under it."""
    try:
        return path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return str(path)


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}" if math.isfinite(value) else ""
    text = str(value)
    if any(ch in text for ch in ',"\n'):
        return '"' + text.replace('"', '""') + '"'
    return text
