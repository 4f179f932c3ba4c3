"""Any artwork the user points at is tracked (issue 30, item 1).

Each entry of ``vars: artworks`` in dvc.yaml gives its file as ``source``, a DVC
dependency of ``artwork@<name>``, and the overrides that draw it as ``args``: an edit to
the file makes the drawing stale. ``source`` must be the file ``artwork.source`` in
``args`` names (a built-in by its name: what its outputs record).
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
from pathlib import Path

import yaml

from tattotronix.art.artwork import resolve_source

from .conftest import PYTHON, ROOT, small_art

ENV = {k: v for k, v in os.environ.items() if not k.startswith("DVC_")}
# DVC runs `python stages/...`: make that the interpreter running the tests
ENV["PATH"] = os.pathsep.join([str(Path(PYTHON).parent), ENV.get("PATH", "")])

#: the entry of ``vars: artworks`` a clone gets for ``art/mine.png``
MINE_ARGS = "artwork.source=art/mine.png mask.width_mm=24"


class Clone:
    """A clone of the committed project with ``art/mine.png`` (:func:`small_art`) drawn as
    the entry ``mine`` of ``vars: artworks``; runs DVC and Python in it, on its own code."""

    def __init__(self, tmp_path: Path):
        self.root = tmp_path / "clone"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(self.root)], check=True)
        self.env = {**ENV, "PYTHONPATH": str(self.root)}  # the clone runs its own code
        (self.root / "art").mkdir()
        self.png = small_art(self.root / "art" / "mine.png")
        dvc_yaml = self.root / "dvc.yaml"
        text = dvc_yaml.read_text(encoding="utf-8")
        entry = ("  - artworks:\n      mine:\n        source: art/mine.png\n"
                 f"        args: {MINE_ARGS}\n")
        assert text.count("  - artworks:\n") == 1
        dvc_yaml.write_text(text.replace("  - artworks:\n", entry), encoding="utf-8")

    def run(self, *argv: str) -> subprocess.CompletedProcess[str]:
        """``argv`` run in the clone, its output captured."""
        return subprocess.run(list(argv), cwd=self.root, env=self.env, capture_output=True,
                              text=True, timeout=900)

    def dvc(self, *argv: str) -> subprocess.CompletedProcess[str]:
        """``dvc argv`` in the clone."""
        return self.run(PYTHON, "-m", "dvc", *argv)


def _artworks(root: Path) -> dict[str, dict[str, str]]:
    doc = yaml.safe_load((root / "dvc.yaml").read_text(encoding="utf-8"))
    (found,) = [v["artworks"] for v in doc["vars"] if "artworks" in v]
    assert isinstance(found, dict)
    return found


def _source_override(args: str) -> str:
    sources = [a.split("=", 1)[1] for a in shlex.split(args) if a.startswith("artwork.source=")]
    assert len(sources) == 1, args
    return sources[0]


def test_every_artworks_dep_is_the_file_its_overrides_draw() -> None:
    """The dep of each entry is what ``resolve_source`` makes of its ``artwork.source``
    (the built-ins: their asset), and every per-artwork stage draws it with ``args``."""
    artworks = _artworks(ROOT)
    assert {"emblem", "lineart", "lineart-vector"} <= set(artworks)
    for name, entry in artworks.items():
        assert set(entry) == {"source", "args"}, name
        drawn = resolve_source(_source_override(entry["args"]))
        assert drawn == (ROOT / entry["source"]).resolve(), name
    assert artworks["emblem"]["source"] == "tattotronix/art/assets/emblem.svg"
    assert _source_override(artworks["emblem"]["args"]) == "emblem"  # what it records
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text(encoding="utf-8"))["stages"]
    per_artwork = {n: s["do"] for n, s in stages.items() if s.get("foreach") == "${artworks}"}
    assert len(per_artwork) == 12, sorted(per_artwork)
    for name, body in per_artwork.items():
        assert body["cmd"].endswith(" ${item.args}"), name
    assert "${item.source}" in per_artwork["artwork"]["deps"]


def test_an_edit_to_a_users_artwork_makes_its_stage_stale(tmp_path: Path) -> None:
    """On a clone: one entry in ``vars: artworks`` draws a PNG (``dvc repro artwork@mine``
    runs that stage alone: the committed gates are current), after which ``dvc status``
    calls it up to date; an edit to the PNG makes ``dvc status`` name the file as a changed dep."""
    c = Clone(tmp_path)
    clone, dvc, png = c.root, c.dvc, c.png
    made = dvc("repro", "artwork@mine")
    assert made.returncode == 0, made.stdout[-3000:] + made.stderr[-3000:]
    ran = [line for line in made.stdout.splitlines() if line.startswith("Running stage")]
    # the clone's code and config stamps are committed and current: only the new drawing
    assert ran == ["Running stage 'artwork@mine':"], made.stdout
    metrics = json.loads((clone / "data" / "metrics" / "artwork" / "mine.json").read_text())
    assert metrics["source"] == "art/mine.png" and metrics["raster_px"][0] == 96
    clean = dvc("status", "--json", "artwork@mine")
    assert clean.returncode == 0 and json.loads(clean.stdout) == {}, clean.stdout

    from PIL import Image

    with Image.open(png) as im:
        edited = im.copy()
    edited.putpixel((5, 5), 0)  # one more dot of ink
    edited.save(png)
    stale = dvc("status", "--json", "artwork@mine")
    assert stale.returncode == 0, stale.stderr
    assert json.loads(stale.stdout) == {
        "artwork@mine": [{"changed deps": {"art/mine.png": "modified"}}]}, stale.stdout
