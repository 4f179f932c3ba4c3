"""Each DVC stage reruns exactly when the code it runs changes: one stamp per stage.

A stage's code is found from the imports themselves (:mod:`tattotronix.io.codegraph`:
the script or ``-m`` module, every project module it imports at run time, the packages
on the way, the package data a module names, and the Hydra plugins). Listing those files
as deps of every stage made ``dvc.lock`` 12,000 lines, most of them code, which DVC reads
and rewrites after every stage. Instead:

* the ``code`` stage (``python -m tattotronix.devtools.codedeps --stamp
  ${paths.data}/code``) depends on the code folders and writes one stamp per stage,
  ``<paths.data>/code/<stage>.txt``: ``<sha256>  <path>`` for each file the stage runs;
* every Python stage depends on its own stamp, and on no code file.

An edit reruns ``code`` (a second), which rewrites the stamps of exactly the stages that
run the edited file, and DVC then reruns exactly those. The stage's outputs record the
stamp's hash as their code version (:func:`tattotronix.io.provenance.code_version`).

    python -m tattotronix.devtools.codedeps --write    # dvc.yaml: the stamps as deps
    python -m tattotronix.devtools.codedeps --check    # exit 1, naming the stage
    python -m tattotronix.devtools.codedeps --status   # the stages an edit makes stale

``--write`` is needed only when a stage is added, renamed or removed: a new import is
found by the ``code`` stage at the next ``dvc repro``.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tattotronix.config.dvclock import guard
from tattotronix.config.tracked import stage_names
from tattotronix.errors import ConfigError
from tattotronix.io.codegraph import (
    CodeGraph,
    entry_of,
    stamp_text,
    write_stamp_folder,
)

__all__ = ["CODE_STAGE", "CodeGraph", "StageDeps", "check", "code_deps", "stage_deps",
           "stamps", "write", "write_stamps"]

ROOT = Path(__file__).resolve().parents[2]
#: a dep that starts with one of these is code (never a dep of a stage but ``code``)
CODE_PREFIXES = ("stages/", "tattotronix", "hydra_plugins")
#: the stage that writes the stamps, and what it depends on
CODE_STAGE = "code"
CODE_FOLDERS = ("hydra_plugins", "stages", "tattotronix")
#: where the stamps go, as dvc.yaml says it
STAMP_DIR = "${paths.data}/code"
_STAMP_CMD = f"python -m tattotronix.devtools.codedeps --stamp {STAMP_DIR}"


#: the stage that checks params.yaml and writes the param stamps
CONFIG_STAGE = "config"
PARAM_STAMP_DIR = "${paths.data}/params"


def stamp_dep(stage: str) -> str:
    """The stamp a stage depends on, as dvc.yaml says it."""
    return f"{STAMP_DIR}/{stage}.txt"


def param_stamp_dep(stage: str) -> str:
    """The param stamp a stage depends on, as dvc.yaml says it
    (:func:`tattotronix.config.tracked.param_stamps`)."""
    return f"{PARAM_STAMP_DIR}/{stage}.json"


def _meta_params(body: dict[str, Any]) -> list[str] | None:
    meta = body.get("meta")
    if isinstance(meta, dict) and isinstance(meta.get("params"), list):
        return [str(k) for k in meta["params"]]
    return None


def _collapse(root: Path, graph: CodeGraph, files: set[Path]) -> list[str]:
    """``files`` as dvc.yaml paths, with a folder standing for all of its files."""
    out: list[str] = []
    remaining = set(files)
    folders = sorted({p.parent for p in files if root in p.parents}
                     | {q for p in files for q in p.parents if root in q.parents},
                     key=lambda p: len(p.parts))
    for folder in folders:
        if folder.parent == root and folder.name == "stages":
            continue  # stages/ holds one entry point per stage: never all of them
        inside = graph.all_files(folder)
        if inside and inside <= remaining:
            out.append(folder.relative_to(root).as_posix())
            remaining -= inside
    out.extend(p.relative_to(root).as_posix() for p in remaining)
    return sorted(out)


def code_files(cmd: str, graph: CodeGraph) -> list[Path] | None:
    """The files a stage command runs, folders expanded (None: not a Python command)."""
    entry = entry_of(cmd, graph.root)
    if entry is None:
        return None
    path, modules = entry
    if not path.is_file():
        raise SystemExit(f"codedeps: {cmd!r} runs {path}, which does not exist")
    return graph.expand(graph.closure(path, modules))


def code_deps(cmd: str, graph: CodeGraph) -> list[str] | None:
    """The code a stage command runs, as dvc.yaml paths with a folder standing for all of
    its files (None: not a Python command)."""
    entry = entry_of(cmd, graph.root)
    if entry is None:
        return None
    path, modules = entry
    if not path.is_file():
        raise SystemExit(f"codedeps: {cmd!r} runs {path}, which does not exist")
    return _collapse(graph.root, graph, graph.closure(path, modules))


@dataclass
class StageDeps:
    """One Python stage of dvc.yaml: what its deps say and the code it runs."""

    name: str
    cmd: str
    deps: list[str]
    wanted: list[str]  # the code it runs (code_deps)

    @property
    def code_written(self) -> list[str]:
        return [d for d in self.deps if _is_code(d)]


def _is_code(dep: object) -> bool:
    return isinstance(dep, str) and dep.startswith(CODE_PREFIXES)


def _stage_bodies(doc: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any]]]:
    for name, stage in doc["stages"].items():
        yield name, (stage["do"] if "do" in stage else stage)


def _python_stages(doc: dict[str, Any], graph: CodeGraph) -> Iterator[tuple[str, dict[str, Any]]]:
    for name, body in _stage_bodies(doc):
        if name != CODE_STAGE and entry_of(str(body["cmd"]), graph.root) is not None:
            yield name, body


def _load(root: Path) -> dict[str, Any]:
    import yaml

    try:
        loader: Any = yaml.CSafeLoader
    except AttributeError:  # pragma: no cover - PyYAML without libyaml
        loader = yaml.SafeLoader
    doc = yaml.load((root / "dvc.yaml").read_text(encoding="utf-8"), Loader=loader)
    assert isinstance(doc, dict)
    return doc


def stage_deps(root: Path = ROOT) -> list[StageDeps]:
    """Every Python stage of ``root/dvc.yaml``, with its deps and the code it runs."""
    doc = _load(root)
    graph = CodeGraph(root)
    out = []
    for name, body in _python_stages(doc, graph):
        wanted = code_deps(str(body["cmd"]), graph)
        assert wanted is not None
        out.append(StageDeps(name, str(body["cmd"]), [str(d) for d in body.get("deps", [])],
                             wanted))
    return out


def stamps(root: Path = ROOT) -> dict[str, str]:
    """stage -> the text of its stamp, from the code as it is now."""
    doc = _load(root)
    graph = CodeGraph(root)
    out = {}
    for name, body in _python_stages(doc, graph):
        files = code_files(str(body["cmd"]), graph)
        assert files is not None
        out[name] = stamp_text(root, files)
    return out


def write_stamps(folder: Path, root: Path = ROOT) -> list[str]:
    """Write every stage's stamp into ``folder`` (:func:`write_stamp_folder`); the stages
    whose stamp changed."""
    return write_stamp_folder(folder, stamps(root), ".txt")


def stale(folder: Path, root: Path = ROOT) -> list[str]:
    """The stages whose stamp in ``folder`` differs from the code as it is now: what
    ``dvc repro`` will rerun for the code's sake."""
    out = []
    for name, text in stamps(root).items():
        path = folder / f"{name}.txt"
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            out.append(name)
    return out


def _code_stage(names: list[str]) -> dict[str, Any]:
    return {"cmd": _STAMP_CMD, "deps": list(CODE_FOLDERS),
            "outs": [{stamp_dep(n): {"cache": False}} for n in names]}


def check(root: Path = ROOT) -> list[str]:
    """One line per way dvc.yaml differs from one stamp per stage (``--write`` mends)."""
    doc = _load(root)
    graph = CodeGraph(root)
    problems = []
    names: list[str] = []
    stamped: list[str] = []
    for name, body in _python_stages(doc, graph):
        names.append(name)
        deps = [str(d) for d in body.get("deps", [])]
        code = [d for d in deps if _is_code(d)]
        if code:
            problems.append(f"stage '{name}': code deps listed ({', '.join(code)}): its "
                            "stamp stands for them")
        if stamp_dep(name) not in deps:
            problems.append(f"stage '{name}': missing its stamp {stamp_dep(name)}")
        if body.get("params"):
            problems.append(f"stage '{name}': params listed for DVC: list them under "
                            "meta: {params: ...} and depend on the param stamp")
        if _meta_params(body) is not None:
            stamped.append(name)
            if param_stamp_dep(name) not in deps:
                problems.append(f"stage '{name}': missing its param stamp "
                                f"{param_stamp_dep(name)}")
    config = doc["stages"].get(CONFIG_STAGE) or {}
    outs = [next(iter(o)) if isinstance(o, dict) else o for o in config.get("outs", [])]
    missing = [param_stamp_dep(n) for n in stamped if param_stamp_dep(n) not in outs]
    if missing:
        problems.append(f"stage '{CONFIG_STAGE}': does not write {', '.join(missing)}")
    code_stage = doc["stages"].get(CODE_STAGE)
    if code_stage != _code_stage(names):
        problems.append(f"stage '{CODE_STAGE}': not the stamp writer for {', '.join(names)}")
    return problems


def write(root: Path = ROOT) -> int:
    """Make dvc.yaml's code deps one stamp per stage (and the ``code`` stage write them);
    the number of stages changed."""
    from ruamel.yaml import YAML
    from ruamel.yaml.comments import CommentedMap, CommentedSeq

    yaml = YAML()
    yaml.indent(mapping=2, sequence=4, offset=2)
    yaml.width = 4096
    path = root / "dvc.yaml"
    doc = yaml.load(path.read_text(encoding="utf-8"))
    graph = CodeGraph(root)
    changed = 0
    names = []
    stamped: list[str] = []
    for name, body in _python_stages(doc, graph):
        names.append(name)
        if body.get("params"):  # DVC would parse params.yaml for them: stamp them
            meta = body.setdefault("meta", CommentedMap())
            meta["params"] = CommentedSeq(body.pop("params"))
            changed += 1
        deps = body.get("deps")
        written = [str(d) for d in deps] if deps is not None else []
        wanted = [d for d in written if not _is_code(d) and d != stamp_dep(name)
                  and d != param_stamp_dep(name)]
        wanted.append(stamp_dep(name))
        if _meta_params(body) is not None:
            stamped.append(name)
            wanted.append(param_stamp_dep(name))
        if written == wanted:
            continue
        changed += 1
        if deps is None:
            body["deps"] = CommentedSeq(wanted)
            continue
        deps.clear()
        deps.extend(wanted)
    config = doc["stages"].get(CONFIG_STAGE)
    if config is not None:
        outs = config.setdefault("outs", CommentedSeq())
        keep = [o for o in outs
                if not str(next(iter(o)) if isinstance(o, dict) else o).startswith(
                    PARAM_STAMP_DIR + "/")]
        fresh_outs = [*keep, *(CommentedMap({param_stamp_dep(n): CommentedMap(
            {"cache": False})}) for n in stamped)]
        if [dict(o) if isinstance(o, dict) else o for o in outs] != [
                dict(o) if isinstance(o, dict) else o for o in fresh_outs]:
            outs.clear()
            outs.extend(fresh_outs)
            changed += 1
    stage = _code_stage(names)
    current = doc["stages"].get(CODE_STAGE)
    if current is None or dict(current) != stage:
        changed += 1
        fresh = CommentedMap()
        fresh["cmd"] = stage["cmd"]
        fresh["deps"] = CommentedSeq(stage["deps"])
        fresh["outs"] = CommentedSeq(
            CommentedMap({k: CommentedMap(v)}) for o in stage["outs"] for k, v in o.items())
        if current is None:
            doc["stages"].insert(0, CODE_STAGE, fresh)
            doc["stages"].yaml_set_comment_before_after_key(
                CODE_STAGE, before="The code each stage runs, one stamp per stage "
                "(tattotronix/devtools/codedeps.py)", indent=2)
        else:
            doc["stages"][CODE_STAGE] = fresh
    if changed:
        with path.open("w", encoding="utf-8") as fh:
            yaml.dump(doc, fh)
    return changed


def _stamp_folder(root: Path) -> Path:
    """Where the pipeline's stamps are (``paths.data`` of params.yaml, then ``code``)."""
    import yaml

    params = yaml.safe_load((root / "params.yaml").read_text(encoding="utf-8")) or {}
    data = (params.get("paths") or {}).get("data") or "data"
    return root / str(data) / "code"


def main(argv: list[str] | None = None) -> int:
    """``--write``, ``--check`` (exit 1 on any difference), ``--stamp DIR`` or ``--status``."""
    ap = argparse.ArgumentParser(prog="python -m tattotronix.devtools.codedeps",
                                 description=(__doc__ or "").split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="compare dvc.yaml with the stages")
    mode.add_argument("--write", action="store_true", help="rewrite the code deps in dvc.yaml")
    mode.add_argument("--stamp", metavar="DIR", help="write every stage's stamp into DIR")
    mode.add_argument("--status", action="store_true",
                      help="name the stages whose code changed since their stamps")
    args = ap.parse_args(argv)
    if args.stamp:
        if os.environ.get("DVC_STAGE"):
            # the first stage of every repro: never build on a cut-short dvc.lock
            try:
                guard(Path.cwd(), stage_names(Path.cwd()))
            except ConfigError as exc:
                print(f"codedeps: error: {exc}", file=sys.stderr)
                return 2
        changed = write_stamps(Path(args.stamp))
        print(f"codedeps: new code for {', '.join(changed)}" if changed else
              "codedeps: every stage's code is as stamped")
        return 0
    if args.status:
        names = stale(_stamp_folder(ROOT))
        print("codedeps: code changed for " + ", ".join(names) + " (dvc repro reruns them)"
              if names else "codedeps: no stage's code changed")
        return 0
    if args.write:
        n = write()
        print(f"codedeps: {n} stage(s) rewritten in dvc.yaml" if n else
              "codedeps: dvc.yaml is up to date")
        return 0
    problems = check()
    for line in problems:
        print(line, file=sys.stderr)
    if problems:
        print("codedeps: run python -m tattotronix.devtools.codedeps --write", file=sys.stderr)
        return 1
    print("codedeps: every stage depends on its stamp")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
