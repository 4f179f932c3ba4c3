"""The artifacts module: every npz round-trips with its provenance, and a reader refuses a
file with a missing key, a truncated file or a file that is not an npz, naming the stage
that writes it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tattotronix.errors import StageInputMissing, TattotronixError
from tattotronix.io import artifacts as A
from tattotronix.io.provenance import config_sha256, file_sha256, plain_config

N, J = 7, 5
RNG = np.random.default_rng(3)
JOINTS = ("base_yaw", "shoulder_pitch", "elbow_pitch", "wrist_pitch", "wrist_roll")


def _f(*shape: int) -> np.ndarray:
    return RNG.normal(size=shape)


def _records() -> dict[str, Any]:
    kind = np.array([0, 2, 1, 1, 1, 0, 0], np.int8)
    return {
        "toolpath": A.ToolpathRecord(
            uvz_mm=_f(N, 3), kind=kind, xyz_m=_f(N, 3), stroke=np.zeros(N, np.int32),
            t_s=np.linspace(0, 1, N), stroke_kind=np.array([1], np.int8),
            stroke_region=np.array([0], np.int32), stroke_width_mm=np.array([0.3])),
        "ik": A.IkRecord(joints=JOINTS, q=_f(N, J), tcp=_f(N, 3), residual=_f(N),
                         uvz_mm=_f(N, 3), xyz_m=_f(N, 3), kind=kind,
                         stroke=np.zeros(N, np.int32)),
        "trajectory": A.TrajectoryRecord(
            joints=JOINTS, t=np.linspace(0, 1, N), q=_f(N, J), qd=_f(N, J), qdd=_f(N, J),
            kind=kind, marked=kind == 1, tcp=_f(N, 3)),
        "run_log": A.RunLogRecord(
            joints=JOINTS, t=np.linspace(0, 1, N), q=_f(N, J), qd=_f(N, J), tau=_f(N, J),
            q_ref=_f(N, J), qd_ref=_f(N, J), tip=_f(N, 3), tip_ref=_f(N, 3),
            error_m=np.abs(_f(N)), down=kind == 1, settled=kind == 1),
        "servo_program": A.ServoProgramRecord(
            t=np.linspace(0, 1, N), q=_f(N, J), counts=RNG.integers(200, 500, (N, J)),
            channels=(0, 1, 2, 3, 4), frame_hz=50.0, count_us=4.8828125),
    }


RECORDS = _records()
#: the stage that writes each, and the relative path of the artwork "emblem"
WHERE: dict[str, tuple[str, str, dict[str, str]]] = {
    "toolpath": ("toolpath", "toolpath/emblem.npz", {"name": "emblem"}),
    "ik": ("ik", "ik/emblem.npz", {"name": "emblem"}),
    "trajectory": ("trajectory", "trajectories/emblem.npz", {"name": "emblem"}),
    "run_log": ("simulate", "runs/emblem-mujoco/log.npz",
                {"label": A.run_label("emblem", "mujoco")}),
    "servo_program": ("deploy", "deploy/emblem.npz", {"name": "emblem"}),
}


@pytest.fixture()
def prov(tmp_path: Path) -> str:
    src = tmp_path / "input.bin"
    src.write_bytes(b"an input")
    return A.make_provenance({"speed": 1.0, "robot": {"mass_model": "printed"}},
                             {"ik": src}, "abc123")


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray):
        return (isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape
                and np.array_equal(a, b))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("which", sorted(RECORDS))
def test_round_trip_keeps_arrays_dtypes_and_provenance(which: str, tmp_path: Path,
                                                       prov: str) -> None:
    rec = RECORDS[which]
    stage, rel, where = WHERE[which]
    file = type(rec).path(tmp_path, **where)
    assert file == tmp_path / rel and type(rec).SPEC.stage == stage
    file.parent.mkdir(parents=True)
    rec.save(file, prov)
    back = type(rec).load(file)
    for f in dataclasses.fields(rec):
        if f.name != "provenance":
            assert _same(getattr(rec, f.name), getattr(back, f.name)), f.name
    assert back.provenance["code_version"] == "abc123"
    assert back.provenance["config_sha256"] == config_sha256(back.provenance["config"])
    assert back.provenance["inputs"]["ik"]["sha256"] == file_sha256(tmp_path / "input.bin")
    with np.load(file, allow_pickle=False) as z:  # the stored layout: spec keys + provenance
        assert list(z.files) == [*type(rec).SPEC.keys, "provenance"]
        for key, dtype in type(rec).SPEC.dtypes.items():
            assert z[key].dtype.kind == "U" if dtype == "str" else z[key].dtype == dtype


def test_study_series_round_trip(tmp_path: Path, prov: str) -> None:
    series = {"whole_t": np.linspace(0, 1, 5), "whole_err_um": _f(5),
              "options": np.array(["a", "b"])}
    file = A.StudySeriesRecord.path(tmp_path, "control", "emblem", "pid_g-wn80")
    assert file == tmp_path / "studies" / "control" / "emblem" / "pid_g-wn80.npz"
    assert A.StudySeriesRecord.path(tmp_path, "actuator", "emblem") == \
        tmp_path / "studies" / "actuator" / "emblem.npz"
    file.parent.mkdir(parents=True)
    A.StudySeriesRecord(series).save(file, prov)
    back = A.StudySeriesRecord.load(file, "control", keys=("whole_t",))
    assert set(back.series) == set(series)
    assert all(_same(series[k], back.series[k]) for k in series)
    assert back.provenance["code_version"] == "abc123"
    with pytest.raises(TattotronixError, match=r"missing key 'x'.*'control' stage"):
        A.StudySeriesRecord.load(file, "control", keys=("x",))
    with pytest.raises(TattotronixError, match="reserved"):
        A.StudySeriesRecord({"provenance": np.zeros(1)}).save(tmp_path / "bad.npz", prov)


def test_writers_refuse_missing_keys_and_bare_provenance(tmp_path: Path, prov: str) -> None:
    with pytest.raises(TattotronixError, match="missing"):
        A.TRAJECTORY.write(tmp_path / "t.npz", {"t": np.zeros(2)}, prov)
    with pytest.raises(TattotronixError, match="provenance lacks"):
        RECORDS["ik"].save(tmp_path / "i.npz", json.dumps({"test": True}))
    with pytest.raises(TattotronixError, match="not JSON"):
        RECORDS["ik"].save(tmp_path / "i.npz", "not json")
    assert not list(tmp_path.glob("*.npz"))


@pytest.mark.parametrize("which", sorted(RECORDS))
def test_missing_key_names_the_file_and_the_stage(which: str, tmp_path: Path,
                                                  prov: str) -> None:
    rec = RECORDS[which]
    stage = WHERE[which][0]
    arrays = {k: np.asarray(v) for k, v in rec.arrays().items()}
    dropped = type(rec).SPEC.keys[1]
    del arrays[dropped]
    file = tmp_path / "x.npz"
    np.savez_compressed(file, **arrays, provenance=np.array(prov))
    with pytest.raises(TattotronixError) as err:
        type(rec).load(file)
    msg = str(err.value)
    assert str(file) in msg and f"missing key '{dropped}'" in msg
    assert f"re-run the '{stage}' stage" in msg
    # no provenance: refused too
    full = {k: np.asarray(v) for k, v in rec.arrays().items()}
    np.savez_compressed(file, **full)
    with pytest.raises(TattotronixError, match=f"missing key 'provenance'.*'{stage}' stage"):
        type(rec).load(file)


@pytest.mark.parametrize("which", sorted(RECORDS))
def test_truncated_and_foreign_files_are_refused(which: str, tmp_path: Path,
                                                 prov: str) -> None:
    rec = RECORDS[which]
    stage = WHERE[which][0]
    good = tmp_path / "good.npz"
    rec.save(good, prov)
    data = good.read_bytes()
    cases = {
        "truncated.npz": data[: len(data) // 2],
        "empty.npz": b"",
        "text.npz": b"not an npz at all\n" * 20,
        "npy.npz": b"",
    }
    for fname, raw in cases.items():
        bad = tmp_path / fname
        if fname == "npy.npz":
            np.save(tmp_path / "plain.npy", np.zeros(3))
            raw = (tmp_path / "plain.npy").read_bytes()
        bad.write_bytes(raw)
        with pytest.raises(TattotronixError) as err:
            type(rec).load(bad)
        assert str(bad) in str(err.value) and f"'{stage}' stage" in str(err.value), fname
    with pytest.raises(TattotronixError, match=f"missing input .*absent.npz.*'{stage}' stage"):
        type(rec).load(tmp_path / "absent.npz")


def test_wrong_dtype_and_bad_provenance_are_refused(tmp_path: Path, prov: str) -> None:
    arrays = {k: np.asarray(v) for k, v in RECORDS["trajectory"].arrays().items()}
    file = tmp_path / "t.npz"
    np.savez(file, **{**arrays, "joints": np.arange(5)}, provenance=np.array(prov))
    with pytest.raises(TattotronixError, match="'joints' holds int64, not names"):
        A.TrajectoryRecord.load(file)
    np.savez(file, **{**arrays, "q": np.array(["a"])}, provenance=np.array(prov))
    with pytest.raises(TattotronixError, match="'q' holds"):
        A.TrajectoryRecord.load(file)
    np.savez(file, **arrays, provenance=np.array("[1, 2]"))
    with pytest.raises(TattotronixError, match="provenance is not a JSON object"):
        A.TrajectoryRecord.load(file)


def test_require_names_the_stage(tmp_path: Path) -> None:
    with pytest.raises(StageInputMissing, match="'ik' stage"):
        A.IkRecord.require(tmp_path, name="emblem")
    with pytest.raises(TattotronixError,
                       match=r"'simulate' stage \(python stages/draw.py art=emblem "
                             r"backend=mujoco window=null\)"):
        A.RunLogRecord.load_run(tmp_path, "emblem", "mujoco")
    with pytest.raises(StageInputMissing, match="'control' stage"):
        A.STUDY_SERIES.require(tmp_path, study="control", name="emblem", case="c")


def test_config_hash_is_the_same_for_a_dictconfig_and_its_dataclass() -> None:
    from omegaconf import OmegaConf

    from tattotronix.config.params import compose
    from tattotronix.config.schema import Config

    cfg = compose()
    plain = plain_config(cfg)
    assert config_sha256(plain) == config_sha256(json.loads(json.dumps(plain)))
    typed = OmegaConf.to_object(cfg)
    assert isinstance(typed, Config)
    assert plain_config(typed) == plain
    assert config_sha256(plain_config(typed)) == config_sha256(plain)


def test_npz_bytes_depend_only_on_the_arrays(tmp_path: Path) -> None:
    """The same arrays written twice give the same file (no member timestamps): DVC sees
    an unchanged output, and a metric that records an input's hash stays put."""
    import hashlib
    import os
    import time

    from tattotronix.io.npz import save_npz

    arrays = {"q": np.linspace(0.0, 1.0, 50).reshape(10, 5), "name": np.array("emblem"),
              "marked": np.array([True, False])}
    save_npz(tmp_path / "a.npz", arrays)
    os.utime(tmp_path / "a.npz", (0, 0))
    time.sleep(2.1)  # zip member times have a 2 s resolution
    save_npz(tmp_path / "b.npz", arrays)
    digest = [hashlib.sha256((tmp_path / f).read_bytes()).hexdigest()
              for f in ("a.npz", "b.npz")]
    assert digest[0] == digest[1]
    with np.load(tmp_path / "b.npz", allow_pickle=False) as z:
        assert z.files == ["q", "name", "marked"]
        assert np.array_equal(z["q"], arrays["q"]) and str(z["name"]) == "emblem"


def test_code_version_is_the_imported_code_not_the_checkout(tmp_path: Path) -> None:
    """A process with no project entry point (a notebook, the tests): two copies of the
    code anywhere on disk give one version; editing a module the process imported moves
    it, editing one it did not import (or a document) does not."""
    from tattotronix.io.provenance import code_version

    def copy(where: str, used: str = "X = 1\n", unused: str = "Y = 1\n",
             docs: str = "docs\n") -> Path:
        root = tmp_path / where
        (root / "tattotronix").mkdir(parents=True)
        (root / "tattotronix" / "__init__.py").write_text("")
        (root / "tattotronix" / "used.py").write_text(used)
        (root / "tattotronix" / "unused.py").write_text(unused)
        (root / "README.md").write_text(docs)
        return root

    import sys
    import types

    def load(root: Path) -> str:
        mod = types.ModuleType("tattotronix.used")
        mod.__file__ = str(root / "tattotronix" / "used.py")
        sys.modules["tattotronix.used"] = mod
        try:
            return code_version(root)
        finally:
            del sys.modules["tattotronix.used"]

    a = load(copy("a"))
    assert a.startswith("sha256:")
    assert load(copy("b/deeper")) == a
    assert load(copy("c", unused="Y = 2\n", docs="other docs\n")) == a
    assert load(copy("d", used="X = 2\n")) != a


def test_npz_bytes_do_not_depend_on_the_python_patch_release(tmp_path: Path) -> None:
    """A newcomer on Debian's Python 3.11.2 got other npz bytes than 3.11.7 (git status
    dirty after the README's first command): a member streamed with force_zip64 gets a
    local header CPython changed in 3.11.4. Members are written with their sizes known,
    no ZIP64 record: version 2.0 to extract, the sizes in the local header. The bytes of
    this file are pinned (both interpreters wrote them)."""
    import hashlib
    import struct

    from tattotronix.io.npz import save_npz

    path = tmp_path / "x.npz"
    save_npz(path, {"a": np.arange(1000.0), "b": np.array("x" * 300),
                    "c": np.zeros((50, 5), np.int8)})
    raw = path.read_bytes()
    assert hashlib.sha256(raw).hexdigest() == (
        "b359e3dc0bb6a0717a34b344d84cfb12684a325a3580d0dc454fc6c469b6ca8c")
    at = 0
    while raw[at:at + 4] == b"PK\x03\x04":
        version, _, _, _, _, _, packed, size, name_len, extra_len = struct.unpack(
            "<HHHHHIIIHH", raw[at + 4:at + 30])
        assert version == 20 and extra_len == 0 and 0 < packed < 0xFFFFFFFF
        at += 30 + name_len + extra_len + packed
    assert at > 0
