"""What a stage run by DVC records of its config: the params DVC reruns it on, its
command's overrides, and what its input artifacts record (tattotronix/config/tracked.py,
tattotronix/io/provenance.py). A change DVC does not rerun a stage on must leave its
outputs' bytes alone, or a clean clone writes other bytes than dvc.lock says."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from tattotronix.config.tracked import override_keys, param_stamps, stage_names, tracked_params
from tattotronix.errors import ConfigError
from tattotronix.io.npz import save_npz
from tattotronix.io.provenance import only_keys, provenance_json, recorded_keys

from .conftest import PYTHON, ROOT, small_art

PIPELINE = {
    "vars": [{"arts": {"a": "artwork.source=a.png", "b": "artwork.source=b.png mask.res_mm=0.1"}},
             {"one": "a"}],
    "stages": {
        "plain": {"cmd": "x", "params": ["robot", "toolpath.pitch_mm"]},
        "each": {"foreach": "${arts}", "do": {"cmd": "x ${item}", "params": ["mask"]}},
        "listed": {"foreach": ["p", "q"], "do": {"cmd": "x", "params": [
            {"params.yaml": ["speed", "ik.seed"]}]}},
        "none": {"cmd": "x ${one}"},
    },
}


def _write(tmp_path: Path, doc: object) -> Path:
    (tmp_path / "dvc.yaml").write_text(yaml.safe_dump(doc))
    return tmp_path


def test_a_stages_tracked_params_are_its_own(tmp_path: Path) -> None:
    root = _write(tmp_path, PIPELINE)
    assert tracked_params("plain", root, {}) == ("robot", "toolpath.pitch_mm")
    assert tracked_params("each@b", root, {}) == ("mask",)
    assert tracked_params("listed@q", root, {}) == ("speed", "ik.seed")
    assert tracked_params("none", root, {}) == ()
    assert tracked_params("dvc.yaml:plain", root, {}) == ("robot", "toolpath.pitch_mm")


@pytest.mark.parametrize(("doc", "stage", "says"), [
    (PIPELINE, "each@c", "no stage 'each@c'"),
    (PIPELINE, "each", "no stage 'each'"),
    ({"stages": {"m": {"matrix": {"x": [1]}, "cmd": "x"}}}, "m", "only plain and foreach"),
    ({"vars": ["vars.yaml"], "stages": {}}, "m", "only inline vars"),
    ({"stages": {"s": {"foreach": "${nope}", "do": {"cmd": "x"}}}}, "s@a",
     "${nope} names nothing"),
    ({"stages": {"s": {"cmd": "x", "params": [{"other.yaml": ["k"]}]}}}, "s", "params from other"),
])
def test_a_pipeline_it_cannot_read_is_refused_by_name(tmp_path: Path, doc: object, stage: str,
                                                      says: str) -> None:
    with pytest.raises(ConfigError) as err:
        tracked_params(stage, _write(tmp_path, doc), {})
    assert says in str(err.value)


def test_no_pipeline_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="dvc.yaml"):
        tracked_params("robot", tmp_path, {})


def test_every_stage_of_the_pipeline_tracks_what_dvc_says() -> None:
    """Our reading of dvc.yaml against DVC's own, stage by stage: the params DVC tracks
    and those its stage's ``meta`` lists for the param stamp; and each stamp holds the
    values of exactly those keys."""
    from dvc.dependency.param import ParamsDependency
    from dvc.repo import Repo

    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    stamps = param_stamps(ROOT, params)
    with Repo(str(ROOT)) as repo:
        stages = list(repo.index.stages)
        assert stages
        assert sorted(s.addressing for s in stages) == sorted(stage_names(ROOT, params))
        for stage in stages:
            dvc_keys = sorted(k for d in stage.deps if isinstance(d, ParamsDependency)
                              for k in d.params)
            meta_keys = list((stage.meta or {}).get("params", []))
            ours = tracked_params(stage.addressing, ROOT, params)
            assert sorted(ours) == sorted(dvc_keys + meta_keys), stage.addressing
            if meta_keys:
                stamp = json.loads(stamps[stage.addressing.split("@")[0]])
                assert stamp == only_keys(params, meta_keys), stage.addressing
                assert f"data/params/{stage.addressing.split('@')[0]}.json" in {
                    d.def_path.replace("${paths.data}", "data") for d in stage.deps}


def test_override_keys() -> None:
    assert override_keys(["artwork.name=x", "+a.b=1", "~c", "++d=2", "-m"]) == (
        "artwork.name", "a.b", "d")


def test_only_keys_takes_sections_and_values_and_copies() -> None:
    config = {"toolpath": {"pitch_mm": 1.2, "step_mm": 0.1}, "speed": 1.0,
              "robot": {"panel": {"x": 1}, "tool": "pen"}}
    part = only_keys(config, ["toolpath.pitch_mm", "robot.panel", "missing.key", "nope"])
    assert part == {"toolpath": {"pitch_mm": 1.2}, "robot": {"panel": {"x": 1}}}
    part["robot"]["panel"]["x"] = 2
    assert config["robot"]["panel"]["x"] == 1  # a copy, never the config's own dicts
    # a section and one of its keys, in either order, keep the whole section
    assert only_keys(config, ["toolpath.pitch_mm", "toolpath"]) == {"toolpath": config["toolpath"]}
    assert only_keys(config, ["toolpath", "toolpath.pitch_mm"]) == {"toolpath": config["toolpath"]}


def test_a_stage_records_its_keys_and_what_its_inputs_record(tmp_path: Path) -> None:
    upstream = {"mask": {"res_mm": 0.1}, "speed": 9.0, "artwork": {"source": "a.png"}}
    src = tmp_path / "in.npz"
    save_npz(src, {"x": np.zeros(2), "provenance": np.array(json.dumps({"config": upstream}))})
    plain = tmp_path / "in.png"
    plain.write_bytes(b"not an artifact")
    config = {"speed": 1.0, "controller": {"wn": 60.0}, "mask": {"res_mm": 0.1, "k": 2},
              "study": {"x": 1}}
    with recorded_keys(["speed"]):
        prov = json.loads(provenance_json(config, {"in": src, "png": plain}, "code"))
    # its own value wins; the upstream's fill in; nothing it does not track
    assert prov["config"] == {"speed": 1.0, "mask": {"res_mm": 0.1},
                              "artwork": {"source": "a.png"}}
    assert prov["inputs"]["png"]["path"] == str(plain)
    # run by hand: the whole config
    whole = json.loads(provenance_json(config, {"in": src}, "code"))
    assert whole["config"] == config


def _mask_run(root: Path, *, exp: bool = True, extra: tuple[str, ...] = ()) -> bytes:
    env = {k: v for k, v in os.environ.items() if not k.startswith("DVC_")}
    env.update(DVC_STAGE="mask@emblem", **({"DVC_EXP_NAME": "exp"} if exp else {}))
    run = subprocess.run([PYTHON, "stages/mask.py", "artwork.name=small", "mask.width_mm=24",
                          "mask.res_mm=0.1", *extra], cwd=root, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return (root / "data" / "mask" / "small.npz").read_bytes()


def test_a_change_dvc_does_not_rerun_a_stage_on_leaves_its_bytes(tmp_path: Path) -> None:
    """The mask stage under DVC (``dvc exp run`` style: params.yaml as DVC composed it):
    a new controller bandwidth, which DVC does not rerun it on, leaves its npz byte for
    byte; a mask setting it tracks moves it, even one that leaves the mask alone."""
    root = tmp_path / "project"
    root.mkdir()
    shutil.copytree(ROOT / "stages", root / "stages")
    for name in ("params.yaml", "dvc.yaml"):
        shutil.copy(ROOT / name, root / name)
    (root / "data" / "artwork").mkdir(parents=True)
    small_art(root / "data" / "artwork" / "small.png")
    # the grid the artwork stage would record for it (24 mm at 0.1 mm/px)
    (root / "data" / "metrics" / "artwork").mkdir(parents=True)
    (root / "data" / "metrics" / "artwork" / "small.json").write_text(
        json.dumps({"res_mm": 0.1, "raster_px": [240, 120]}))
    first = _mask_run(root)
    params = root / "params.yaml"
    doc = yaml.safe_load(params.read_text())
    doc["controller"]["wn"] = float(doc["controller"]["wn"]) + 7.0
    doc["study"]["window_s"] = float(doc["study"]["window_s"]) + 1.0
    params.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert _mask_run(root) == first
    with np.load(root / "data" / "mask" / "small.npz") as z:
        recorded = json.loads(str(z["provenance"]))["config"]
    # the mask stage also checks the arm's reach where the drawing is placed: the panel,
    # the IK settings and the needle's heights
    assert sorted(recorded) == ["artwork", "ik", "mask", "robot", "toolpath"]
    assert sorted(recorded["robot"]) == ["panel"]
    assert sorted(recorded["toolpath"]) == ["clearance_mm", "panel_origin", "plunge_mm"]
    assert recorded["artwork"] == {"name": "small"}
    assert recorded["mask"]["res_mm"] == 0.1 and recorded["mask"]["width_mm"] == 24.0
    doc["mask"]["edge_k"] = float(doc["mask"]["edge_k"]) + 0.5  # the threshold ignores it
    params.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert _mask_run(root) != first
