"""The page in a real browser (issue 32): headless Chromium (Debian's ``chromium``, which
``.ci/run`` installs) driven by Playwright uploads an SVG, sees the plan and the ink the
servos would draw, starts a dry run, pauses and resumes it. The sent poses (the arm's
``poses.jsonl``, beside the I2C transcript) then show, by forward kinematics, that the
needle stayed at the clearance height through the pause and that every frame of the
drawing was sent, none twice. Screenshots of each step go to ``SCREENSHOTS`` when that
environment variable names a folder (README's is one of them)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.kinematics import Chain
from tattotronix.robot.description import build_description
from tests.test_server import _serve

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
LOGO = """<svg xmlns="http://www.w3.org/2000/svg" width="40mm" height="20mm" viewBox="0 0 40 20">
<path fill-rule="evenodd" d="M1 1H19V19H1Z M6 6H14V14H6Z"/><circle cx="30" cy="10" r="8"/>
</svg>"""

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(CHROMIUM is None, reason="no chromium (.ci/run installs it)")]


def _shot(page: object, name: str, folder: Path) -> None:
    path = folder / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)  # type: ignore[attr-defined]
    extra = os.environ.get("SCREENSHOTS")
    if extra:
        Path(extra).mkdir(parents=True, exist_ok=True)
        shutil.copy(path, Path(extra) / path.name)


def test_the_page_plans_predicts_starts_pauses_and_resumes(tmp_path: Path) -> None:
    from playwright.sync_api import expect, sync_playwright

    svg = tmp_path / "logo.svg"
    svg.write_text(LOGO)
    proc, _, port = _serve(tmp_path)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
            page = browser.new_page(viewport={"width": 1000, "height": 900})
            page.goto(f"http://127.0.0.1:{port}/")
            expect(page.locator("#live")).to_contain_text("no job yet", timeout=20_000)
            page.set_input_files("#file", str(svg))
            page.fill("#width", "16")
            # placed off the panel: said at once, from a draft, before any plan
            page.fill("#u", "95")
            expect(page.locator("#msg")).to_contain_text("off the", timeout=60_000)
            page.fill("#u", "0")
            expect(page.locator("#stats")).to_contain_text("draft: entries", timeout=60_000)
            expect(page.locator("#msg")).to_have_text("")
            page.click("#plan")
            expect(page.locator("#stats")).to_contain_text("duration", timeout=120_000)
            _shot(page, "1-plan", tmp_path)
            page.click("#predict")
            expect(page.locator("#ink img")).to_have_count(2, timeout=120_000)
            expect(page.locator("#ink")).to_contain_text("marking deviation")
            _shot(page, "2-predicted", tmp_path)
            page.click("#start")
            expect(page.locator("#live")).to_contain_text("drawing", timeout=60_000)
            page.wait_for_function(
                "() => /frame (\\d+)/.exec(document.getElementById('live').textContent)"
                " && +/frame (\\d+)/.exec(document.getElementById('live').textContent)[1] > 40",
                timeout=60_000)
            page.click("#pause")
            expect(page.locator("#live")).to_contain_text("dry run): paused", timeout=60_000)
            expect(page.locator("#live")).to_contain_text("lift to the clearance height")
            _shot(page, "3-paused", tmp_path)
            page.click("#resume")
            expect(page.locator("#live")).to_contain_text("dry run): done", timeout=180_000)
            _shot(page, "4-done", tmp_path)
            browser.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)

    (poses_file,) = (tmp_path / "srv" / "jobs").glob("*/runs/logo-arm/poses.jsonl")
    assert (poses_file.parent / "i2c.jsonl").stat().st_size > 0  # the transcript
    poses = [json.loads(line) for line in poses_file.read_text().splitlines()]
    assert {p["session"] for p in poses} == {1, 2}
    cfg = compose_settings()
    chain = Chain.from_description(build_description(cfg.robot))
    tcp, _ = chain.fk(np.array([p["q"] for p in poses]))
    height_mm = (tcp[:, 2] - float(cfg.toolpath.panel_origin[2])) * 1e3
    clearance = float(cfg.toolpath.clearance_mm)
    first = [p for p in poses if p["session"] == 1]
    # the pause: the first session ended with its lift, the needle at the clearance
    # height, and the second starts one frame's step from there (nothing is sent between)
    assert first[-1]["phase"] == "lift" and height_mm[len(first) - 1] >= clearance - 0.05
    assert height_mm[len(first)] >= clearance - 0.05
    step = np.abs(np.subtract(poses[len(first)]["q"], first[-1]["q"])).max()
    assert step < 0.01, step  # rad: a frame's move, not a jump
    # every frame of the drawing sent, none twice (a pause resumes at the frame it stopped)
    drawn = [p["frame"] for p in poses if p["phase"] == "draw"]
    frames = json.loads((poses_file.parent / "state.json").read_text())["frames"]
    assert sorted(drawn) == list(range(frames))
