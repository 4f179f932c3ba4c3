"""Figures draw text with the fonts matplotlib ships, whatever fonts the machine has and
whichever environment built the user's shared font cache (tattotronix/plotting.py,
``pin_fonts``): two machines once wrote the same figure with a label a pixel apart."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from .conftest import ROOT

SCRIPT = """
import json, sys
import matplotlib
from matplotlib import font_manager
from tattotronix.plotting import pyplot
plt = pyplot()
fig, ax = plt.subplots()
t = ax.text(0, 0, " exact hold: 2 / (3 $\\\\lambda_{max}$) = 0.316", fontweight="bold")
fig.canvas.draw()
print(json.dumps({"data": matplotlib.get_data_path(),
                  "fonts": [font_manager.findfont(font_manager.FontProperties(**p)) for p in
                            ({}, {"weight": "bold"}, {"style": "italic"},
                             {"family": "DejaVu Sans Display"})],
                  "extent": list(t.get_window_extent().bounds)}))
"""


def _fonts(cache: Path, seed: str) -> dict[str, object]:
    import json
    import os

    env = {**os.environ, "MPLCONFIGDIR": str(cache), "PYTHONHASHSEED": seed}
    r = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, text=True,
                       capture_output=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_text_uses_the_shipped_fonts_whatever_the_font_cache(tmp_path: Path) -> None:
    """A fresh font cache, and one that lists only the system's fonts (as a cache built by
    a since-deleted environment did): the same font files and the same text extent."""
    fresh = _fonts(tmp_path / "fresh", "1")
    assert all(str(f).startswith(str(fresh["data"])) for f in fresh["fonts"]), fresh
    # the user's cache, as another environment left it: no shipped font in it
    import json

    cache = tmp_path / "stale"
    cache.mkdir()
    built = next((tmp_path / "fresh").glob("fontlist-*.json"))
    listed = json.loads(built.read_text())
    listed["ttflist"] = [e for e in listed["ttflist"]
                         if str(e["fname"]).startswith("/usr/")] or listed["ttflist"][:1]
    (cache / built.name).write_text(json.dumps(listed))
    stale = _fonts(cache, "2")
    assert stale["fonts"] == fresh["fonts"] and stale["extent"] == fresh["extent"]
