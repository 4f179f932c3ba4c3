"""The headline figures (README, "Metrics and experiments"): what ``dvc metrics show`` and
``dvc exp show`` list, written by the ``headline`` stage from the full metrics; the full
metrics stay git-tracked outputs."""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.report.headline import (
    FILE,
    FOLDER,
    KEYS,
    SERVO_CASE,
    drawing_headline,
    format_headline,
    write_headline,
)
from tattotronix.studies.servo import STUDY as SERVO_STUDY

from .conftest import PYTHON, ROOT
from .test_readme_commands import README, commands

ENV = {**{k: v for k, v in os.environ.items() if not k.startswith("DVC_")},
       "DVC_NO_ANALYTICS": "1", "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
       "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t",
       "PATH": os.pathsep.join([str(Path(PYTHON).parent), os.environ.get("PATH", "")])}


def _metrics(root: Path, name: str, *, marking_um: float = 18.74765, diverged: bool = False,
             servo: bool = False) -> None:
    """Minimal trajectory, run (and servo) metrics files of one drawing under ``root``."""
    m = root / "metrics"
    (m / "trajectory").mkdir(parents=True, exist_ok=True)
    (m / "runs").mkdir(parents=True, exist_ok=True)
    (m / "trajectory" / f"{name}.json").write_text(json.dumps(
        {"entries": 80, "duration_s": 650.3734653671817, "cycle_over_marking": 1.2105324}))
    ink = None if diverged else {"bleed_share": 0.0023794951, "coverage": 0.5583870348}
    (m / "runs" / f"{name}-mujoco.json").write_text(json.dumps(
        {"marking_max_um": None if diverged else marking_um, "settled_mean_um": 1.099023662,
         "artwork": ink, "verdict": "diverged" if diverged else "ok"}))
    if servo:
        (m / "servo" / name).mkdir(parents=True, exist_ok=True)
        (m / "servo" / name / f"{SERVO_CASE}.json").write_text(json.dumps(
            {"whole": {"marking_max_um": 18551.71812}}))


def test_the_headline_of_a_drawing_is_rounded_and_null_where_a_run_has_no_figure(
        tmp_path: Path) -> None:
    _metrics(tmp_path, "emblem", servo=True)
    _metrics(tmp_path, "wild", marking_um=88177.2, diverged=True)
    h = drawing_headline(tmp_path / "metrics", "emblem")
    assert tuple(h) == KEYS
    assert h == {"entries": 80, "time_s": 650.4, "cycle": 1.21, "max_um": 18.7,
                 "mean_um": 1.1, "bleed": 0.00238, "cover": 0.558, "servo_mm": 18.6}
    wild = drawing_headline(tmp_path / "metrics", "wild")
    assert wild["max_um"] is None and wild["bleed"] is None and wild["cover"] is None
    assert wild["servo_mm"] is None  # no servo study for this drawing
    line = format_headline("emblem", h)
    assert "18.7 µm" in line and "18.6 mm" in line and "0.238 %" in line, line


def test_the_stage_writes_the_study_artworks_file_and_one_per_figure(tmp_path: Path) -> None:
    _metrics(tmp_path, "emblem", servo=True)
    _metrics(tmp_path, "lineart", marking_um=16.93)
    out = Outputs(tmp_path, root=tmp_path)
    write_headline(out, "emblem")
    out.commit()
    study = (tmp_path / "metrics" / FILE).read_text()
    assert list(json.loads(study)) == list(KEYS)  # dvc exp show keeps the file's order
    assert sorted(p.name for p in (tmp_path / "metrics" / FOLDER).iterdir()) == sorted(
        f"{k}.json" for k in KEYS)
    max_um = json.loads((tmp_path / "metrics" / FOLDER / "max_um.json").read_text())
    assert max_um == {"emblem": 18.7, "lineart": 16.9}
    servo = json.loads((tmp_path / "metrics" / FOLDER / "servo_mm.json").read_text())
    assert servo == {"emblem": 18.6, "lineart": None}
    # the same inputs give the same bytes
    again = Outputs(tmp_path, root=tmp_path)
    write_headline(again, "emblem")
    again.commit()
    assert (tmp_path / "metrics" / FILE).read_text() == study


def test_a_missing_run_names_the_stage_to_run(tmp_path: Path) -> None:
    _metrics(tmp_path, "emblem")
    (tmp_path / "metrics" / "runs" / "emblem-mujoco.json").unlink()
    with pytest.raises(TattotronixError, match=r"simulate@emblem"):
        write_headline(Outputs(tmp_path, root=tmp_path), "emblem")
    with pytest.raises(TattotronixError, match=r"trajectory@other"):
        write_headline(Outputs(tmp_path, root=tmp_path), "other")


def test_the_servo_case_is_the_servo_studys_as_mounted_case() -> None:
    cfg = compose_settings()
    assert SERVO_CASE in SERVO_STUDY.cases(cfg.study)
    assert SERVO_STUDY.case_name(compose_settings(SERVO_STUDY.cases(cfg.study)[SERVO_CASE])) \
        == SERVO_CASE


def test_only_the_headline_is_a_dvc_metric_and_every_metrics_file_stays_in_git() -> None:
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    declared = {}
    for name, stage in stages.items():
        body = stage.get("do", stage)
        for entry in body.get("metrics") or []:
            declared[name] = list(entry)
        for entry in body.get("outs") or []:
            path = entry if isinstance(entry, str) else next(iter(entry))
            if "/metrics/" in path or path.endswith("certify.json"):
                assert isinstance(entry, dict) and entry[path] == {"cache": False}, path
    assert declared == {"headline": ["${paths.data}/metrics/headline.json"]}
    assert "metrics" not in yaml.safe_load((ROOT / "dvc.yaml").read_text())


def test_dvc_metrics_show_lists_the_headline(tmp_path: Path) -> None:
    """`dvc metrics show` lists the study artwork's headline, one line; `dvc metrics show
    data/metrics/headline` every drawing's, in 80 columns (the README's commands)."""
    if not (ROOT / "data" / "metrics" / FILE).is_file():
        pytest.skip("the headline is not checked out (run `dvc repro headline`)")
    shown = subprocess.run([PYTHON, "-m", "dvc", "metrics", "show", "--json"], cwd=ROOT,
                           env=ENV, capture_output=True, text=True, timeout=300)
    assert shown.returncode == 0, shown.stderr
    (files,) = [rev["data"] for rev in json.loads(shown.stdout).values()]
    assert list(files) == [f"data/metrics/{FILE}"]
    assert list(files[f"data/metrics/{FILE}"]["data"]) == [
        k for k in KEYS if files[f"data/metrics/{FILE}"]["data"].get(k) is not None]
    (every,) = [shlex.split(c) for c in commands(README.read_text(encoding="utf-8"))
                if c.startswith("dvc metrics show data/metrics/headline")]
    table = subprocess.run([PYTHON, "-m", *every], cwd=ROOT, env=ENV, capture_output=True,
                           text=True, timeout=300)
    assert table.returncode == 0, table.stderr
    lines = table.stdout.splitlines()
    assert len(lines) == 1 + len(KEYS) and max(map(len, lines)) <= 80, table.stdout
    assert lines[0].split()[1:3] == ["emblem", "lineart"], lines[0]


def test_the_readme_exp_show_fits_120_columns(tmp_path: Path) -> None:
    """The README's `dvc exp show` after its experiment, in a small DVC project with this
    project's params.yaml and headline keys (values as wide as the emblem's, or wider):
    the table fits 120 columns and shows the headline of the commit and the experiment.
    The same command on this project is checked after its real experiment in
    tests/test_config.py::test_dvc_repro_on_a_clean_clone."""
    repo = tmp_path / "exp"
    (repo / "src").mkdir(parents=True)
    shutil.copy(ROOT / "params.yaml", repo / "params.yaml")
    (repo / "src" / "a.py").write_text("")
    (repo / "headline.py").write_text(
        "import json, os, yaml\n"
        "wn = yaml.safe_load(open('params.yaml'))['controller']['wn']\n"
        "os.makedirs('data/metrics/runs', exist_ok=True)\n"
        "h = {'entries': 280, 'time_s': 1198.1, 'cycle': 1.21, 'max_um': 88200.0,\n"
        "     'mean_um': round(11800.0 * 160 / wn, 1), 'bleed': 0.00238, 'cover': 0.558,\n"
        "     'servo_mm': 18.6}\n"
        f"open('data/metrics/{FILE}', 'w').write(json.dumps(h))\n"
        "open('data/metrics/runs/x.json', 'w').write(json.dumps({'wn': wn}))\n")
    (repo / "dvc.yaml").write_text(
        "stages:\n"
        "  sim:\n"
        "    cmd: python headline.py\n"
        "    deps: [headline.py, src, params.yaml]\n"  # as the config stage's
        "    params: [controller]\n"
        "    outs:\n"
        "      - data/metrics/runs:\n"
        "          cache: false\n"
        "    metrics:\n"
        f"      - data/metrics/{FILE}:\n"
        "          cache: false\n"
        "  after:\n"
        "    cmd: cp data/metrics/runs/x.json after.json\n"
        "    deps: [data/metrics/runs]\n"
        "    outs: [after.json]\n")

    def run(*argv: str, env: dict[str, str] = ENV) -> subprocess.CompletedProcess[str]:
        done = subprocess.run(list(argv), cwd=repo, env=env, capture_output=True, text=True,
                              timeout=300)
        assert done.returncode == 0, done.stdout + done.stderr
        return done

    dvc = (PYTHON, "-m", "dvc")
    run("git", "init", "-q", "-b", "main")
    run(*dvc, "init", "-q")
    run("git", "add", "-A")
    run("git", "commit", "-qm", "init")
    run(*dvc, "repro", "-q")
    run("git", "add", "-A")
    run("git", "commit", "-qm", "repro")
    run(*dvc, *shlex.split(_readme("dvc exp run -S"))[1:])
    show = run(*dvc, *shlex.split(_readme("dvc exp show --only-changed"))[1:], "--no-pager",
               env={**ENV, "COLUMNS": "1000"})
    lines = [line.rstrip() for line in show.stdout.splitlines() if line.strip()]
    assert max(map(len, lines)) <= 120, show.stdout
    header = next(line for line in lines if "Experiment" in line).split()
    assert header[1:] == [*KEYS, "controller.wn"], header
    rows = [line.split() for line in lines if line.split()[-1] in ("120", "160.0", "160")]
    assert len(rows) == 3, show.stdout  # the workspace, main and the experiment
    assert all(len(r) >= len(KEYS) + 2 and "-" not in r[-len(KEYS) - 1:] for r in rows)


def _readme(prefix: str) -> str:
    (command,) = [c for c in commands(README.read_text(encoding="utf-8"))
                  if c.startswith(prefix)]
    return command
