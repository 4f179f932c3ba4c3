"""Time law: the accuracy goals on artworks other than the emblem (docs/timelaw.md).

Each artwork is planned from its image with the defaults (tip acceleration and jerk
limits, blended travel) and drawn closed loop over the whole drawing on MuJoCo with the
default controller (pid_g_v, wn 160 rad/s, 1 kHz). The goals (issue 16): worst marking
error below 20 um, settled mean at most 2 um, travel mean error below 20 um, peak torque
no higher than the acceleration-limited law's on the emblem (0.391 N m); the cycle over
the marking-only time is reported beside them.

* ``shapes``: the tracer self-test's five shapes (docs/original.md, "2.10 Tracer
  self-test": disc, annulus, C, E, B), drawn here as one image;
* ``stars``: three stars of 5, 7 and 12 points (sharp corners everywhere);
* ``portrait-edges``: the built-in portrait in ``edges`` mode, 100 mm wide (at the
  default 150 mm it does not fit the panel).

Not timed (one run each): the figures are the tracking, not the wall time.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw
from run import Row

from tattotronix.app.pipeline import plan_drawing
from tattotronix.app.simulate import run_closed_loop
from tattotronix.art.artwork import builtin_path
from tattotronix.config.params import compose_settings
from tattotronix.control.drawing import Drawing
from tattotronix.kinematics import Chain
from tattotronix.robot.description import build_description

DATA = Path(__file__).resolve().parents[1] / "data"


def shapes_png(path: Path) -> Path:
    """The tracer self-test's five shapes side by side (black ink on white)."""
    im = Image.new("L", (1600, 400), 255)
    d = ImageDraw.Draw(im)
    cy = 200
    disc, ring, c_shape, e_shape, b_shape = 160, 480, 800, 1120, 1440
    d.ellipse([disc - 150, cy - 150, disc + 150, cy + 150], fill=0)
    for x in (ring, c_shape):
        d.ellipse([x - 150, cy - 150, x + 150, cy + 150], fill=0)
        d.ellipse([x - 80, cy - 80, x + 80, cy + 80], fill=255)
    d.rectangle([c_shape, cy - 40, c_shape + 160, cy + 40], fill=255)
    for x, right in ((e_shape, 101), (b_shape, 50)):
        d.rectangle([x - 100, cy - 140, x + 100, cy + 140], fill=0)
        for y in (cy - 70, cy + 70):
            d.rectangle([x - 50, y - 30, x + right, y + 30], fill=255)
    im.save(path)
    return path


def stars_png(path: Path) -> Path:
    """Three stars of 5, 7 and 12 points (black ink on white)."""
    im = Image.new("L", (1600, 500), 255)
    d = ImageDraw.Draw(im)
    for x0, n in ((250, 5), (750, 7), (1300, 12)):
        a = np.pi / 2 + np.arange(2 * n) * np.pi / n
        r = np.where(np.arange(2 * n) % 2 == 0, 220.0, 80.0)
        d.polygon(list(zip(x0 + r * np.cos(a), 250 - r * np.sin(a), strict=True)), fill=0)
    im.save(path)
    return path


def _row(name: str, source: Path, overrides: list[str]) -> list[Row]:
    cfg = compose_settings([f"artwork.source={source}", *overrides])
    desc = build_description(cfg.robot)
    traj = plan_drawing(cfg, source, name, desc)
    drawing = Drawing(name, traj.t, traj.q, traj.qd, traj.kind, "planned", {})
    loop = run_closed_loop(cfg, DATA, desc, drawing)
    m = loop.metrics(loop.errors(Chain.from_description(desc), float(cfg.draw.settle_periods)))
    tm = traj.metrics()
    note = (f"settled mean {m['settled_mean_um']:.2f} um, travel mean "
            f"{m['travel_mean_um']:.1f} um, peak torque {m['peak_torque_nm']:.3f} N m, "
            f"cycle x{tm['cycle_over_marking']:.3f}, {tm['entries']} entries, peak jerk "
            f"{tm['peak_jerk_rad_s3_max']:.0f} rad/s^3, tip "
            f"{tm['peak_tip_accel_marking_mm_s2']:.1f} mm/s^2")
    worst = m["marking_max_um"]
    return [(f"worst marking error [{name}]",
             float(worst) if isinstance(worst, int | float) else math.nan, "um", note)]


def bench(repeat: int) -> list[Row]:
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        rows += _row("shapes", shapes_png(Path(tmp) / "shapes.png"), [])
        rows += _row("stars", stars_png(Path(tmp) / "stars.png"), [])
    rows += _row("portrait-edges", builtin_path("portrait"),
                 ["mask.method=edges", "mask.width_mm=100"])
    return rows
