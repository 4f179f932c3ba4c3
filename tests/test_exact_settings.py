"""The exact way to the settings (``schema.build_exact``) builds what OmegaConf's merge
builds, or steps aside for it.

Every DVC stage starts with :func:`load_settings`, every study case with
:func:`with_overrides`, and a stage run by hand with :func:`hand_settings`; all take the
exact way when they can (milliseconds) and Hydra's and OmegaConf's otherwise (a second).
These tests hold the ways equal, type for type, on every stage command of ``dvc.yaml``,
every study case of ``conf/`` and the runs by hand of the README and the tests, and check
that what the exact way does not take (a value OmegaConf converts, a bad key, a bad
value, a flag or a group's choice by hand) gets the same settings or the same refusal as
before.
"""

from __future__ import annotations

import json
import shlex
from collections.abc import Callable
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from tattotronix.config.params import (
    _compose_params,
    compose_settings,
    hand_settings,
    load_settings,
    to_settings,
    with_overrides,
)
from tattotronix.config.schema import Config, ControllerConfig, NotExact, build_exact, to_dict
from tattotronix.errors import ConfigError

from .conftest import ROOT


def _typed(cfg: Config) -> str:
    """The settings as JSON: 160 and 160.0 differ here, as they would in a provenance."""
    return json.dumps(to_dict(cfg))


def _slow(overrides: list[str]) -> Config:
    return to_settings(_compose_params(overrides, ROOT))


def _stage_overrides() -> dict[str, list[str]]:
    from dvc.repo import Repo

    found = {}
    for stage in Repo(str(ROOT)).index.stages:
        argv = shlex.split(stage.cmd if isinstance(stage.cmd, str) else " ".join(stage.cmd))
        scripts = [i for i, a in enumerate(argv) if a.startswith("stages/")]
        if scripts:
            found[stage.addressing] = argv[scripts[0] + 1:]
    return found


def test_every_dvc_stage_gets_the_settings_omegaconf_builds() -> None:
    stages = _stage_overrides()
    assert len(stages) > 40 and any(argv for argv in stages.values())
    distinct = {tuple(argv): name for name, argv in stages.items()}  # stages share them
    for argv, name in distinct.items():
        fast, slow = load_settings(argv, ROOT), _slow(list(argv))
        assert fast == slow and _typed(fast) == _typed(slow), name


def _study_cases(cfg: Config) -> list[list[str]]:
    from tattotronix.studies.registry import STUDIES

    cases = {}
    for study in STUDIES.values():  # one case per set of keys (each key's value types)
        for overrides in study.cases(cfg.study).values():
            kinds = tuple(sorted((o.split("=")[0], type(_value(o)).__name__)
                                 for o in overrides))
            cases.setdefault((study.name, kinds), list(overrides))
    return list(cases.values())


def _value(override: str) -> object:
    import yaml

    return yaml.safe_load(override.partition("=")[2])


def test_every_study_case_gets_the_settings_omegaconf_builds() -> None:
    cfg = load_settings([], ROOT)
    cases = _study_cases(cfg)
    assert len(cases) >= 7
    for overrides in cases:
        slow = to_settings(OmegaConf.merge(OmegaConf.structured(Config), to_dict(cfg),
                                           OmegaConf.from_dotlist(overrides)))
        fast = with_overrides(cfg, overrides)
        assert fast == slow and _typed(fast) == _typed(slow), overrides


def _outcome(build: Callable[..., Config], *args: object) -> Config | str:
    """The settings ``build(*args)`` gives, or the message it refuses with."""
    try:
        return build(*args)
    except ConfigError as exc:
        return str(exc)


@pytest.mark.parametrize("overrides", [
    ["controller.wn=120"],  # an int for a float: 120.0 both ways
    ["controller.wn='120'"],  # a string OmegaConf converts
    ["controller.structure=pid", "draw.window=busiest"],
    ["draw.window=[10.0,5]"],  # Any: the list as given
    ["artwork.name=2024"],  # an int for a string: OmegaConf makes it "2024"
    ["toolpath.compensate=yes"],  # not a YAML bool to Hydra: OmegaConf refuses or converts
    ["+toolpath.extra=1"],  # an append: Hydra's way (and its refusal)
    ["~draw.art"],  # a delete
    ["controller.wn=abc"],
    ["controller.nothing=1"],
    ["controller.wn=-5"],  # out of range: refused either way
])
def test_overrides_the_exact_way_does_not_take_end_as_before(overrides: list[str]) -> None:
    slow = _outcome(_slow, overrides)
    fast = _outcome(load_settings, overrides, ROOT)
    if isinstance(slow, str):
        assert fast == slow
    else:
        assert isinstance(fast, Config) and _typed(fast) == _typed(slow)


@pytest.mark.parametrize("overrides", [
    ["controller.wn=abc"], ["controller.nothing=1"], ["controller.wn=-5"],
    ["controller.wn=1e2"], ["controller.structure=pid_g"], ["controller.wn"],
])
def test_study_overrides_end_as_omegaconf_ends_them(overrides: list[str]) -> None:
    cfg = load_settings([], ROOT)
    try:
        merged = OmegaConf.merge(OmegaConf.structured(Config), to_dict(cfg),
                                 OmegaConf.from_dotlist(overrides))
    except Exception:  # noqa: BLE001 (OmegaConf's refusal, which ours words)
        merged = None
    slow = (_outcome(to_settings, merged) if merged is not None else "bad configuration")
    fast = _outcome(with_overrides, cfg, overrides)
    if isinstance(slow, str):
        assert isinstance(fast, str) and fast.startswith(slow)
    else:
        assert isinstance(fast, Config) and _typed(fast) == _typed(slow)


@pytest.mark.parametrize("plain", [
    {"wn": "160"},  # a string for a float
    {"wn": True},  # a bool is not a number here
    {"structure": "PID"},  # not a member's name
    {"nothing": 1},  # an unknown key
    {"wn": "${x}"},
])
def test_build_exact_steps_aside_for_what_it_does_not_take(plain: dict[str, object]) -> None:
    with pytest.raises(NotExact):
        build_exact(ControllerConfig, plain)


def test_build_exact_fills_defaults_and_types_floats() -> None:
    built = build_exact(ControllerConfig, {"wn": 120})
    assert built == ControllerConfig(wn=120.0) and isinstance(built.wn, float)


def test_a_stage_reads_params_yaml_as_omegaconf_does(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """libyaml with OmegaConf's rules: ``16e1`` is a float (YAML 1.1 says a string)."""
    monkeypatch.setenv("DVC_EXP_NAME", "x")  # no gate: there is no conf/ beside this copy
    (tmp_path / "params.yaml").write_text((ROOT / "params.yaml").read_text())
    text = (tmp_path / "params.yaml").read_text()
    assert "  wn: 160.0\n" in text
    (tmp_path / "params.yaml").write_text(text.replace("  wn: 160.0\n", "  wn: 16e1\n", 1))
    fast = load_settings(["paths.data=x"], tmp_path)
    assert fast.controller.wn == 160.0 and isinstance(fast.controller.wn, float)


#: command lines of runs by hand: the README's, the tests' (and the DVC stages', above)
HAND_RUNS = [
    [], ["artwork.source=emblem"], ["mask.width_mm=60.0", "paths.out=/tmp/x"],
    ["backend=pybullet", "draw.progress=false"], ["artwork.source=lineart", "mask.res_mm=0.1",
                                                  "toolpath.compensate=true"],
    ["controller.structure=pid", "controller.wn=120.0"], ["artwork.name=my-logo"],
    ["paths.data=/tmp/somewhere", "dry_run=true"], ["surface.kind=forearm"],
    ["controller.wn=120"],  # an int for a float: 120.0 both ways
]


@pytest.mark.parametrize("argv", HAND_RUNS)
def test_a_run_by_hand_gets_the_settings_hydra_composes(argv: list[str]) -> None:
    """Where :func:`hand_settings` builds the settings itself, they are Hydra's
    composition of conf/ with the same command line, type for type."""
    fast = hand_settings(argv, ROOT)
    assert fast is not None, argv
    slow = compose_settings(argv)
    assert fast == slow and _typed(fast) == _typed(slow), argv


@pytest.mark.parametrize("argv", [
    ["-m", "controller.wn=100.0,120.0"], ["--cfg", "job"], ["surface=forearm"],
    ["hydra.verbose=true"], ["hydra/launcher=basic"], ["+toolpath.extra=1"],
    ["controller.wn='120'"],  # a string to convert
    ["controller.nothing=1"], ["controller.wn=-5"], ["controller.wn=abc"],
])
def test_what_a_run_by_hand_leaves_to_hydra(argv: list[str]) -> None:
    """A flag, a group's choice, a hydra key, an append, a string to convert and anything
    Hydra would refuse go Hydra's way (its composition, its words)."""
    assert hand_settings(argv, ROOT) is None


def test_a_run_by_hand_composes_when_conf_moved(tmp_path: Path) -> None:
    """A params.yaml the gate did not check against these bytes of conf/ (conf/ edited,
    params.yaml not yet recomposed) leaves the settings to Hydra's composition of conf/."""
    import shutil

    for name in ("conf",):
        shutil.copytree(ROOT / name, tmp_path / name)
    for name in ("params.yaml",):
        shutil.copy2(ROOT / name, tmp_path / name)
    (tmp_path / "data").mkdir()
    gate = ROOT / "data" / "config.hash"
    shutil.copy2(gate, tmp_path / "data" / "config.hash")
    assert hand_settings([], tmp_path) is not None  # the same bytes: the gate holds
    ctl = tmp_path / "conf" / "controller" / "default.yaml"
    ctl.write_text(ctl.read_text() + "wn: 120.0\n")
    assert hand_settings([], tmp_path) is None
