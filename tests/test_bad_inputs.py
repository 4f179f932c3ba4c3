"""Every bad input gets one clear line, never a traceback (README, "Configuration").

* The schema sweep: every numeric key of the schema (walked from the dataclasses, so a new
  key cannot be forgotten) with 0, a negative, nan, inf and an absurd value is either
  inside the range its field declares and accepted, or refused by ``to_settings`` naming
  the full key; in-process, one composition for all.
* Budgets, corrupt inputs, bad solver settings, the mask's inversion: in-process.
* Real stages (run side by side): a bad override, an out-of-range value, a corrupt input
  of each kind, a setting over a work budget, Ctrl-C: exit code 2 (130 for Ctrl-C), one
  line naming the key or the file, no traceback, nothing written.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import signal
import subprocess
import time
import types
import typing
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Union, get_args, get_origin

import numpy as np
import pytest
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from tattotronix.art.grid import InkMask
from tattotronix.config import schema
from tattotronix.config.params import compose, compose_settings, main, one_line, to_settings
from tattotronix.config.schema import Config, Range, range_of
from tattotronix.errors import ConfigError, StageInputMissing, TattotronixError
from tattotronix.io.outputs import Outputs

from .conftest import PYTHON, ROOT, default_signals, stage_env

# ------------------------------------------------------------------ the schema and its keys


def _numeric(tp: object) -> tuple[str, bool] | None:
    """("int" | "float", is_list) for a numeric annotation (Optional allowed), else None."""
    if get_origin(tp) in (Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        if len(args) != 1:
            return None
        tp = args[0]
    if tp is int or tp is float:
        return tp.__name__, False
    if get_origin(tp) is list and get_args(tp) and get_args(tp)[0] in (int, float):
        return get_args(tp)[0].__name__, True
    return None


def _hints(cls: type) -> dict[str, object]:
    return typing.get_type_hints(cls, vars(schema))


def _schema_classes(root: type = Config) -> list[type]:
    """Every settings class reachable from ``root`` through its fields' types."""
    seen: list[type] = []
    todo = [root]
    while todo:
        cls = todo.pop()
        if cls in seen:
            continue
        seen.append(cls)
        for tp in _hints(cls).values():
            for t in (tp, *get_args(tp), *(a for g in get_args(tp) for a in get_args(g))):
                if isinstance(t, type) and dataclasses.is_dataclass(t):
                    todo.append(t)
    return seen


def test_every_numeric_key_of_the_schema_declares_a_range() -> None:
    classes = _schema_classes()
    assert schema.JointConfig in classes and schema.ControlCase in classes
    missing = [f"{cls.__name__}.{f.name}" for cls in classes
               for f in dataclasses.fields(cls)
               if _numeric(_hints(cls)[f.name]) and range_of(f) is None]
    assert not missing, f"numeric keys without a range (declare one with bounded()): {missing}"


@dataclasses.dataclass(frozen=True)
class Key:
    """A numeric key of the composed config."""

    name: str  # as messages name it: robot.joints[0].effort, trajectory.lifts_mm[0]
    path: str  # as OmegaConf updates it: robot.joints.0.effort, trajectory.lifts_mm.0
    kind: str  # "int" or "float"
    rng: Range
    value: object  # the composed value at ``path`` (None for an unset optional)
    one_item_list: bool = False  # an unset optional list: the sweep sets [value]


def _keys(obj: object, name: str = "", path: str = "") -> Iterator[Key]:
    hints = _hints(type(obj))
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        n, p = f"{name}{f.name}", f"{path}{f.name}"
        value = getattr(obj, f.name)
        num, rng = _numeric(hints[f.name]), range_of(f)
        if num and rng:
            kind, is_list = num
            if is_list and value:  # the sweep changes the first item
                yield Key(f"{n}[0]", f"{p}.0", kind, rng, value[0])
            elif is_list:
                yield Key(f"{n}[0]", p, kind, rng, value, one_item_list=True)
            else:
                yield Key(n, p, kind, rng, value)
        elif dataclasses.is_dataclass(value):
            yield from _keys(value, f"{n}.", f"{p}.")
        elif isinstance(value, list):
            for i, v in enumerate(value):
                if dataclasses.is_dataclass(v):
                    yield from _keys(v, f"{n}[{i}].", f"{p}.{i}.")
        elif isinstance(value, dict):
            for k, v in value.items():
                if dataclasses.is_dataclass(v):
                    yield from _keys(v, f"{n}.{k}.", f"{p}.{k}.")


SWEEP_FLOAT = (0.0, -1.0, math.nan, math.inf, 1e300)
SWEEP_INT = (0, -1, 10**30)


@pytest.fixture(scope="module")
def composed() -> DictConfig:
    return compose()


def test_the_sweep_reaches_every_section(composed: DictConfig) -> None:
    names = [k.name for k in _keys(to_settings(composed))]
    for want in ("robot.joints[4].velocity", "robot.printed.base_link.mass",
                 "robot.servos.SG90.deadband_us", "robot.pen.radius",
                 "study.control.cases.pid-wn20.wn", "study.approach_mm[0]",
                 "toolpath.pitch_mm", "controller.torque_limit_nm", "pose[0]", "speed"):
        assert want in names, want
    assert len(names) > 150


def test_every_numeric_key_is_checked_against_its_range(composed: DictConfig) -> None:
    """0, a negative, nan, inf and an absurd value for every numeric key: accepted when the
    declared range admits it, else refused naming the full key (``to_settings``); an int
    key refuses nan and inf by its type, naming the key."""
    cfg = composed
    before = to_settings(cfg)
    wrong: list[str] = []
    for key in _keys(before):
        values: tuple[object, ...] = SWEEP_INT + (math.nan, math.inf) if key.kind == "int" \
            else SWEEP_FLOAT
        for v in values:
            setting: object = [v] if key.one_item_list else v
            try:
                OmegaConf.update(cfg, key.path, setting, merge=False)
            except OmegaConfBaseException as exc:  # the type refuses it (Hydra: ConfigError)
                text = one_line(exc)
                if key.kind != "int" or isinstance(v, int) or key.path.split(".")[-1] \
                        not in text:
                    wrong.append(f"{key.name}={v}: refused by OmegaConf: {text}")
                continue
            try:
                to_settings(cfg)
                if not key.rng.admits(v):  # type: ignore[arg-type]
                    wrong.append(f"{key.name}={v}: accepted outside {key.rng.describe()}")
            except ConfigError as exc:
                if key.rng.admits(v):  # type: ignore[arg-type]
                    wrong.append(f"{key.name}={v}: refused inside its range: {exc}")
                elif f"{key.name} must be " not in str(exc) or "\n" in str(exc):
                    wrong.append(f"{key.name}={v}: the refusal does not name it: {exc}")
            finally:
                OmegaConf.update(cfg, key.path, key.value, merge=False)
    assert to_settings(cfg) == before  # every key restored
    assert not wrong, "\n".join(wrong[:40])


@pytest.mark.parametrize(("override", "words"), [
    ("toolpath.pitch_mm=inf", ["toolpath.pitch_mm must be >= 0.05 and <= 100 mm (got inf)"]),
    ("toolpath.pitch_mm=1e-6", ["toolpath.pitch_mm", "1e-06"]),
    ("mask.res_mm=0", ["mask.res_mm", "(got 0)"]),
    ("mask.min_region_mm2=-1", ["mask.min_region_mm2", "(got -1)"]),
    ("mask.edge_sigma_px=-3", ["mask.edge_sigma_px", "(got -3)"]),
    ("collision.margin_mm=-5", ["collision.margin_mm", "mm (got -5)"]),
    ("ik.max_iter=0", ["ik.max_iter must be an integer >= 1"]),
    ("ik.dls_lambda=-1", ["ik.dls_lambda", "(got -1)"]),
    ("robot.joints.0.effort=nan", ["robot.joints[0].effort", "(got nan)"]),
    ("trajectory.lifts_mm=[10,-1]", ["trajectory.lifts_mm[1]", "(got -1)"]),
    ("toolpath.min_loop_px=nan", ["toolpath.min_loop_px", "Integer"]),
])
def test_hydra_overrides_are_refused_naming_the_key(override: str, words: list[str]) -> None:
    with pytest.raises(ConfigError) as err:
        compose_settings([override])
    msg = str(err.value)
    assert "\n" not in msg and "$VALUE" not in msg
    assert all(w in msg for w in words), msg


def test_every_value_the_project_uses_is_inside_the_ranges() -> None:
    """conf/ (and so params.yaml), the study sweeps, and the overrides of the tests."""
    cfg = compose_settings()  # conf/ itself
    toolpath = {f.name: range_of(f) for f in dataclasses.fields(schema.ToolpathConfig)}
    controller = {f.name: range_of(f) for f in dataclasses.fields(schema.ControllerConfig)}
    plant_dt = range_of(next(f for f in dataclasses.fields(schema.PlantConfig)
                             if f.name == "dt_s"))
    sweeps = [(toolpath["approach_mm"], cfg.study.approach_mm),
              (toolpath["step_mm"], cfg.study.step_mm),
              (controller["rate_hz"], cfg.study.rate_hz),
              (controller["wn"], cfg.study.rate_wn),
              (controller["wn"], [c.wn for c in cfg.study.control.cases.values()]),
              (plant_dt, [cfg.study.rate_plant_dt_s])]
    for rng, values in sweeps:
        assert rng is not None and all(rng.admits(v) for v in values), (rng, values)
    used = ["speed=500", "speed=2", "mask.width_mm=24", "mask.width_mm=120",
            "mask.min_region_mm2=0.5", "controller.rate_hz=200", "controller.wn=10",
            "controller.wn=240", "plant.damping=0.01", "hardware.ramp_rad_s=0.3",
            "toolpath.pitch_mm=0.5", "toolpath.approach_mm=0.25", "toolpath.step_mm=0.6",
            "ik.dls_lambda=0.002", "collision.margin_mm=2.5", "artwork.max_pixels=1000",
            "hardware.fail_after_writes=4", "robot.joints.1.lower=1.6",
            "robot.joints.0.upper=-1.57", "trajectory.accel_rad_s2=7.5", "window=[200,12]"]
    compose_settings(used)


def test_params_check_says_a_bad_conf_in_one_line(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """``tattotronix-params --check``: no duplicated lines, no ``$VALUE`` template."""
    import shutil

    shutil.copytree(ROOT / "conf", tmp_path / "conf")
    shutil.copy(ROOT / "params.yaml", tmp_path / "params.yaml")
    toolpath = tmp_path / "conf" / "toolpath" / "default.yaml"
    text = toolpath.read_text()
    for bad, words in (("wide", ["toolpath.pitch_mm", "'wide'", "Float"]),
                       ("0", ["toolpath.pitch_mm must be >= 0.05", "(got 0)"])):
        toolpath.write_text(text + f"pitch_mm: {bad}\n")
        assert main(["--check", "--root", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "$VALUE" not in err, err
        assert all(w in err for w in words), err


# ------------------------------------------------------------------ the library, in-process


def _prov() -> str:
    from tattotronix.io.artifacts import make_provenance

    return make_provenance({"speed": 1.0}, {}, "test")


def _striped(h_mm: float, w_mm: float, res: float, stripe_px: int = 0) -> InkMask:
    h, w = round(h_mm / res), round(w_mm / res)
    ink = np.zeros((h, w), bool)
    ink[4:-4, 4:-4] = True
    if stripe_px:
        ink[:, ::stripe_px] = False  # vertical gaps: many runs per row
    return InkMask.centred(ink, res)


def _params(**change: float) -> object:
    from tattotronix.path.params import ToolpathParams

    cfg = compose_settings()
    return dataclasses.replace(
        ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel), **change)


@pytest.mark.parametrize(("mask", "change", "words"), [
    # a tiny pitch: refused on the scanline count alone, before the hatch allocates
    (lambda: _striped(100, 150, 0.25), {"pitch_mm": 1e-6},
     ["toolpath.pitch_mm=1e-06", "scanlines", "cells", "GiB", "budget of 2e+07"]),
    # many runs per row: refused on the strokes the hatch would make, before hatching
    (lambda: _striped(100, 150, 0.25, stripe_px=4), {"pitch_mm": 0.05},
     ["toolpath.pitch_mm=0.05", "strokes", "budget of 12000", "quadratic"]),
    # long strokes at a fine step: refused on the points, before resampling
    (lambda: _striped(130, 190, 0.25), {"step_mm": 0.005},
     ["toolpath.step_mm=0.005", "points", "budget of 1000000", "GiB"]),
])
def test_toolpath_work_over_budget_is_refused_with_the_estimate(
        mask: Callable[[], InkMask], change: dict[str, float], words: list[str]) -> None:
    from tattotronix.path.plan import plan_toolpath

    t0 = time.perf_counter()
    with pytest.raises(TattotronixError) as err:
        plan_toolpath(mask(), _params(**change))  # type: ignore[arg-type]
    assert all(w in str(err.value) for w in words), str(err.value)
    assert time.perf_counter() - t0 < 20  # refused before the work, not after


def test_a_simulated_run_over_the_tick_budget_is_refused() -> None:
    from tattotronix.control.drawing import MAX_TICKS, check_tick_budget

    check_tick_budget(600.0, 1000.0)  # the emblem at 1 kHz
    with pytest.raises(TattotronixError, match=r"controller.rate_hz=10000.*over the budget"):
        check_tick_budget(MAX_TICKS / 10_000 + 1, 10_000.0)


@pytest.mark.parametrize(("change", "key"), [
    ({"max_iter": 0}, "ik.max_iter"), ({"dls_lambda": -1.0}, "ik.dls_lambda"),
    ({"dls_lambda": 0.0}, "ik.dls_lambda"), ({"tol": math.nan}, "ik.tol"),
    ({"anchor_spacing_m": math.inf}, "ik.anchor_spacing_m"), ({"max_iter": 2.5}, "ik.max_iter"),
])
def test_ik_settings_are_validated_naming_the_key(change: dict[str, float], key: str) -> None:
    """Not "unreachable": the setting is named (no sqrt warning, no residual nan)."""
    from tattotronix.kinematics import Chain, solve_path
    from tattotronix.robot.description import build_description

    chain = Chain.from_description(build_description(compose_settings().robot))
    with pytest.raises(TattotronixError, match=rf"^{key} must be"):
        solve_path(chain, np.array([[0.21, 0.0, 0.0035]]), **change)  # type: ignore[arg-type]


def _variants(raw: bytes) -> Iterator[tuple[str, bytes]]:
    """Truncations, flipped bytes (in the deflate streams, the CRCs, the directory),
    zeroed blocks, garbage."""
    rng = np.random.default_rng(0)
    n = len(raw)
    for frac in (0.0, 0.01, 0.3, 0.5, 0.9, 0.99):
        yield f"truncated at {frac}", raw[:int(n * frac)]
    for i in rng.integers(0, n, 25):
        b = bytearray(raw)
        b[i] ^= 0xFF
        yield f"byte {i} flipped", bytes(b)
    for i in rng.integers(0, max(n - 64, 1), 6):
        b = bytearray(raw)
        b[i:i + 64] = bytes(64)
        yield f"64 bytes zeroed at {i}", bytes(b)
    yield "garbage", rng.integers(0, 256, 2000, dtype=np.uint8).tobytes()


def test_corrupt_artifacts_are_refused_naming_the_file_and_the_stage(tmp_path: Path) -> None:
    from tattotronix.io import artifacts as A
    from tattotronix.studies.base import StudyCase

    from .test_artifacts import RECORDS

    readers: dict[str, tuple[Callable[[Path], object], bytes, str]] = {}
    for kind, stage in (("toolpath", "toolpath"), ("ik", "ik"), ("trajectory", "trajectory")):
        f = tmp_path / f"{kind}.npz"
        RECORDS[kind].save(f, _prov())
        readers[kind] = (type(RECORDS[kind]).load, f.read_bytes(), stage)
    f = tmp_path / "mask.npz"
    InkMask.centred(np.eye(50, dtype=bool), 0.25).save(f)
    readers["mask"] = (InkMask.load, f.read_bytes(), "mask")
    readers["study case"] = (lambda p: StudyCase.load(p, "rate"), b'{"a": [1, 2, 3]}', "rate")
    assert A.TRAJECTORY.stage == "trajectory"
    bad = tmp_path / "bad.npz"
    for what, (read, raw, stage) in readers.items():
        for how, data in _variants(raw):
            bad.write_bytes(data)
            try:
                read(bad)
            except StageInputMissing:
                raise AssertionError(f"{what}, {how}: reported missing") from None
            except TattotronixError as exc:
                msg = str(exc)
                assert str(bad) in msg and f"'{stage}' stage" in msg and "\n" not in msg, \
                    (what, how, msg)
            except Exception as exc:  # noqa: BLE001 - the point of the test
                raise AssertionError(f"{what}, {how}: {type(exc).__name__}: {exc}") from None


def test_corrupt_model_files_are_refused_naming_the_file_and_the_stage(tmp_path: Path) -> None:
    from tattotronix.kinematics.ik import PinocchioTip
    from tattotronix.robot.description import build_description
    from tattotronix.robot.loaders import MujocoArm, PinocchioArm, load_pinocchio
    from tattotronix.robot.mjcf import to_mjcf
    from tattotronix.robot.urdf import to_urdf

    desc = build_description(compose_settings().robot)
    urdf, mjcf = to_urdf(desc), to_mjcf(desc)
    cases: list[tuple[str, str, Callable[[Path], object]]] = [
        ("robot.urdf", urdf[: len(urdf) // 2], lambda p: load_pinocchio(p, 9.81)),
        ("robot.urdf", "<robot name='x'><link name='a'/></robot>",
         lambda p: PinocchioTip.from_urdf(p, desc.tip_frame)),
        ("robot.urdf", "\udcff".encode("utf-8", "surrogateescape").decode("latin-1") * 3,
         lambda p: PinocchioArm(p, 9.81)),
        ("robot.xml", mjcf[: len(mjcf) // 2], MujocoArm),
    ]
    for name, text, read in cases:
        path = tmp_path / name
        path.write_bytes(text.encode("latin-1", "replace") if "\udcff" in text
                         else text.encode("utf-8"))
        with pytest.raises(TattotronixError) as err:
            read(path)
        assert str(path) in str(err.value) and "'robot' stage" in str(err.value), err.value
    with pytest.raises(StageInputMissing, match="'robot' stage"):
        load_pinocchio(tmp_path / "absent.urdf", 9.81)


def test_the_mask_says_when_it_inverts_and_a_setting_turns_it_off(
        caplog: pytest.LogCaptureFixture) -> None:
    from tattotronix.art.mask import make_mask

    grey = np.zeros((100, 120))  # a black field with a white square: the art is light
    grey[30:70, 40:80] = 255.0
    with caplog.at_level(logging.INFO, logger="tattotronix"):
        mask, stats = make_mask(grey, 0.25, min_region_mm2=0.0)
    said = [r.getMessage() for r in caplog.records if "inverted" in r.getMessage()]
    assert stats.inverted and mask.ink[50, 60] and not mask.ink[5, 5]
    assert len(said) == 1 and "mask.auto_invert=false" in said[0] and "86.7 %" in said[0]
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="tattotronix"):
        mask, stats = make_mask(grey, 0.25, min_region_mm2=0.0, auto_invert=False)
    assert not stats.inverted and mask.ink[5, 5] and not mask.ink[50, 60]
    assert not [r for r in caplog.records if "inverted" in r.getMessage()]


def test_an_aborted_transaction_leaves_no_file_and_no_folder_it_made(tmp_path: Path) -> None:
    (tmp_path / "data" / "kept").mkdir(parents=True)
    out = Outputs(tmp_path / "data")
    with pytest.raises(KeyboardInterrupt), out.transaction():
        out.write_text(out.path("kept", "a.txt"), "a")
        out.write_json(out.path("metrics", "deep", "b.json"), {})
        raise KeyboardInterrupt
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")) == [
        "data", "data/kept"]


# ------------------------------------------------------------------ real stages


def _files(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}


def _flip(path: Path, at: float = 0.5) -> None:
    raw = bytearray(path.read_bytes())
    i = int(len(raw) * at)
    raw[i:i + 16] = bytes(b ^ 0xFF for b in raw[i:i + 16])
    path.write_bytes(bytes(raw))


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _urdf(data: Path) -> Path:
    from tattotronix.robot.description import build_description
    from tattotronix.robot.urdf import to_urdf

    path = data / "robot" / "tattotronix.urdf"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(to_urdf(build_description(compose_settings().robot)))
    return path


def _toolpath(data: Path, n: int = 3) -> Path:
    """A tiny reachable toolpath (three points on the panel)."""
    from tattotronix.io.artifacts import ToolpathRecord, make_provenance

    uvz = np.array([[0.0, 0.0, -1.5], [10.0, 0.0, -1.5], [0.0, 5.0, -1.5]])[:n]
    path = ToolpathRecord.path(data, name="t")
    path.parent.mkdir(parents=True, exist_ok=True)
    ToolpathRecord(uvz_mm=uvz, kind=np.array([2, 1, 1], np.int8)[:n],
                   xyz_m=np.array([0.21, 0.0, 0.005]) + uvz / 1000.0,
                   stroke=np.zeros(n, np.int32), t_s=np.arange(n, dtype=float),
                   stroke_kind=np.ones(1, np.int8), stroke_region=np.zeros(1, np.int32),
                   stroke_width_mm=np.full(1, np.nan)
                   ).save(path, make_provenance({}, {}))
    return path


def _records(data: Path, kind: str) -> Path:
    from .test_artifacts import RECORDS

    rec = RECORDS[kind]
    path = type(rec).path(data, name="t")
    path.parent.mkdir(parents=True, exist_ok=True)
    rec.save(path, _prov())
    return path


def _mask(data: Path, mask: InkMask) -> Path:
    path = data / "mask" / "t.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    mask.save(path)
    return path


def _setup_corrupt_mask(data: Path) -> tuple[list[str], list[str]]:
    path = _mask(data, _striped(20, 30, 0.25))
    _flip(path)
    return [], [str(path), "re-run the 'mask' stage"]


def _setup_truncated_toolpath(data: Path) -> tuple[list[str], list[str]]:
    _urdf(data)
    path = _toolpath(data)
    _truncate(path)
    return [], [str(path), "re-run the 'toolpath' stage"]


def _setup_corrupt_ik(data: Path) -> tuple[list[str], list[str]]:
    _urdf(data)
    path = _records(data, "ik")
    _flip(path, 0.3)
    return [], [str(path), "re-run the 'ik' stage"]


def _setup_truncated_trajectory(data: Path) -> tuple[list[str], list[str]]:
    path = _records(data, "trajectory")
    _truncate(path)
    return [], [str(path), "re-run the 'trajectory' stage"]


def _setup_corrupt_urdf(data: Path) -> tuple[list[str], list[str]]:
    urdf = _urdf(data)
    _truncate(urdf)
    _toolpath(data)
    return [], [str(urdf), "re-run the 'robot' stage"]


def _setup_over_budget(data: Path) -> tuple[list[str], list[str]]:
    _mask(data, _striped(130, 190, 0.25))
    return ["toolpath.step_mm=0.005"], ["toolpath.step_mm=0.005", "points", "budget"]


def _setup_non_ascii(data: Path) -> tuple[list[str], list[str]]:
    from .conftest import small_art

    path = small_art(data.parent / "日本.png")
    return ([f"artwork.source={path}"],
            ["artwork.source", "quote a value with non-ASCII letters",
             f"\"artwork.source='{path}'\""])


def _config(*overrides: str, words: tuple[str, ...]) -> Callable[[Path], tuple[list[str],
                                                                                list[str]]]:
    return lambda data: (list(overrides), list(words))


#: id -> (stage, setup(data) -> (overrides, words the one line must hold))
STAGE_CASES: dict[str, tuple[str, Callable[[Path], tuple[list[str], list[str]]]]] = {
    "mask res_mm=0": ("mask", _config("mask.res_mm=0", words=("mask.res_mm", "(got 0)"))),
    "toolpath pitch_mm=1e-6": ("toolpath", _config(
        "toolpath.pitch_mm=1e-6", words=("toolpath.pitch_mm", "(got 1e-06)"))),
    "ik max_iter=0": ("ik", _config("ik.max_iter=0", words=("ik.max_iter",))),
    "ik dls_lambda=-1": ("ik", _config("ik.dls_lambda=-1", words=("ik.dls_lambda",))),
    "mask edge_sigma_px=-3": ("mask", _config(
        "mask.method=edges", "mask.edge_sigma_px=-3", words=("mask.edge_sigma_px",))),
    "collision margin_mm=-5": ("collision", _config(
        "collision.margin_mm=-5", words=("collision.margin_mm", "mm (got -5)"))),
    "unknown key": ("trajectory", _config("trajectory.max_stepmm=1", words=("max_stepmm",))),
    "non-ASCII path unquoted": ("artwork", _setup_non_ascii),
    "corrupt mask": ("toolpath", _setup_corrupt_mask),
    "truncated toolpath": ("ik", _setup_truncated_toolpath),
    "corrupt IK path": ("trajectory", _setup_corrupt_ik),
    "truncated trajectory": ("collision", _setup_truncated_trajectory),
    "corrupt URDF": ("ik", _setup_corrupt_urdf),
    "points over budget": ("toolpath", _setup_over_budget),
}


@pytest.fixture(scope="module")
def stage_runs(tmp_path_factory: pytest.TempPathFactory
               ) -> dict[str, tuple[subprocess.CompletedProcess[str], Path, set[str], list[str]]]:
    """Every case's stage, two at a time (each is a process of 2-3 s)."""
    prepared = {}
    for key, (stage, setup) in STAGE_CASES.items():
        data = tmp_path_factory.mktemp("bad") / "data"
        data.mkdir()
        overrides, words = setup(data)
        cmd = [PYTHON, f"stages/{stage}.py", f"paths.data={data}", "artwork.name=t",
               "draw.progress=false", *overrides]
        prepared[key] = (cmd, data, _files(data), words)
    results = {}
    running: list[tuple[str, subprocess.Popen[str]]] = []
    pending = list(prepared)
    while pending or running:
        while pending and len(running) < 2:
            key = pending.pop(0)
            running.append((key, subprocess.Popen(
                prepared[key][0], cwd=ROOT, env=stage_env(), text=True,
                stdout=subprocess.PIPE, stderr=subprocess.PIPE)))
        key, proc = running.pop(0)
        stdout, stderr = proc.communicate(timeout=300)
        cmd, data, before, words = prepared[key]
        results[key] = (subprocess.CompletedProcess(cmd, proc.returncode, stdout, stderr),
                        data, before, words)
    return results


@pytest.mark.parametrize("key", list(STAGE_CASES))
def test_a_stage_refuses_bad_input_in_one_line(stage_runs: dict[str, tuple[
        subprocess.CompletedProcess[str], Path, set[str], list[str]]], key: str) -> None:
    run, data, before, words = stage_runs[key]
    stage = STAGE_CASES[key][0]
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stdout + run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert lines[0].startswith(f"{stage}: error: "), lines[0]
    assert all(w in lines[0] for w in words), (words, lines[0])
    assert _files(data) == before  # nothing written, nothing that looks finished


SIGINT_STAGE = '''
import os, signal, time
from tattotronix.stage import run_stage

def main(cfg, out):
    out.write_text(out.path("made", "looks_finished.txt"), "no")
    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, mid-stage
    time.sleep(60)

if __name__ == "__main__":
    run_stage("interrupted", main)
'''


def test_ctrl_c_ends_a_stage_in_one_line_with_130_and_nothing_written(tmp_path: Path) -> None:
    script = tmp_path / "stages" / "interrupted.py"
    script.parent.mkdir()
    script.write_text(SIGINT_STAGE)
    data = tmp_path / "data"
    run = subprocess.run([PYTHON, str(script), f"paths.data={data}"], cwd=ROOT,
                         env=stage_env(), capture_output=True, text=True, timeout=120,
                         preexec_fn=default_signals)
    assert run.returncode == 130, run.stderr
    assert run.stderr.strip().splitlines() == [
        "interrupted: interrupted (Ctrl-C): stopped, nothing written"]
    assert not data.exists() or not _files(data)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_ctrl_c_on_a_real_stage(tmp_path: Path) -> None:
    """SIGINT to the toolpath stage while it orders 10 000 strokes (its work starts once
    the process has used a few seconds of CPU: the imports take about one)."""
    from tattotronix.art.artwork import load_artwork
    from tattotronix.art.mask import make_mask

    art = load_artwork(None, 150.0, 0.25, 40_000_000)
    data = tmp_path / "data"
    _mask(data, make_mask(art.grey, 0.25)[0])
    before = _files(data)
    proc = subprocess.Popen([PYTHON, "stages/toolpath.py", f"paths.data={data}",
                             "artwork.name=t", "toolpath.pitch_mm=0.05"], cwd=ROOT,
                            env=stage_env(), text=True, stdout=subprocess.PIPE,
                            preexec_fn=default_signals,
                            stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while _cpu_s(proc.pid) < 6.0 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert stderr.strip().splitlines() == [
        "toolpath: interrupted (Ctrl-C): stopped, nothing written"]
    assert "Traceback" not in stdout + stderr and _files(data) == before



def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.append(int(stat.parent.name))
    return kids


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_ctrl_c_stops_a_study_and_its_workers_at_once(draw_data: Path) -> None:
    """SIGINT to a study's stage while its pool runs the cases: the workers stop with it
    (no queued case runs first), the exit says so, and nothing is written."""
    before = _files(draw_data)
    proc = subprocess.Popen(
        [PYTHON, "stages/approach.py", f"paths.data={draw_data}", "study.all_cases=true",
         f"artwork.source={draw_data.parent / 'small.png'}", "mask.width_mm=24",
         "mask.min_region_mm2=0.5", "draw.progress=false",
         "study.approach_mm=[0.0,0.5,1.0,2.0,4.0,6.0]"],
        cwd=ROOT, env=stage_env(), text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        preexec_fn=default_signals)
    deadline = time.monotonic() + 120
    while len(_children(proc.pid)) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    workers = _children(proc.pid)
    assert proc.poll() is None and len(workers) >= 2, proc.communicate()
    time.sleep(0.5)  # the cases are under way
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert time.monotonic() - t0 < 5.0  # not the rest of the cases first
    assert stderr.strip().splitlines()[-1] == (
        "approach: interrupted (Ctrl-C): stopped, nothing written")
    assert "Traceback" not in stdout + stderr and _files(draw_data) == before
    assert not [w for w in workers if Path(f"/proc/{w}").exists()]
