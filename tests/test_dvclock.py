"""A dvc.lock cut short by an interrupt is refused with its fix, never built on."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from tattotronix.config.dvclock import BACKUP, DamagedLockError, guard, restore
from tattotronix.config.tracked import stage_names

from .conftest import ROOT, default_signals, small_pipeline

PYTHON = sys.executable
#: Ctrl-C's landed in the lock's rewrite: on a busy machine most are refused, and each
#: refusal costs two more repros (the refused one, and the one that mends)
TRIES = 12

LOCK = """schema: '2.0'
stages:
  a:
    cmd: python stages/a.py
    outs:
    - path: data/a.txt
      hash: md5
      md5: 0cc175b9c0f1b6a831c399e269772661
      size: 1
  b:
    cmd: python stages/b.py
    deps:
    - path: data/a.txt
      hash: md5
      md5: 0cc175b9c0f1b6a831c399e269772661
      size: 1
"""


def test_a_whole_lock_passes_and_is_kept_to_restore(tmp_path: Path) -> None:
    (tmp_path / "dvc.lock").write_text(LOCK)
    guard(tmp_path, ["a", "b"])
    assert (tmp_path / BACKUP).read_text() == LOCK
    (tmp_path / "dvc.lock").write_text("")
    assert "restored" in restore(tmp_path)
    assert (tmp_path / "dvc.lock").read_text() == LOCK


@pytest.mark.parametrize("cut", [0, 20, len(LOCK) - 30])
def test_a_lock_cut_short_is_refused_naming_the_fix(tmp_path: Path, cut: int) -> None:
    (tmp_path / "dvc.lock").write_text(LOCK)
    guard(tmp_path, ["a", "b"])  # the last whole one
    (tmp_path / "dvc.lock").write_text(LOCK[:cut])
    with pytest.raises(DamagedLockError, match="--restore") as err:
        guard(tmp_path, ["a", "b"])
    assert "\n" not in str(err.value)
    assert (tmp_path / BACKUP).read_text() == LOCK  # the damaged one never replaces it


def test_a_lock_that_lost_a_stage_is_refused_unless_the_stage_is_gone(tmp_path: Path) -> None:
    (tmp_path / "dvc.lock").write_text(LOCK)
    guard(tmp_path, ["a", "b"])
    (tmp_path / "dvc.lock").write_text(LOCK.split("  b:")[0])  # cut between two stages
    with pytest.raises(DamagedLockError, match=r"lost the records of 1 stage\(s\).*\(b\)"):
        guard(tmp_path, ["a", "b"])
    guard(tmp_path, ["a"])  # b is no longer in dvc.yaml: nothing is lost


def test_no_lock_is_a_fresh_start(tmp_path: Path) -> None:
    (tmp_path / "dvc.lock").write_text(LOCK)
    guard(tmp_path, ["a", "b"])
    (tmp_path / "dvc.lock").unlink()  # removed on purpose: everything reruns
    guard(tmp_path, ["a", "b"])
    assert not (tmp_path / BACKUP).exists()
    with pytest.raises(DamagedLockError, match="git checkout dvc.lock"):
        restore(tmp_path)


def test_stage_names_are_dvcs() -> None:
    names = stage_names(ROOT)
    assert {"code", "config", "robot", "simulate@emblem", "simulate@lineart-vector"} <= set(
        names)


# --- Ctrl-C while DVC writes the lock ----------------------------------------------------

def _env(clone: Path) -> dict[str, str]:
    env = {**os.environ, "DVC_NO_ANALYTICS": "1", "PYTHONPATH": str(clone)}
    env.pop("DVC_STAGE", None)
    return env


def _interrupt_while_locking(clone: Path, out: Path) -> bool:
    """``dvc repro -f -s mass``, with SIGINT sent to its process group (as a terminal's
    Ctrl-C is) the moment DVC starts rewriting dvc.lock after the stage; whether the
    signal was sent while DVC ran. DVC's output goes to ``out``, with its exit code."""
    lock = clone / "dvc.lock"
    before = lock.stat()
    with out.open("w") as log:
        proc = subprocess.Popen([PYTHON, "-m", "dvc", "repro", "-f", "-s", "mass"],
                                cwd=clone, env=_env(clone), stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True,
                                preexec_fn=default_signals)
    sent = False
    deadline = time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline:
        now = lock.stat()
        if (now.st_size, now.st_mtime_ns) != (before.st_size, before.st_mtime_ns):
            os.killpg(proc.pid, signal.SIGINT)  # DVC has opened it to rewrite it
            sent = True
            break
    code = proc.wait(timeout=120)
    with out.open("a") as log:
        log.write(f"\n[exit code {code}; lock {before.st_size} -> {lock.stat().st_size} "
                  "bytes]\n")
    return sent


def _dvc(clone: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PYTHON, "-m", "dvc", *argv], cwd=clone, env=_env(clone),
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_ctrl_c_while_dvc_writes_the_lock_leaves_it_whole_or_refused(tmp_path: Path) -> None:
    """12 tries: Ctrl-C lands while DVC rewrites dvc.lock after a stage. Each time the
    lock is either whole, or refused (by DVC, or by the next stage of the project) and
    `python -m tattotronix.config.dvclock --check` names the fix, which mends it (the
    restore, then the repro it asks for)."""
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    small_pipeline(clone, ("code", "config", "robot", "mass"), _env(clone))
    first = _dvc(clone, "repro")
    assert first.returncode == 0, first.stdout[-2000:] + first.stderr[-2000:]
    stages = set(yaml.safe_load((clone / "dvc.lock").read_text())["stages"])
    assert stages == {"code", "config", "robot", "mass"}
    outcomes = {"whole": 0, "refused": 0}
    for _ in range(TRIES):
        # on a busy machine DVC may rewrite the lock and exit between two looks: that
        # run ended whole and is tried again (at most 5 times) to land the signal
        out = tmp_path / "dvc.out"
        assert any(_interrupt_while_locking(clone, out) for _ in range(5)), (
            "DVC never rewrote dvc.lock while it was watched; the last try's output:\n"
            + out.read_text()[-3000:])
        check = subprocess.run([PYTHON, "-m", "tattotronix.config.dvclock", "--check"],
                               cwd=clone, env=_env(clone), capture_output=True, text=True)
        if check.returncode == 0:
            lock = yaml.safe_load((clone / "dvc.lock").read_text())
            assert set(lock["stages"]) == stages  # nothing lost
            outcomes["whole"] += 1
            continue
        # refused: one line, exit 2, naming the fix; DVC or the project refuses to go on
        assert check.returncode == 2, check.stderr
        assert check.stderr.count("\n") == 1 and "--restore" in check.stderr, check.stderr
        again = _dvc(clone, "repro")  # the first stage it runs (a lost one) refuses
        assert again.returncode != 0, again.stdout[-2000:]
        fixed = subprocess.run([PYTHON, "-m", "tattotronix.config.dvclock", "--restore"],
                               cwd=clone, env=_env(clone), capture_output=True, text=True)
        assert fixed.returncode == 0, fixed.stderr
        assert set(yaml.safe_load((clone / "dvc.lock").read_text())["stages"]) == stages
        # DVC removed the outputs of the stage it refused to run (config's stamps, not
        # cached): the next repro, as the restore says, remakes them
        assert "dvc repro" in fixed.stdout, fixed.stdout
        mended = _dvc(clone, "repro")
        assert mended.returncode == 0, mended.stdout[-2000:] + mended.stderr[-2000:]
        outcomes["refused"] += 1
    assert sum(outcomes.values()) == TRIES, outcomes
    # mended every time: the pipeline is whole and DVC reads it
    assert _dvc(clone, "status").returncode == 0
    print(outcomes)
