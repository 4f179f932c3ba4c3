"""Configuration: params.yaml is the composition of conf/, never silently stale."""

from __future__ import annotations

import csv
import io
import json
import os
import shlex
import shutil
import subprocess
from collections.abc import Callable
from enum import Enum
from pathlib import Path

import pytest
import yaml

from tattotronix.config.params import (
    compose,
    compose_settings,
    main,
    params_text,
    stale_message,
    write_params,
)
from tattotronix.config.schema import to_dict
from tattotronix.config.tracked import param_stamps
from tattotronix.errors import ConfigError
from tattotronix.report.headline import KEYS as HEADLINE_KEYS

from .conftest import PYTHON, ROOT, small_pipeline

MISSING_MARK = object()
ENV = {k: v for k, v in os.environ.items() if not k.startswith("DVC_")}
# DVC runs `python stages/...`: make that the interpreter running the tests
ENV["PATH"] = os.pathsep.join([str(Path(PYTHON).parent), ENV.get("PATH", "")])


def _readme_command(prefix: str) -> str:
    """The one README command that starts with ``prefix``: the tests run the README's own
    words."""
    from .test_readme_commands import README, commands

    (command,) = [c for c in commands(README.read_text(encoding="utf-8"))
                  if c.startswith(prefix)]
    return command


def _project_copy(tmp: Path) -> Path:
    """conf/, params.yaml, dvc.yaml and stages/ in a scratch folder (the code stays
    installed)."""
    for sub in ("conf", "stages"):
        shutil.copytree(ROOT / sub, tmp / sub)
    for name in ("params.yaml", "dvc.yaml"):
        shutil.copy(ROOT / name, tmp / name)
    return tmp


def test_params_yaml_equals_the_composition_of_conf() -> None:
    assert stale_message(ROOT) is None
    assert (ROOT / "params.yaml").read_text() == params_text(compose(conf_dir=ROOT / "conf"))


def _leaves(node: object, key: str) -> list[tuple[str, object]]:
    """Every (dotted key, value) a YAML mapping sets, its defaults list left out."""
    if not isinstance(node, dict):
        return [(key, node)]
    return [leaf for k, v in node.items() if k != "defaults"
            for leaf in _leaves(v, f"{key}.{k}" if key else str(k))]


def _same(written: object, default: object) -> bool:
    if isinstance(default, Enum):
        return written == default.name
    if isinstance(default, float | int) and not isinstance(default, bool):
        return isinstance(written, float | int) and float(written) == float(default)
    return written == default


def test_no_conf_value_restates_its_default() -> None:
    """Issue 31: a default is written once, in the schema. A value in conf/ is either one
    the schema has no default for (the robot, the studies' cases, the calibration) or a
    choice: one that differs from what the file's own defaults list gives (the schema's
    default, or for surface=panel, the forearm option it starts from)."""
    from omegaconf import OmegaConf
    from omegaconf.errors import MissingMandatoryValue

    from tattotronix.config.schema import SCHEMAS, Config

    restated = []
    for path in sorted((ROOT / "conf").rglob("*.yaml")):
        rel = path.relative_to(ROOT / "conf")
        if rel.parts[0] == "hydra":
            continue
        group = "" if len(rel.parts) == 1 else rel.parts[0]
        written = yaml.safe_load(path.read_text()) or {}
        base = OmegaConf.structured(SCHEMAS[group] if group else Config)
        for parent in [d for d in written.get("defaults", []) if isinstance(d, str)
                       and not d.startswith("_") and "/" not in d]:  # an option it extends
            base = OmegaConf.merge(base, {k: v for k, v in yaml.safe_load(
                (path.parent / f"{parent}.yaml").read_text()).items() if k != "defaults"})
        for key, value in _leaves({k: v for k, v in written.items() if k != "hydra"}, ""):
            try:  # a key under a MISSING node (the robot, the cases) has no default
                default = OmegaConf.select(base, key, default=MISSING_MARK,
                                           throw_on_missing=True)
            except MissingMandatoryValue:
                continue
            if default is MISSING_MARK:
                continue
            plain = OmegaConf.to_container(default) if OmegaConf.is_config(default) \
                else default
            if _same(value, plain):
                restated.append(f"{rel}: {key}")
    assert not restated, restated


@pytest.mark.parametrize("overrides", [[], ["robot.mass_model=box", "mask.width_mm=120"]])
def test_dvc_composition_equals_ours(tmp_path: Path, overrides: list[str]) -> None:
    from dvc.utils.hydra import compose_and_dump

    out = tmp_path / "params.yaml"
    compose_and_dump(out, str(ROOT / "conf"), None, "config", str(ROOT), overrides)
    assert yaml.safe_load(out.read_text()) == yaml.safe_load(params_text(compose(overrides)))


def test_dvc_hydra_composition_is_enabled() -> None:
    text = (ROOT / ".dvc" / "config").read_text()
    assert "[hydra]" in text and "enabled = True" in text


@pytest.mark.parametrize(
    ("override", "words"),
    [
        ("robot.mass_model=prnited", ["prnited", "printed, box", "robot.mass_model"]),
        ("robot.mas_model=box", ["mas_model"]),
        ("mask.method=foo", ["foo", "threshold, edges"]),
        ("mask.width_mm=wide", ["mask.width_mm", "wide"]),
    ],
)
def test_bad_key_or_value_names_the_key(override: str, words: list[str]) -> None:
    with pytest.raises(ConfigError) as err:
        compose([override])
    assert all(w in str(err.value) for w in words), str(err.value)


def test_stale_params_are_detected_and_recomposed(tmp_path: Path) -> None:
    root = _project_copy(tmp_path)
    robot = root / "conf" / "robot" / "tattotronix.yaml"
    robot.write_text(robot.read_text() + "mass_model: box\n")
    msg = stale_message(root)
    assert msg and "robot.mass_model" in msg and "'printed'" in msg and "'box'" in msg
    assert "tattotronix-params" in msg
    assert main(["--check", "--root", str(root)]) == 1
    write_params(root)
    assert stale_message(root) is None
    assert main(["--check", "--root", str(root)]) == 0


def test_stage_under_dvc_refuses_stale_params(tmp_path: Path) -> None:
    root = _project_copy(tmp_path)
    env = {**ENV, "DVC_STAGE": "robot", "DVC_ROOT": str(root)}
    run = subprocess.run([PYTHON, "stages/robot.py"], cwd=root, env=env,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert (root / "data" / "robot" / "tattotronix.urdf").exists()
    toolpath = root / "conf" / "toolpath" / "default.yaml"
    toolpath.write_text(toolpath.read_text() + "pitch_mm: 0.5\n")
    run = subprocess.run([PYTHON, "stages/robot.py"], cwd=root, env=env,
                         capture_output=True, text=True)
    assert run.returncode == 2
    assert "params.yaml is stale" in run.stderr and "toolpath.pitch_mm" in run.stderr
    # under `dvc exp run` DVC has just composed params.yaml with the experiment's overrides
    run = subprocess.run([PYTHON, "stages/robot.py"], cwd=root,
                         env={**env, "DVC_EXP_NAME": "exp"}, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr


def test_stage_overrides_paths_data_and_leaves_no_hydra_folders(tmp_path: Path) -> None:
    run = subprocess.run(
        [PYTHON, str(ROOT / "stages" / "robot.py"), "paths.data=out", "robot.tool=none"],
        cwd=tmp_path, env=ENV, capture_output=True, text=True,
    )
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    report = yaml.safe_load((tmp_path / "out" / "metrics" / "robot.json").read_text())
    assert report["tool"] == "none"
    # the settings the models came from, published for the stages that build on them
    published = json.loads((tmp_path / "out" / "robot" / "config.json").read_text())
    assert published == to_dict(compose_settings(["robot.tool=none"]).robot)


def test_stage_bad_value_exits_with_the_allowed_values(tmp_path: Path) -> None:
    run = subprocess.run(
        [PYTHON, str(ROOT / "stages" / "robot.py"), "paths.data=out", "robot.mass_model=prnited"],
        cwd=tmp_path, env=ENV, capture_output=True, text=True,
    )
    assert run.returncode != 0
    assert "expected one of [printed, box]" in run.stdout + run.stderr
    assert not (tmp_path / "out").exists()


def _clone(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """A clean clone of this checkout, and the environment its commands run in."""
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    # PYTHONPATH: the clone runs its own code, not the checkout the tests started from
    env = {**ENV, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
           "GIT_COMMITTER_EMAIL": "t@t", "PYTHONPATH": str(clone)}
    return clone, env


def _runner(clone: Path, env: dict[str, str]
            ) -> Callable[..., subprocess.CompletedProcess[str]]:
    def run(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(list(argv), cwd=clone, env=env, capture_output=True, text=True)
    return run


DVC = (PYTHON, "-m", "dvc")


@pytest.mark.slow
def test_dvc_repro_on_a_clean_clone(tmp_path: Path) -> None:
    """Acceptance: `dvc repro` on a fresh clone runs every stage, leaves git clean and ends
    certified. Git clean means every output (dvc.lock holds the hash of each, the npz with
    their provenance, the figures, the animation) and every metrics file is byte for byte
    what another machine wrote at another commit, in another folder: no absolute path,
    time of day, commit or wall time reaches a file (those go to data/timings/), and
    `dvc metrics diff --targets data/metrics` shows nothing. The one DVC metric is the headline.
    A second `dvc repro` does nothing; a new `controller.wn` in conf/ marks
    exactly its dependents changed. (The README's experiments on this pipeline:
    test_the_readme_experiments_rerun_only_what_they_change, below.)"""
    clone, env = _clone(tmp_path)
    run = _runner(clone, env)
    first = run(*DVC, "repro")
    assert first.returncode == 0, first.stdout[-4000:] + first.stderr[-4000:]
    assert "Running stage 'robot'" in first.stdout
    # every output came out byte-identical to the committed dvc.lock, so git sees no change
    # and certify (whose inputs are the committed documents, metrics and figures) is up to
    # date without running
    assert run("git", "status", "--porcelain").stdout == "", run("git", "status").stdout
    # every metrics file, not only the headline (DVC's default): none moved
    diff = run(*DVC, "metrics", "diff", "--targets", "data/metrics", "data/certify.json")
    assert diff.returncode == 0 and diff.stdout.strip() == "", diff.stdout
    shown = json.loads(run(*DVC, "metrics", "show", "--json").stdout)
    (metrics,) = [rev["data"] for rev in shown.values()]
    assert list(metrics) == ["data/metrics/headline.json"], list(metrics)
    assert list(metrics["data/metrics/headline.json"]["data"]) == list(HEADLINE_KEYS)
    assert (clone / "data" / "timings" / "ik" / "emblem.json").is_file()  # the wall times
    assert ("Running stage 'certify'" in first.stdout
            or "Stage 'certify' didn't change" in first.stdout)
    for stage in ("config", "mass"):
        assert f"Stage '{stage}'" in first.stdout or f"stage '{stage}'" in first.stdout
    second = run(*DVC, "repro")
    assert second.returncode == 0
    assert "Running stage" not in second.stdout
    assert "up to date" in run(*DVC, "status").stdout

    # a new bandwidth in conf/: params.yaml follows, and DVC sees exactly the stages that
    # read it as changed (what the README's experiment reruns)
    ctl = clone / "conf" / "controller" / "default.yaml"
    ctl.write_text(ctl.read_text() + "wn: 120.0\n")
    assert run(PYTHON, "-m", "tattotronix.config.params").returncode == 0
    status = run(*DVC, "status").stdout
    assert "simulate@emblem" in status and "robot:" not in status, status


#: the stages the README's experiment needs (the study artwork's drawing, its figures and
#: the headline), and some it must leave alone
EXPERIMENT_STAGES = ("code", "config", "robot", "artwork", "mask", "toolpath", "ik",
                     "trajectory", "simulate", "figures", "headline")


@pytest.mark.slow
def test_the_readme_experiments_rerun_only_what_they_change(tmp_path: Path) -> None:
    """The README's experiments, in its own words, on a clean clone whose pipeline is cut
    to the study artwork's drawing (the project's stages and commands; the whole
    pipeline's reproduction is the test above): `dvc exp run -S controller.wn=120` reruns
    only what depends on wn, and leaves the settings of every other stage as they were;
    `dvc metrics diff` shows the tracking change in the headline (and in the full metrics
    when named); the README's `dvc exp show` fits 120 columns with the headline figures of
    the commit and the experiment; `git checkout -- . && dvc checkout` puts the commit's
    workspace back; the `--queue` / `--run-all` form leaves the workspace alone and
    `dvc exp show` lists both. (Certify's drift inside an experiment:
    tests/test_certify.py.)"""
    clone, env = _clone(tmp_path)
    run = _runner(clone, env)
    small_pipeline(clone, EXPERIMENT_STAGES, env, artworks=("emblem",))
    first = run(*DVC, "repro")
    assert first.returncode == 0, first.stdout[-4000:] + first.stderr[-4000:]
    # the drawing's tracked outputs come out as committed (the cut changed no stage; the
    # stamps of the stages cut away are gone)
    status = run("git", "status", "--porcelain", "data").stdout.splitlines()
    assert all(line.startswith(" D data/code/") or line.startswith(" D data/params/")
               for line in status), status
    assert run("git", "add", "-A").returncode == 0
    assert run("git", "commit", "-qm", "the study artwork's pipeline").returncode == 0

    # the README's experiment, in both forms: only what depends on wn reruns
    direct = run(*DVC, "exp", "run", "-S", "controller.wn=120")
    assert direct.returncode == 0, direct.stdout[-3000:] + direct.stderr[-3000:]
    ran = {line.split("'")[1] for line in direct.stdout.splitlines()
           if line.startswith("Running stage '")}
    assert {"simulate@emblem", "figures@emblem", "headline"} <= ran, ran
    untouched = ("robot", "artwork@emblem", "mask@emblem", "toolpath@emblem", "ik@emblem",
                 "trajectory@emblem")
    assert not ran & set(untouched), ran
    # on the whole pipeline, the experiment's params.yaml changes the settings stamp (what
    # DVC reruns a stage on) of the stages that read wn only: the studies set it per case,
    # and the planning stages never read it
    params = yaml.safe_load((clone / "params.yaml").read_text())
    before, after = param_stamps(ROOT), param_stamps(ROOT, params)
    moved = {stage for stage in before if before[stage] != after[stage]}
    assert {"simulate", "figures"} <= moved, moved
    assert not moved & {"robot", "toolpath", "ik", "trajectory", "deploy", "actuator",
                        "kinematics", "control", "rate", "servo"}, moved
    diff = run(*DVC, "metrics", "diff")  # the headline: the study artwork's errors moved
    assert diff.returncode == 0
    assert "data/metrics/headline.json" in diff.stdout and "mean_um" in diff.stdout, diff.stdout
    diff = run(*DVC, "metrics", "diff", "--targets", "data/metrics/runs/emblem-mujoco.json")
    assert "settled_mean_um" in diff.stdout, diff.stdout  # a full metrics file, named
    diff = run(*DVC, *shlex.split(_readme_command("dvc metrics diff --targets"))[1:])
    assert "emblem" in diff.stdout and "mean_um.json" in diff.stdout, diff.stdout
    # the README's `dvc exp show`: at its natural width (no terminal squeezes it) it fits
    # 120 columns, with the eight headline figures of the commit and of the experiment
    exp_show = shlex.split(_readme_command("dvc exp show --only-changed"))
    show = subprocess.run([PYTHON, "-m", *exp_show, "--no-pager"], cwd=clone,
                          env={**env, "COLUMNS": "1000"}, capture_output=True, text=True)
    assert show.returncode == 0, show.stderr
    lines = [line.rstrip() for line in show.stdout.splitlines() if line.strip()]
    assert max(map(len, lines)) <= 120, show.stdout
    header = next(line for line in lines if "Experiment" in line).split()
    assert header[1:] == [*HEADLINE_KEYS, "controller.wn"], header
    table = [line.split() for line in lines
             if line.split()[-1] in ("120", "120.0", "160", "160.0")]
    assert {float(row[-1]) for row in table} == {120.0, 160.0}, show.stdout
    assert all(len(row) >= len(HEADLINE_KEYS) + 2 for row in table), show.stdout
    # the README's way back: the commit's tracked files, and DVC's outputs from the cache
    back = run("bash", "-c", _readme_command("git checkout -- . && dvc checkout"))
    assert back.returncode == 0, back.stdout + back.stderr
    assert run("git", "status", "--porcelain").stdout == "", run("git", "status").stdout
    assert "up to date" in run(*DVC, "status").stdout
    # the README queues another value; the same one here (its run is as long)
    queued = run(*DVC, "exp", "run", "--queue", "-S", "controller.wn=120")
    assert queued.returncode == 0, queued.stdout + queued.stderr
    ran_all = run(*DVC, "exp", "run", "--run-all")
    assert ran_all.returncode == 0, ran_all.stdout[-3000:] + ran_all.stderr[-3000:]
    assert run("git", "status", "--porcelain").stdout == ""  # ran aside
    show = run(*DVC, "exp", "show", "--no-pager", "--csv")
    assert show.returncode == 0, show.stderr
    rows = list(csv.DictReader(io.StringIO(show.stdout)))
    wn_cols = [c for c in rows[0] if c.endswith("controller.wn")]
    wn = [r for r in rows if any(r[c] in ("120", "120.0") for c in wn_cols)]
    assert len(wn) >= 2, show.stdout  # both experiments are listed
    assert all(r["mean_um"] not in ("", "-") for r in wn), show.stdout  # with their headline
