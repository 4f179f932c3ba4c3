"""The faults a new user hits end in one line, and nothing is inked again (issue 29, item 3).

* The arm's state file: every field checked (a frame outside the program, a frame or a
  session of the wrong type, corrupt JSON); a bad one is refused in one line naming the
  file and the field, exit 2, before anything reaches the bus.
* A servo type at zero latency (no delay buffer) runs.
* A trajectory whose time does not strictly increase, or that holds NaN, is refused by
  every reader, naming the file.
* A folder named like a config key or group at the project root changes nothing: the
  search path of the project's compositions holds ``conf/`` (and ``params.yaml``
  composes with no folder on it at all).
* A ``-m`` sweep gives each job its own output folder.
* SIGTERM and SIGHUP clean up as Ctrl-C does (exit 143 and 129); Ctrl-C while a stage still
  imports its libraries ends in one line, 130; the arm's double Ctrl-C, 130.
* A needle that cannot draw the artwork (most of its ink outside it) is refused, naming
  ``toolpath.needle_width_mm``.
"""

from __future__ import annotations

import ast
import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tattotronix.config.params import compose_settings, load_params
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import DRY_RUN_STATE, TEST_HOOK_ENV, ArmState
from tattotronix.io.artifacts import TrajectoryRecord, make_provenance
from tattotronix.io.outputs import SWEEP_JOBS, Outputs
from tattotronix.kinematics import Chain
from tattotronix.robot.description import RobotDescription

from .conftest import PYTHON, ROOT, default_signals, stage_env

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _one_line(run: subprocess.CompletedProcess[str], start: str) -> str:
    """The run's one line on stderr (no traceback), which starts with ``start``."""
    assert "Traceback" not in run.stdout + run.stderr, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert lines[0].startswith(start), lines[0]
    return lines[0]


def _stage(*args: str, env: dict[str, str] | None = None, cwd: Path = ROOT
           ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PYTHON, *args], cwd=cwd, env=env or stage_env(), text=True,
                          capture_output=True, timeout=600, preexec_fn=default_signals)


# ------------------------------------------------------------------ the arm's state file

#: a paused state file of a 1545-frame program (the fields as the arm writes them)
STATE = {"q": [0.0, 0.1, -0.2, 0.0, 0.1], "drawing": "small", "program": "f64560116611139b",
         "frame": 100, "frames": 1545, "status": "paused", "reason": "SIGINT",
         "saved_at": 1.7e9, "drawn": 100, "session": 1}

#: id -> (a change to the state file's JSON, or its whole text; the field the refusal names)
BAD_STATES: dict[str, tuple[dict[str, object] | str, str]] = {
    "frame -5": ({"frame": -5}, "'frame'"),
    "frame 99999": ({"frame": 99999}, "'frame'"),
    "frame 611.7": ({"frame": 611.7}, "'frame'"),
    "frame '611'": ({"frame": "611"}, "'frame'"),
    "frame true": ({"frame": True}, "'frame'"),
    "drawn past the program": ({"drawn": 2000}, "'drawn'"),
    "session 'x'": ({"session": "x"}, "'session'"),
    "session -1": ({"session": -1}, "'session'"),
    "frames 1.5": ({"frames": 1.5}, "'frames'"),
    "status unknown": ({"status": "resting"}, "'status'"),
    "drawing a number": ({"drawing": 7}, "'drawing'"),
    "q of 4 angles": ({"q": [0.0, 0.0, 0.0, 0.0]}, "'q'"),
    "q with NaN": ({"q": [0.0, float("nan"), 0.0, 0.0, 0.0]}, "'q'"),
    "q with true": ({"q": [True, 0.0, 0.0, 0.0, 0.0]}, "'q'"),
    "an unknown field": ({"frme": 3}, "'frme'"),
    "corrupt JSON": ('{"q": [0.0, 0.1, -0.2, 0.0, 0.1], "frame": 10', "unreadable"),
    "a list": ("[1, 2, 3]", "not a JSON object"),
}


def _bad_state_text(change: dict[str, object] | str, base: dict[str, object]) -> str:
    return change if isinstance(change, str) else json.dumps({**base, **change})


@pytest.mark.parametrize("case", list(BAD_STATES))
def test_every_field_of_the_arm_state_is_checked(tmp_path: Path, case: str) -> None:
    change, field = BAD_STATES[case]
    path = tmp_path / "state.json"
    path.write_text(_bad_state_text(change, STATE))
    with pytest.raises(TattotronixError) as err:
        ArmState.load(path, 5)
    msg = str(err.value)
    assert msg.startswith(f"arm state file {path}: ") and field in msg, msg
    assert "\n" not in msg and "Nothing was sent" in msg
    path.write_text(json.dumps(STATE))
    assert ArmState.load(path, 5) == ArmState(**STATE)  # type: ignore[arg-type]


def _arm(data: Path, *extra: str, hook: str | None = None
         ) -> subprocess.CompletedProcess[str]:
    env = stage_env()
    env.pop(TEST_HOOK_ENV, None)
    if hook:
        env[TEST_HOOK_ENV] = hook
    return _stage("stages/draw.py", f"paths.data={data}", "backend=arm",
                  f"artwork.source={data.parent / 'small.png'}", *SMALL, "dry_run=true",
                  "realtime=false", *extra, env=env)


#: the state files a resume is refused on, at the stage: id -> (change, field)
STAGE_STATES = {k: BAD_STATES[k] for k in ("frame -5", "frame 99999", "frame 611.7",
                                           "frame '611'", "session 'x'", "corrupt JSON")}


def _a_marking_frame(draw_data: Path, scratch: Path, desc: RobotDescription) -> int:
    """A frame of the small drawing's arm program with the needle in the work: ten frames
    after the first that reaches the surface (from a whole dry run on a copy, so the
    interrupt lands where a lift is needed, whatever the path planner does)."""
    data = scratch / "data"
    shutil.copytree(draw_data, data)
    shutil.copy(draw_data.parent / "small.png", scratch / "small.png")
    whole = _arm(data)
    assert whole.returncode == 0, whole.stderr
    poses = [json.loads(line) for line in
             (data / "runs" / "small-arm" / "poses.jsonl").read_text().splitlines()]
    chain = Chain.from_description(desc)
    tip_z = chain.fk(np.array([p["q"] for p in poses]))[0][:, 2]
    surface = desc.panel_centre[2] + desc.panel_size[2] / 2
    down = np.flatnonzero(tip_z <= surface + 1e-5)
    assert down.size, "the small drawing never reaches the surface"
    return int(down[0]) + 10


@pytest.mark.slow
def test_a_bad_arm_state_is_refused_and_nothing_is_inked_twice(
        draw_data: Path, tmp_path: Path, desc: RobotDescription) -> None:
    """A double Ctrl-C while drawing: 130, one line. Then every bad state file (and one
    whose frame count is not the program's): exit 2, one line naming the file and the
    field, nothing sent, nothing written. Then the good one: the resume draws every frame
    once."""
    at = _a_marking_frame(draw_data, tmp_path / "whole", desc)
    first = _arm(draw_data, hook=f"draw:{at}:INT;lift:1:INT")
    assert first.returncode == 130, first.stderr
    line = _one_line(first, f"draw: interrupted: SIGINT while drawing, at frame {at} of ")
    assert "then SIGINT: noted and ignored" in line and line.endswith("resume=true")
    run = draw_data / "runs" / "small-arm"
    good = json.loads((run / DRY_RUN_STATE).read_text())
    assert (good["status"], good["frame"]) == ("paused", at)

    cases = {**STAGE_STATES, "frames not the program's": ({"frames": 611}, "'frames'")}
    runs = {}
    for key, (change, _) in cases.items():  # each on a copy of the data: two at a time
        data = tmp_path / key.replace(" ", "_").replace("'", "") / "data"
        shutil.copytree(draw_data, data)
        shutil.copy(draw_data.parent / "small.png", data.parent / "small.png")
        (data / "runs" / "small-arm" / DRY_RUN_STATE).write_text(_bad_state_text(change, good))
        runs[key] = data
    keys = list(runs)
    for i in range(0, len(keys), 2):
        procs = {k: subprocess.Popen(
            [PYTHON, "stages/draw.py", f"paths.data={runs[k]}", "backend=arm",
             f"artwork.source={runs[k].parent / 'small.png'}", *SMALL, "dry_run=true",
             "realtime=false", "resume=true"], cwd=ROOT, env=stage_env(), text=True,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE) for k in keys[i:i + 2]}
        for key, proc in procs.items():
            before = _files(runs[key])
            out, err = proc.communicate(timeout=600)
            r = subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
            state = runs[key] / "runs" / "small-arm" / DRY_RUN_STATE
            assert r.returncode == 2, (key, r.stderr)
            line = _one_line(r, f"draw: error: arm state file {state}: ")
            assert cases[key][1] in line and "Nothing was sent" in line, (key, line)
            assert _files(runs[key]) == before, key  # no pose, no I2C write, no state

    done = _arm(draw_data, "resume=true")
    assert done.returncode == 0, done.stderr
    poses = [json.loads(x) for x in (run / "poses.jsonl").open()]
    drawn = [p["frame"] for p in poses if p["phase"] == "draw"]
    assert sorted(drawn) == list(range(good["frames"]))  # every frame, once


# ------------------------------------------------------------------ zero latency


def test_a_servo_type_at_zero_latency_runs_without_a_delay_buffer(models: tuple[Path, Path]
                                                                  ) -> None:
    """``robot.servos.MG996R.latency_ms=0``: those joints' drives act on each command at
    once, the others' a latency later (MuJoCo keeps delay buffers for them only)."""
    from tattotronix.hardware import default_calibration
    from tattotronix.hardware.servo_model import joint_servos
    from tattotronix.plants.base import PlantSettings
    from tattotronix.plants.servo_plant import ServoArm
    from tattotronix.robot.description import build_description

    cfg = compose_settings(["robot.servos.MG996R.latency_ms=0", "servo.deadband=false",
                            "servo.backlash=false", "servo.quantise=false",
                            "servo.nonlinearity=false"])
    desc = build_description(cfg.robot)
    specs = joint_servos(cfg.robot, desc.joint_names, default_calibration(), cfg.servo)
    zero = [i for i, s in enumerate(specs) if s.latency_s == 0]
    late = [i for i, s in enumerate(specs) if s.latency_s > 0]
    assert zero and late  # MG996R on some joints, another type on the rest
    settings = PlantSettings.from_settings(cfg.plant, 0.0, desc.tip_frame)
    q0 = np.array([0.0, 0.3, -0.6, 0.0, 0.3])
    cmd = np.tile(q0, (10, 1))
    cmd[3:] += 0.05
    arm = ServoArm(models[1], settings, specs, lag=True, ideal_wn=300.0, q0=q0)
    run = arm.run(cmd, 50.0, q0)
    assert run.healthy and np.all(np.isfinite(run.shaft))
    sent = 3 / 50.0
    for i in zero + late:
        acts = float(run.t[np.flatnonzero(run.target[:, i] != q0[i])[0]])
        assert acts == pytest.approx(sent + specs[i].latency_s, abs=settings.dt_s), i


def test_the_servo_backend_draws_with_a_servo_type_at_zero_latency(draw_data: Path) -> None:
    r = _stage("stages/draw.py", f"paths.data={draw_data}", "backend=servo",
               f"artwork.source={draw_data.parent / 'small.png'}", *SMALL,
               "robot.servos.MG996R.latency_ms=0", "draw.progress=false", "window=[0,4]")
    assert r.returncode == 0, r.stderr
    metrics = json.loads((draw_data / "metrics" / "runs" / "small-servo.json").read_text())
    assert metrics["completed"] and 0.0 in metrics["controller"]["latency_ms"]


# ------------------------------------------------------------------ impossible trajectories


def _trajectory(data: Path, name: str = "small") -> Path:
    """The small drawing's trajectory, planned as the pipeline plans it, stored."""
    from tattotronix.app.pipeline import plan_drawing
    from tattotronix.robot.description import build_description

    cfg = compose_settings(SMALL)
    traj = plan_drawing(cfg, data.parent / "small.png", name, build_description(cfg.robot))
    path = TrajectoryRecord.path(data, name=name)
    path.parent.mkdir(parents=True, exist_ok=True)
    traj.save(path, make_provenance(cfg, {}))
    return path


def _damage(path: Path, **change: object) -> None:
    rec = TrajectoryRecord.load(path)
    arrays = {**rec.arrays(), **change}
    TrajectoryRecord(**arrays).save(path, make_provenance({}, {}))  # type: ignore[arg-type]


def _backwards(t: np.ndarray) -> np.ndarray:
    t = t.copy()
    t[40], t[41] = t[41], t[40]  # time runs back for one sample
    return t


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data folder with the robot models and the small drawing's trajectory."""
    from tattotronix.robot.description import build_description

    from .conftest import small_art, write_models

    data = tmp_path_factory.mktemp("traj") / "data"
    (data / "robot").mkdir(parents=True)
    desc = build_description(compose_settings().robot)
    urdf, mjcf = write_models(desc, data / "robot")
    urdf.rename(data / "robot" / f"{desc.name}.urdf")
    mjcf.rename(data / "robot" / f"{desc.name}.xml")
    small_art(data.parent / "small.png")
    _trajectory(data)
    return data


def test_every_impossible_trajectory_is_refused_naming_the_file(stored: Path,
                                                                 tmp_path: Path) -> None:


    good = TrajectoryRecord.load(TrajectoryRecord.path(stored, name="small"))
    n = len(good.t)
    cases = {
        "backwards": ({"t": _backwards(good.t)}, "'t' is not strictly increasing"),
        "standing still": ({"t": np.concatenate([good.t[:5], good.t[4:n - 1]])},
                           "'t' is not strictly increasing"),
        "NaN in q": ({"q": np.where(np.arange(n)[:, None] == 7, np.nan, good.q)},
                     "'q' is not finite"),
        "inf in t": ({"t": np.where(np.arange(n) == n - 1, np.inf, good.t)},
                     "'t' is not finite"),
        "inf in qd": ({"qd": np.where(np.arange(n)[:, None] == 3, -np.inf, good.qd)},
                      "'qd' is not finite"),
        "short q": ({"q": good.q[:-1]}, "'q' has shape"),
    }
    for case, (change, words) in cases.items():
        path = tmp_path / f"{case}.npz"
        shutil.copy(TrajectoryRecord.path(stored, name="small"), path)
        _damage(path, **change)
        with pytest.raises(TattotronixError) as err:
            TrajectoryRecord.load(path)
        msg = str(err.value)
        assert f"cannot read {path} (" in msg and words in msg, (case, msg)
        assert "re-run the 'trajectory' stage" in msg and "\n" not in msg, msg


@pytest.mark.parametrize(("stage", "args"), [
    ("collision", ["artwork.name=small"]),
    ("draw", ["backend=arm", "art=small", "preview=true"]),  # the arm's preview
])
@pytest.mark.parametrize("damage", ["backwards", "NaN in q"])
def test_a_stage_refuses_an_impossible_trajectory(stored: Path, tmp_path: Path, stage: str,
                                                  args: list[str], damage: str) -> None:
    data = tmp_path / "data"
    shutil.copytree(stored, data)
    path = TrajectoryRecord.path(data, name="small")
    good = TrajectoryRecord.load(path)
    _damage(path, **({"t": _backwards(good.t)} if damage == "backwards" else
                     {"q": np.where(np.arange(len(good.t))[:, None] == 7, np.nan, good.q)}))
    before = _files(data)
    r = _stage(f"stages/{stage}.py", f"paths.data={data}", *args)
    assert r.returncode == 2, r.stderr
    line = _one_line(r, f"{stage}: error: cannot read {path} (")
    assert ("strictly increasing" if damage == "backwards" else "'q' is not finite") in line
    assert _files(data) == before


# ------------------------------------------------------------------ the search path


GROUP_FOLDERS = ("art", "artwork", "robot", "toolpath", "mask", "hydra")


def _project(root: Path) -> Path:
    """A copy of the project's config, with folders named like its keys and groups."""
    root.mkdir()
    shutil.copytree(ROOT / "conf", root / "conf")
    for name in ("params.yaml", "dvc.yaml"):
        shutil.copy2(ROOT / name, root / name)
    for name in GROUP_FOLDERS:
        (root / name).mkdir(exist_ok=True)
        (root / name / "emblem.yaml").write_text("oops: 1\n")
    return root


def test_folders_at_the_project_root_are_not_config_groups(tmp_path: Path) -> None:
    root = _project(tmp_path / "project")
    cfg = load_params(["backend=mujoco", "art=emblem", "artwork.name=emblem",
                       "window=[0,12]"], root=root)
    assert (cfg.art, cfg.backend.name, list(cfg.window)) == ("emblem", "mujoco", [0, 12])
    assert cfg.robot.name == compose_settings().robot.name  # params.yaml's, not the folder's


def test_a_dvc_stage_runs_beside_a_folder_named_art(tmp_path: Path) -> None:
    """``simulate@*`` passes ``art=<name>``; the robot stage takes the same override and
    is quick: under DVC (params.yaml) and by hand (conf/), in a project with ``art/``."""
    root = _project(tmp_path / "project")
    (root / "stages").mkdir()
    shutil.copy2(ROOT / "stages" / "robot.py", root / "stages" / "robot.py")
    env = {**stage_env(), "DVC_STAGE": "robot", "PYTHONPATH": str(ROOT)}
    r = _stage("stages/robot.py", "art=emblem", env=env, cwd=root)
    assert r.returncode == 0, r.stderr
    assert (root / "data" / "robot" / "tattotronix.urdf").is_file()
    by_hand = _stage("stages/robot.py", "art=emblem", f"paths.out={root / 'mine'}",
                     env={**stage_env(), "PYTHONPATH": str(ROOT)}, cwd=root)
    assert by_hand.returncode == 0, by_hand.stderr


# ------------------------------------------------------------------ sweeps


def test_each_job_of_a_sweep_writes_its_own_folder(tmp_path: Path) -> None:
    jobs = [Outputs(tmp_path, [f"toolpath.pitch_mm={p}", f"paths.data={tmp_path}"],
                    root=tmp_path) for p in (1.0, 1.5)]
    assert [o.path("toolpath", "t.npz") for o in jobs] == [
        tmp_path / SWEEP_JOBS / f"toolpath.pitch_mm={p}" / "toolpath" / "t.npz"
        for p in (1.0, 1.5)]
    single = Outputs(tmp_path, None, root=tmp_path)
    assert single.path("toolpath", "t.npz") == tmp_path / "toolpath" / "t.npz"
    # a stage that names its jobs' files itself (draw.py, a study's case) writes beside
    named = Outputs(tmp_path, ["controller.wn=40", "plant.damping=0.01"], root=tmp_path)
    assert named.sweep_suffix(("controller.wn",)) == "@plant.damping=0.01"
    assert named.root == tmp_path
    long = Outputs(tmp_path, [f"k{i}.value_with_a_long_name={i}" for i in range(20)],
                   root=tmp_path)
    assert len(long.root.name) <= 120 and long.root.parent == tmp_path / SWEEP_JOBS


def test_a_toolpath_sweep_keeps_both_jobs(draw_data: Path) -> None:
    from tattotronix.app.pipeline import mask_of

    mask = mask_of(compose_settings(SMALL), draw_data.parent / "small.png", "small")
    (draw_data / "mask").mkdir()
    mask.save(draw_data / "mask" / "small.npz")
    r = _stage("stages/toolpath.py", "-m", f"paths.data={draw_data}", "artwork.name=small",
               "toolpath.pitch_mm=1.0,1.5")
    assert r.returncode == 0, r.stderr
    # each job's folder is named by its overrides (those of the command line included)
    jobs = {p: draw_data / SWEEP_JOBS / f"artwork.name=small,toolpath.pitch_mm={p}"
            for p in ("1.0", "1.5")}
    files = {p: job / "toolpath" / "small.npz" for p, job in jobs.items()}
    assert all(f.is_file() for f in files.values()), sorted(_files(draw_data))
    strokes = {p: int(np.load(f)["stroke"].max()) for p, f in files.items()}
    assert strokes["1.0"] > strokes["1.5"]  # each job its own plan
    assert not (draw_data / "toolpath").exists()
    metrics = [job / "metrics" / "toolpath" / "small.json" for job in jobs.values()]
    assert json.loads(metrics[0].read_text()) != json.loads(metrics[1].read_text())


# ------------------------------------------------------------------ signals


SIGNAL_STAGE = '''
import os, signal, time
from tattotronix.stage import run_stage

def main(cfg, out):
    out.write_text(out.path("made", "looks_finished.txt"), "no")
    out.write_bytes(out.path("emblem.npz"), b"half")  # .emblem.tmp<pid>.npz until the end
    os.kill(os.getpid(), getattr(signal, os.environ["STOP_WITH"]))
    time.sleep(60)

if __name__ == "__main__":
    run_stage("signalled", main)
'''


@pytest.mark.parametrize(("sig", "code", "said"), [
    ("SIGINT", 130, "Ctrl-C"), ("SIGTERM", 143, "SIGTERM"), ("SIGHUP", 129, "SIGHUP")])
def test_a_stop_signal_removes_the_temporaries(tmp_path: Path, sig: str, code: int,
                                               said: str) -> None:
    script = tmp_path / "stages" / "signalled.py"
    script.parent.mkdir()
    script.write_text(SIGNAL_STAGE)
    data = tmp_path / "data"
    data.mkdir()
    r = _stage(str(script), f"paths.data={data}", env={**stage_env(), "STOP_WITH": sig})
    assert r.returncode == code, r.stderr
    assert _one_line(r, "signalled: ") == (
        f"signalled: interrupted ({said}): stopped, nothing written")
    assert _files(data) == {}  # no .emblem.tmp<pid>.npz, no folder made for it
    assert not list(data.iterdir())


IMPORTING_STAGE = '''
import tattotronix  # noqa: F401
import os, signal, time
os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C while the heavy libraries import
time.sleep(60)
from tattotronix.stage import run_stage  # noqa: E402
'''


@pytest.mark.parametrize("under_dvc", [True, False])
def test_ctrl_c_while_a_stage_imports_ends_in_one_line(tmp_path: Path, under_dvc: bool
                                                       ) -> None:
    script = tmp_path / "stages" / "importing.py"
    script.parent.mkdir()
    script.write_text(IMPORTING_STAGE)
    env = {**stage_env(), **({"DVC_STAGE": "importing"} if under_dvc else {})}
    r = _stage(str(script), env=env)
    assert r.returncode == 130, r.stderr
    assert _one_line(r, "importing: ") == (
        "importing: interrupted (Ctrl-C): stopped, nothing written")


def test_only_a_stage_script_gets_the_import_guard() -> None:
    code = ("import signal, tattotronix; "
            "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)")
    r = subprocess.run([PYTHON, "-c", code], capture_output=True, text=True, timeout=120,
                       preexec_fn=default_signals)
    assert r.stdout.strip() == "True", r.stderr


def test_every_stage_script_imports_tattotronix_before_any_library() -> None:
    """So the guard is in place while the libraries import (tattotronix/__init__.py)."""
    stdlib = set(sys.stdlib_module_names)
    late = []
    for script in sorted((ROOT / "stages").glob("*.py")):
        for node in ast.parse(script.read_text()).body:
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                         else [node.module or ""])
                top = names[0].split(".")[0]
                if top == "tattotronix":
                    break
                if top not in stdlib and top != "__future__":
                    late.append(f"{script.name}: {names[0]}")
                    break
    assert not late, late


# ------------------------------------------------------------------ the needle


def _emblem_mask(data: Path) -> None:
    from tattotronix.art.artwork import load_artwork
    from tattotronix.art.mask import make_mask

    art = load_artwork(None, 150.0, 0.25, 40_000_000)
    (data / "mask").mkdir(parents=True)
    make_mask(art.grey, 0.25)[0].save(data / "mask" / "t.npz")


def test_a_needle_wider_than_the_artwork_is_refused(tmp_path: Path) -> None:
    """The built-in emblem at toolpath.needle_width_mm=8: about 73 % of the ink outside
    it (72.7 % since line art runs on through its corners)."""
    data = tmp_path / "data"
    _emblem_mask(data)
    before = _files(data)
    r = _stage("stages/toolpath.py", f"paths.data={data}", "artwork.name=t",
               "toolpath.needle_width_mm=8")
    assert r.returncode == 2, r.stderr
    line = _one_line(r, "toolpath: error: toolpath.needle_width_mm=8 cannot draw this "
                        "artwork: ")
    assert "% of the ink it would lay down falls outside the artwork" in line
    share = float(line.split("cannot draw this artwork: ", 1)[1].split(" %", 1)[0])
    assert 70.0 < share < 76.0, line
    assert _files(data) == before


def test_the_check_refuses_only_most_of_the_ink_outside() -> None:
    """A bar 5 mm tall, hatched as the original does (no compensation): a needle of 4 mm
    puts 47 % of its ink outside, one of 6 mm, 58 %."""
    from tattotronix.art.grid import InkMask
    from tattotronix.path.params import ToolpathParams
    from tattotronix.path.plan import MAX_BLEED_SHARE, check_needle, plan_toolpath

    ink = np.zeros((80, 200), bool)
    ink[30:50, 10:190] = True  # 45 x 5 mm at 0.25 mm
    mask = InkMask.centred(ink, 0.25)
    cfg = compose_settings()
    for needle, refused in ((0.3, False), (4.0, False), (6.0, True), (9.0, True)):
        params = dataclasses.replace(
            ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel),
            needle_width_mm=needle, compensate=False)
        tp = plan_toolpath(mask, params)
        bleed = tp.ink(mask, needle, 0.025).fidelity.bleed_share
        assert (bleed > MAX_BLEED_SHARE) == refused, (needle, bleed)
        if refused:
            with pytest.raises(TattotronixError, match=rf"toolpath.needle_width_mm={needle:g} "):
                check_needle(tp, mask, needle, 0.025)
        else:
            check_needle(tp, mask, needle, 0.025)


def test_a_needle_that_leaves_nothing_to_draw_is_named() -> None:
    """With compensation, a needle that leaves no part of the artwork to draw says so,
    naming it (not "no ink region of at least ... mm^2 (mask.min_region_mm2)"). As the
    compensation stands, a needle at least toolpath.line_max_mm wide leaves a thick part
    no inset (tattotronix/path/inset.py), so a 5 mm bar and a 2 mm needle get here."""
    from tattotronix.art.grid import InkMask
    from tattotronix.path.params import ToolpathParams
    from tattotronix.path.plan import plan_toolpath

    ink = np.zeros((80, 200), bool)
    ink[30:50, 10:190] = True
    cfg = compose_settings()
    params = dataclasses.replace(
        ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel),
        needle_width_mm=2.0, compensate=True)
    with pytest.raises(TattotronixError, match=r"^toolpath.needle_width_mm=2 leaves nothing "
                                               r"to draw: no part of the artwork's 1 ink"):
        plan_toolpath(InkMask.centred(ink, 0.25), params)


def test_an_in_memory_plan_refuses_the_needle_too(draw_data: Path) -> None:
    """draw.py plans a new artwork in memory (the arm's preview here): the same check."""
    r = _stage("stages/draw.py", f"paths.data={draw_data}", "backend=arm", "preview=true",
               f"artwork.source={draw_data.parent / 'small.png'}", *SMALL,
               "toolpath.needle_width_mm=8")
    assert r.returncode == 2, r.stderr
    _one_line(r, "draw: error: toolpath.needle_width_mm=8 cannot draw this artwork: ")
    assert not (draw_data / "runs").exists()
