"""Every command in the README's code blocks is run by a test, or says why not (issue 19).

The commands are the lines of README.md's ```` ```bash ````, ``sh``, ``shell`` and
``console`` blocks (in a ``console`` block, only the lines that start with ``$ ``): a line
ending in a backslash is joined to the next, a ``#`` comment is dropped, blank lines are
skipped, and runs of spaces become one. A comment that starts with ``or:`` offers another
command (``# or: pip install ...``), and counts as one.

``COVERED`` says how each is covered:

* ``("test", "tests/<file>.py::<test>", how)``: that test runs the command, or the same
  command at a test's size (a small drawing, a scratch data folder, a copy of the
  project); ``how`` says what it runs and what differs;
* ``("not run", why)``: no test runs it, and why (a real I2C device, a SLURM cluster, a
  display, a remote, the suite itself).

A command added to the README fails ``test_every_readme_command_is_covered`` until someone
says here how it is covered; one removed from the README fails
``test_every_entry_is_still_in_the_readme``. Pure parsing: no command is run here
(``tests/test_readme_runs.py`` runs those that no other test did).
"""

from __future__ import annotations

import ast
import re

from .conftest import ROOT

README = ROOT / "README.md"
SHELL_BLOCKS = ("bash", "sh", "shell", "console")
TEST, NOT_RUN = "test", "not run"

SMALL = "on a small drawing (a 24 mm PNG the test makes) in a scratch data folder"

#: README command -> (TEST, test id, how) or (NOT_RUN, why)
COVERED: dict[str, tuple[str, ...]] = {
    # --- the top of the README
    ('python3 -m venv .venv && . .venv/bin/activate && pip install -c constraints.txt -e '
     '".[dev]" && dvc repro'): (
        TEST, "tests/test_config.py::test_dvc_repro_on_a_clean_clone",
        "`dvc repro` on a clean clone of the project: every stage on the built-in drawings, "
        "certify included, then a second `dvc repro` that runs nothing; the test runs in the "
        "suite's environment, and making a fresh venv and `pip install -e \".[dev]\"` into it "
        "is what `bash .ci/run` does before the tests"),
    ". .venv/bin/activate && python -m pytest": (
        NOT_RUN, "the test suite itself; `bash .ci/run` runs it, and "
        "tests/test_docs.py::test_readme_opens_with_the_two_fresh_machine_commands checks "
        "that .ci/run holds `python -m pytest`"),
    # --- curved surfaces
    "python stages/surface.py surface=forearm mask.width_mm=60": (
        TEST, "tests/test_onskin_plan.py::test_the_stage_writes_its_outputs",
        "the command with the built-in drawing's name, a coarser reachability map and a "
        "scratch output folder; its metrics, npz and figure checked"),
    ("python stages/surface.py surface=mesh surface.mesh_file=arm.stl "
     "surface.mesh_unit_mm=10"): (
        TEST, "tests/test_onskin_plan.py::"
        "test_a_scanned_phantom_plans_with_its_distortion_reported",
        "the same settings through the library (plan_on_surface, the stage's body) on the "
        "phantom exported as a noisy, re-triangulated STL in mm, a smaller design placed "
        "on its top; the stage around the body is the one the forearm's test runs"),
    # --- the job server
    "tattotronix serve": (
        TEST, "tests/test_server.py::"
        "test_serve_binds_locally_without_a_token_and_to_the_network_with_one",
        "the command as written (on a free port, in a scratch folder): it answers this "
        "machine with no token"),
    "tattotronix serve --host 0.0.0.0": (
        TEST, "tests/test_server.py::"
        "test_serve_binds_locally_without_a_token_and_to_the_network_with_one",
        "the command as written (on a free port, in a scratch folder): the token is "
        "printed once and every route but the page needs it"),
    # --- sharing the cache
    "dvc remote add -d shared /mnt/team/tattotronix-dvc": (
        NOT_RUN, "needs a team folder (a local or network mount) for the remote and writes "
        "the clone's .dvc/config; DVC's own command, nothing of this project"),
    'pip install "dvc[s3]" && dvc remote add -d shared s3://my-bucket/tattotronix': (
        NOT_RUN, "installs a package from the registry and needs an S3 bucket and its "
        "credentials (the network)"),
    "dvc push": (
        NOT_RUN, "needs a configured remote (the repository configures none); DVC's own "
        "command"),
    # --- collision safety
    "python stages/collision.py 'pose=[0,1.57,0,0,0]'": (
        TEST, "tests/test_collision.py::test_cli_pose_names_the_colliding_pairs",
        "the same command (the `cli_runs` fixture), on the committed k-DOP geometry; the "
        "test reads its one JSON object"),
    # --- simulation and control
    "python stages/draw.py backend=mujoco art=emblem": (
        TEST, "tests/test_draw.py::test_draw_writes_log_metrics_and_ink_on_every_backend[mujoco]",
        f"backend=mujoco {SMALL}; on the emblem itself it is the `simulate@emblem` stage "
        "(`art=emblem backend=mujoco window=null`), which "
        "tests/test_config.py::test_dvc_repro_on_a_clean_clone runs"),
    "python stages/draw.py backend=model art=emblem 'window=[200,12]' controller.wn=40": (
        TEST, "tests/test_draw.py::test_unstable_controller_is_reported_not_crashed",
        f"backend=model with a window (window=[0,3], controller.rate_hz=200) {SMALL}; the "
        "README's overrides compose in tests/test_bad_inputs.py::"
        "test_every_value_the_project_uses_is_inside_the_ranges"),
    "python stages/draw.py artwork.source=my_logo.png": (
        TEST, "tests/test_draw.py::test_draw_writes_log_metrics_and_ink_on_every_backend[mujoco]",
        "artwork.source=<a PNG the test makes> (with mask.width_mm=24), planned in memory in "
        "a data folder that holds only the robot models"),
    "python stages/draw.py art=emblem speed=2 viewer=true": (
        NOT_RUN, "viewer=true opens a window: needs a display; speed=2 on a stored drawing "
        "is run in memory by tests/test_control.py::"
        "test_stored_drawing_is_played_as_is_and_retimed_for_another_speed"),
    # --- the real arm
    "python stages/draw.py backend=arm art=emblem preview=true": (
        TEST, "tests/test_arm.py::test_preview_prints_the_plan_and_sends_nothing",
        f"preview=true {SMALL}, with an I2C device path that does not exist"),
    "python stages/draw.py backend=arm art=emblem dry_run=true realtime=false": (
        TEST, "tests/test_arm.py::"
        "test_dry_run_draw_is_deterministic_appends_and_survives_a_missing_bus",
        f"dry_run=true realtime=false {SMALL}, twice, and a real run without the device"),
    "python stages/draw.py backend=arm art=emblem": (
        NOT_RUN, "drives the servos: needs the PCA9685 on I2C (the Raspberry Pi with the "
        "arm); tests/test_arm.py::test_missing_i2c_device_is_a_clear_error runs it without "
        "the device, and the dry runs run everything up to the bus"),
    "python stages/draw.py backend=arm art=emblem resume=true": (
        TEST, "tests/test_arm.py::"
        "test_bus_error_half_way_then_resume_completes_with_a_fresh_approach",
        "resume=true after an I2C error half-way, as dry runs against the recording bus, "
        f"{SMALL}"),
    # --- calibrating the servos
    "python stages/servo_pulse.py channel=0 width_us=1500": (
        TEST, "tests/test_readme_runs.py::test_servo_pulse_holds_the_widths_typed_and_ends_off",
        "the same command with dry_run=true (a recording bus instead of the PCA9685) and "
        "widths typed on standard input"),
    # --- sweeps, launchers and experiments
    "python stages/control_study.py -m controller.structure=pid_g_v controller.wn=40,80,160": (
        TEST, "tests/test_studies.py::test_multirun_sweeps_in_parallel_with_joblib",
        f"the same sweep over controller.wn=40,160 through the joblib launcher, {SMALL}"),
    "python stages/rate.py -m controller.rate_hz=200,500 controller.wn=40,80": (
        TEST, "tests/test_studies.py::test_the_cluster_sweep_runs_through_submitit",
        f"rate.py -m over controller.wn=40,80 at controller.rate_hz=1000, {SMALL}, through "
        "submitit's local launcher (the default joblib launcher runs in "
        "test_multirun_sweeps_in_parallel_with_joblib)"),
    "python stages/approach.py -m toolpath.approach_mm=0.25,0.75 plant.damping=0,0.01": (
        TEST, "tests/test_studies.py::test_approach_and_resample_cases_replan_the_path",
        f"approach.py {SMALL}: one case by hand, then the configured cases at once, not a -m "
        "sweep; the sweep's jobs run in test_multirun_sweeps_in_parallel_with_joblib, and the "
        "case names that carry another swept key (plant.damping) are checked by "
        "test_sweep_suffix_names_the_other_overrides_only_in_a_multirun"),
    "python stages/rate.py -m hydra/launcher=cluster hydra.launcher.partition=cpu "
    "controller.rate_hz=200,500,1000 controller.wn=40,80,160": (
        NOT_RUN, "submits jobs to a SLURM cluster; "
        "tests/test_studies.py::test_the_cluster_sweep_runs_through_submitit composes "
        "hydra/launcher=cluster and runs the same kind of sweep through submitit's local "
        "executor"),
    # --- metrics and experiments
    "dvc metrics show": (
        TEST, "tests/test_headline.py::test_dvc_metrics_show_lists_the_headline",
        "`dvc metrics show --json` in the project: the one file is the headline; "
        "tests/test_config.py::test_dvc_repro_on_a_clean_clone does the same on a clean "
        "clone"),
    "dvc metrics show data/metrics/headline": (
        TEST, "tests/test_headline.py::test_dvc_metrics_show_lists_the_headline",
        "the same command in the project: a figure per row, a drawing per column, at most "
        "80 columns"),
    "dvc exp run -S controller.wn=120": (
        TEST, "tests/test_config.py::test_the_readme_experiments_rerun_only_what_they_change",
        "the same command on a clean clone (its pipeline cut to the study artwork's "
        "drawing) after its `dvc repro`: only what depends on wn reruns, every other "
        "stage's settings stamp is unchanged; certify records the drift in "
        "tests/test_certify.py::test_inside_an_experiment_the_drift_is_a_metric_not_a_failure; "
        "tests/test_headline.py::test_the_readme_exp_show_fits_120_columns runs it in a "
        "small DVC project"),
    "dvc exp show --only-changed --drop 'Created|State|Executor|params.yaml|data/' --keep "
    "'entries|time_s|cycle|max_um|mean_um|bleed|cover|servo_mm'": (
        TEST, "tests/test_config.py::test_the_readme_experiments_rerun_only_what_they_change",
        "the same command (read from the README) after the experiment on a clean clone: at "
        "most 120 columns, the headline of the commit and of the experiment; "
        "tests/test_headline.py::test_the_readme_exp_show_fits_120_columns runs it in a "
        "small DVC project with this project's params.yaml"),
    "dvc metrics diff --targets data/metrics/headline": (
        TEST, "tests/test_config.py::test_the_readme_experiments_rerun_only_what_they_change",
        "the same command (read from the README) after the experiment on a clean clone: "
        "every drawing's settled mean moved"),
    "git checkout -- . && dvc checkout": (
        TEST, "tests/test_config.py::test_the_readme_experiments_rerun_only_what_they_change",
        "the same command (read from the README) after the experiment on a clean clone; "
        "then `git status` is clean and `dvc status` up to date"),
    "dvc exp run --queue -S controller.wn=80 && dvc exp run --run-all": (
        TEST, "tests/test_config.py::test_the_readme_experiments_rerun_only_what_they_change",
        "the same with controller.wn=120, on a clean clone (its pipeline cut to the study "
        "artwork's drawing): the workspace stays clean and "
        "`dvc exp show --csv` lists both experiments with their headline"),
    # --- CAD meshes
    "python stages/robot.py robot.cad_dir=../shared/cad/meshes": (
        TEST, "tests/test_readme_runs.py::test_the_cad_commands_run_on_the_meshes",
        "robot.cad_dir=$TATTOTRONIX_CAD_DIR (CI: ../shared/cad/meshes) with paths.data=<tmp>; "
        "skipped without the meshes (marked cad)"),
    "python stages/mass.py robot.cad_dir=../shared/cad/meshes": (
        TEST, "tests/test_readme_runs.py::test_the_cad_commands_run_on_the_meshes",
        "robot.cad_dir=$TATTOTRONIX_CAD_DIR (CI: ../shared/cad/meshes) with paths.data=<tmp>; "
        "skipped without the meshes (marked cad)"),
    # --- development
    'pip install -c constraints.txt -e ".[dev]"': (
        NOT_RUN, "installs from the package registries; `bash .ci/run` does it, into a "
        "fresh venv"),
    "ruff check . && mypy": (
        NOT_RUN, "`bash .ci/run` runs both (lint, types) before the tests"),
    "lint-imports": (
        NOT_RUN, "`bash .ci/run` runs it (the layers) before the tests"),
    "python -m tattotronix.devtools.codedeps --write": (
        TEST, "tests/test_readme_runs.py::test_codedeps_write_restores_a_dropped_code_dep",
        "the same command in a copy of the project whose dvc.yaml lost a code dep"),
    'python -m pytest -m "not slow"': (
        NOT_RUN, "the test suite itself (the quick part of it)"),
    "python benchmarks/run.py": (
        NOT_RUN, "measures speed (medians over repeated runs, minutes of work) and prints "
        "it; no test checks a benchmark figure"),
    "bash .ci/run": (
        NOT_RUN, "CI itself: a fresh venv from the package registries, lint, types and "
        "every test"),
}


def _strip_comment(line: str) -> tuple[str, str]:
    """(the command, the comment) of one line; a ``#`` inside quotes is not a comment."""
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i], line[i + 1:]
    return line, ""


def commands(text: str) -> list[str]:
    """The commands of the shell code blocks of a markdown text, in order (see the module
    docstring for the rules)."""
    found: list[str] = []
    for lang, body in re.findall(r"^```([\w-]*)[^\n]*\n(.*?)^```", text, re.M | re.S):
        if lang not in SHELL_BLOCKS:
            continue
        joined: list[str] = []
        pending = ""
        for raw in body.splitlines():
            if lang == "console":
                if not raw.startswith("$ ") and not pending:
                    continue  # the output of a command
                raw = raw[2:] if raw.startswith("$ ") and not pending else raw
            if raw.rstrip().endswith("\\"):
                pending += raw.rstrip()[:-1] + " "
                continue
            joined.append(pending + raw)
            pending = ""
        if pending:
            joined.append(pending)
        for line in joined:
            command, comment = _strip_comment(line)
            alternative = re.match(r"\s*or:\s*(.+)", comment)
            other = _strip_comment(alternative.group(1))[0] if alternative else ""
            for c in (command, other):
                c = " ".join(c.split())
                if c:
                    found.append(c)
    return found


def _test_exists(test_id: str) -> bool:
    """Whether ``tests/<file>.py::<name>[<param>]`` (or ``::<Class>::<name>``) is a test
    function defined in that file."""
    path, *names = test_id.split("::")
    file = ROOT / path
    if not (path.startswith("tests/") and file.is_file() and names):
        return False
    names[-1] = re.sub(r"\[.*\]$", "", names[-1])
    body: list[ast.stmt] = ast.parse(file.read_text(encoding="utf-8")).body
    for i, name in enumerate(names):
        last = i == len(names) - 1
        kinds = (ast.FunctionDef, ast.AsyncFunctionDef) if last else (ast.ClassDef,)
        node = next((n for n in body if isinstance(n, kinds) and n.name == name), None)
        if node is None:
            return False
        body = node.body
    return names[-1].startswith("test")


def test_every_readme_command_is_covered() -> None:
    missing = [c for c in commands(README.read_text(encoding="utf-8")) if c not in COVERED]
    assert not missing, (
        "README commands that no entry of COVERED in tests/test_readme_commands.py names; "
        "add each with the test that runs it, or the reason none does:\n  "
        + "\n  ".join(missing))


def test_every_entry_is_still_in_the_readme() -> None:
    found = set(commands(README.read_text(encoding="utf-8")))
    stale = [c for c in COVERED if c not in found]
    assert not stale, ("entries of COVERED whose command is no longer in README.md (edit or "
                       "delete them):\n  " + "\n  ".join(stale))


def test_every_entry_names_a_test_that_exists_or_a_reason() -> None:
    bad = []
    for command, entry in COVERED.items():
        if entry[0] == TEST and len(entry) == 3 and entry[2].strip():
            if not _test_exists(entry[1]):
                bad.append(f"{command}: no test {entry[1]}")
        elif entry[0] == NOT_RUN and len(entry) == 2 and entry[1].strip():
            continue
        else:
            bad.append(f"{command}: want ({TEST!r}, test id, how) or ({NOT_RUN!r}, why), "
                       f"got {entry!r}")
    assert not bad, "\n".join(bad)


def test_the_extraction_rules() -> None:
    text = "\n".join([
        "Prose: `python not_this.py`.",
        "```bash",
        "python a.py  x=1   # a comment",
        "python b.py -m k=1,2 \\",
        "    j=3      # on SLURM",
        "",
        '# or: pip install "p[x]" && q   # with a note',
        "# a comment line",
        "echo '#not a comment' \"a # b\"",
        "```",
        "```python",
        "import os",
        "```",
        "```console",
        "$ tool --flag",
        "output line",
        "```",
        "```",
        "plain block",
        "```",
    ])
    assert commands(text) == ["python a.py x=1", "python b.py -m k=1,2 j=3",
                              'pip install "p[x]" && q', "echo '#not a comment' \"a # b\"",
                              "tool --flag"]
    assert _test_exists("tests/test_readme_commands.py::test_the_extraction_rules")
    assert _test_exists(
        "tests/test_draw.py::test_draw_writes_log_metrics_and_ink_on_every_backend[model]")
    assert not _test_exists("tests/test_readme_commands.py::commands")
    assert not _test_exists("tests/test_readme_commands.py::test_nothing")
    assert not _test_exists("tests/no_such_file.py::test_x")
