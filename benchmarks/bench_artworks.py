"""Many drawings, not only ours: plan (and simulate) a set of generated artworks.

Every goal the project holds must hold on drawings it was not tuned on. This benchmark
generates a set of artworks of the kinds users bring (a logo with holes, stars, text, line
art of several widths in raster and vector mode, random blobs with holes, the photograph
in edges mode, and the built-in emblem) and prints, for each:

* ``entries``: needle entries with compensation (the default) and without; the goal is
  with <= without;
* ``cycle``: the trajectory's duration over its marking-only time (goal <= 1.10);
* ``bleed``/``cover``: the planned ink against the artwork (worst bleed, mm; coverage);
* ``missed``: parts of the artwork no ink comes near (a lost line, a dropped region; the
  toolpath stage names each in a warning); the goal is 0;
* ``lines``: for stroked lines, the share of each designed centreline the needle covers
  (the worst line; goal >= 95 %, a line drawn as dashes scores far less);
* with ``--sim``: the worst marking error and the settled mean on MuJoCo over the whole
  drawing (``stages/draw.py``; goal < 20 µm and <= 2 µm), and the verdict;
* with ``--servo``: the mean and worst marking deviation the servo plant predicts for the
  arm as built (``backend=servo``, mm), with no correction (``servo_none``), with the
  defaults (the sag and the lead, ``servo_default``) and with all five
  (``servo_all``; issue 34's goal: mean <= 1.0 mm, worst <= 2.0 mm).

Usage::

    python benchmarks/bench_artworks.py [--sim] [--servo] [--only NAME ...] [--keep DIR]
    python benchmarks/run.py artworks        # planning only, as a row per figure

Planning takes seconds per drawing; ``--sim`` simulates each whole drawing (minutes each).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from bench_toolpath import logo_svg  # noqa: E402

#: stroke widths of the line-art drawing, mm (the issue's dashes were 0.5 to 0.65 mm)
LINE_WIDTHS_MM = (0.3, 0.5, 0.65, 1.0)


@dataclass(frozen=True)
class Art:
    """One benchmark drawing: its source (a file or a built-in name) and its overrides."""

    name: str
    source: str
    overrides: tuple[str, ...] = ()
    #: an SVG whose stroked lines are scored for dashes
    lines_svg: str | None = None


def _star(cx: float, cy: float, r: float, points: int, turn: float) -> str:
    angles = turn + np.arange(2 * points) * math.pi / points
    radii = np.where(np.arange(2 * points) % 2 == 0, r, 0.45 * r)
    xy = " ".join(f"{cx + q * math.sin(a):.3f},{cy - q * math.cos(a):.3f}"
                  for q, a in zip(radii, angles, strict=True))
    return f'<polygon points="{xy}"/>'


def stars_svg() -> str:
    """Seven filled stars of 5 to 8 points, 120 x 60 mm (deterministic)."""
    rng = np.random.default_rng(7)
    stars = "\n  ".join(
        _star(float(rng.uniform(15, 105)), float(rng.uniform(15, 45)),
              float(rng.uniform(7, 14)), int(rng.integers(5, 9)), float(rng.uniform(0, 1)))
        for _ in range(7))
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="120mm" height="60mm" '
            f'viewBox="0 0 120 60">\n <g fill="black">\n  {stars}\n </g>\n</svg>\n')


def blobs_svg() -> str:
    """Random filled blobs with holes (even-odd rings), 120 x 80 mm (deterministic)."""
    rng = np.random.default_rng(11)
    paths = []
    for _ in range(6):
        cx, cy = rng.uniform(20, 100), rng.uniform(18, 62)
        r = rng.uniform(8, 16)
        t = np.linspace(0, 2 * math.pi, 48, endpoint=False)
        wob = 1 + 0.25 * np.sin(3 * t + rng.uniform(0, 6)) * rng.uniform(0.3, 1)
        outer = " ".join(f"{cx + r * w * math.cos(a):.3f},{cy + r * w * math.sin(a):.3f}"
                         for w, a in zip(wob, t, strict=True))
        inner = " ".join(f"{cx + 0.4 * r * math.cos(a):.3f},{cy - 0.4 * r * math.sin(a):.3f}"
                         for a in t)
        paths.append(f'<path fill-rule="evenodd" d="M {outer} Z M {inner} Z"/>')
    body = "\n  ".join(paths)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="120mm" height="80mm" '
            f'viewBox="0 0 120 80">\n <g fill="black">\n  {body}\n </g>\n</svg>\n')


def lines_svg() -> str:
    """Stroked, unfilled lines of :data:`LINE_WIDTHS_MM`: a wave, a spiral arc, a zigzag
    and a circle per width, 120 x 80 mm."""
    rows = []
    for i, w in enumerate(LINE_WIDTHS_MM):
        y = 12 + 18 * i
        wave = " ".join(f"{x:.2f},{y + 4 * math.sin(x / 6):.3f}" for x in np.arange(8, 60, 1.0))
        zig = " ".join(f"{64 + 4 * k},{y + (4 if k % 2 else -4)}" for k in range(9))
        rows.append(f'<g stroke-width="{w}"><polyline points="{wave}"/>'
                    f'<polyline points="{zig}"/><circle cx="{108}" cy="{y}" r="6"/></g>')
    body = "\n  ".join(rows)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="120mm" height="80mm" '
            f'viewBox="0 0 120 80">\n <g fill="none" stroke="black" stroke-linecap="round">'
            f'\n  {body}\n </g>\n</svg>\n')


def text_png(path: Path) -> None:
    """Bold text, two lines, as a 300 dpi PNG (a scanned lettering sheet)."""
    from PIL import Image, ImageDraw, ImageFont

    im = Image.new("L", (1500, 700), 255)
    draw = ImageDraw.Draw(im)
    font: ImageFont.FreeTypeFont | ImageFont.ImageFont
    try:
        font = ImageFont.truetype("DejaVuSans-Bold.ttf", 230)
    except OSError:
        font = ImageFont.load_default(size=230)
    draw.text((60, 40), "INK &", fill=0, font=font)
    draw.text((60, 360), "2026", fill=0, font=font)
    im.save(path, dpi=(300, 300))


def artworks(folder: Path) -> list[Art]:
    """The benchmark's drawings, generated into ``folder``."""
    for name, text in (("logo.svg", logo_svg()), ("stars.svg", stars_svg()),
                       ("blobs.svg", blobs_svg()), ("lines.svg", lines_svg())):
        (folder / name).write_text(text)
    text_png(folder / "text.png")
    lines = str(folder / "lines.svg")
    return [
        Art("emblem", "emblem"),
        Art("logo", str(folder / "logo.svg")),
        Art("stars", str(folder / "stars.svg")),
        Art("blobs", str(folder / "blobs.svg")),
        Art("text", str(folder / "text.png")),
        Art("lines", lines, (), lines),
        Art("lines-vector", lines, ("artwork.vector=true",), lines),
        # placed turned on the panel: lines of the needle-compensation threshold's width
        # come out a hair under or over it along their length (they were lost, issue 30)
        Art("lines-turned", lines, ("mask.rotate_deg=20",)),
        Art("lineart", "lineart", ("mask.res_mm=0.1",)),
        Art("portrait-edges", "portrait", ("mask.method=edges", "mask.width_mm=110")),
    ]


@dataclass
class Result:
    """The figures of one drawing."""

    name: str
    figures: dict[str, float | int | str | None] = field(default_factory=dict)
    error: str | None = None


def worst_line(lines_svg_path: str, uv_mm: np.ndarray, marking: np.ndarray,
               shape: tuple[int, int], res_mm: float, step_mm: float,
               needle_mm: float) -> float:
    """The worst designed line's share of its length the needle passes along
    (:func:`tattotronix.path.linecover.line_coverage`)."""
    from tattotronix.art.artwork import read_svg, svg_intrinsic_size
    from tattotronix.art.vector import svg_lines
    from tattotronix.path.linecover import line_coverage

    path = Path(lines_svg_path)
    lines = svg_lines(path, svg_intrinsic_size(read_svg(path)), shape, res_mm, 0.05)
    shares = line_coverage(lines.paths, lines.widths_mm, uv_mm[marking], needle_mm, step_mm)
    return float(shares.min()) if len(shares) else 1.0


def plan_figures(art: Art) -> dict[str, float | int | str | None]:
    """Plan ``art`` with and without compensation, and its trajectory; the figures."""
    from tattotronix.app.pipeline import drawing_inputs, solve_ik, trajectory_from_path
    from tattotronix.config.params import compose_settings, with_overrides
    from tattotronix.kinematics import Chain
    from tattotronix.path.params import ToolpathParams
    from tattotronix.path.plan import plan_toolpath
    from tattotronix.robot.description import build_description
    from tattotronix.trajectory import JointPath

    cfg = compose_settings([f"artwork.source={art.source}", f"artwork.name={art.name}",
                            *art.overrides])
    t0 = time.perf_counter()
    mask, vector = drawing_inputs(cfg, art.source, art.name)
    out: dict[str, float | int | str | None] = {}
    tps = {}
    for comp in (False, True):
        c = with_overrides(cfg, [f"toolpath.compensate={str(comp).lower()}"])
        params = ToolpathParams.from_settings(c.toolpath, c.mask, c.robot.panel)
        tps[comp] = plan_toolpath(mask, params, vector=vector)
    tp = tps[cfg.toolpath.compensate]
    out["entries"] = tps[True].metrics.entries
    out["entries_uncomp"] = tps[False].metrics.entries
    out["drags"] = tps[True].metrics.drags
    out["drags_uncomp"] = tps[False].metrics.drags
    out["time_s"] = round(tp.metrics.time_s, 1)
    out["travel_mm"] = round(tp.metrics.travel_mm)
    ink = tp.ink(mask, cfg.toolpath.needle_width_mm, cfg.toolpath.ink_res_mm)
    fid = ink.fidelity
    out["bleed_mm"] = round(fid.bleed_max_mm, 3)
    out["cover"] = round(fid.coverage, 3)
    needle = float(cfg.toolpath.needle_width_mm)
    out["missed"] = len(ink.missed_by(cfg.toolpath.pitch_mm, needle, mask.res_mm,
                                      params.lines_only)[0])
    if art.lines_svg:
        marking = tp.path.kind == 1
        out["lines_worst"] = round(worst_line(
            art.lines_svg, tp.path.uvz_mm[:, :2], marking, mask.ink.shape, mask.res_mm,
            cfg.toolpath.step_mm, cfg.toolpath.needle_width_mm), 3)
    desc = build_description(cfg.robot)
    chain = Chain.from_description(desc)
    res = solve_ik(chain, tp.xyz_m, tp.path.uvz_mm, cfg.ik)
    tcp, _ = chain.fk(res.q)
    jp = JointPath.from_arrays(desc.joint_names, res.q, tcp, tp.path.kind, tp.path.uvz_mm)
    traj = trajectory_from_path(cfg, jp, desc)
    out["duration_s"] = round(traj.duration_s, 1)
    out["cycle"] = round(traj.duration_s / traj.marking_only_s, 3)
    out["plan_s"] = round(time.perf_counter() - t0, 1)
    return out


def sim_figures(art: Art, folder: Path) -> dict[str, float | int | str | None]:
    """Simulate the whole drawing on MuJoCo (``stages/draw.py``); its figures."""
    from tattotronix.art.artwork import resolve_source

    out_dir = folder / f"sim-{art.name}"
    # a file, not a built-in's name: draw.py plans it in memory under the drawing's name
    cmd = [sys.executable, str(ROOT / "stages" / "draw.py"), "backend=mujoco",
           f"artwork.source={resolve_source(art.source)}", f"artwork.name={art.name}",
           f"paths.out={out_dir}", "draw.progress=false", *art.overrides]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:]
        return {"verdict": f"failed: {tail[0] if tail else proc.returncode}"}
    metrics = json.loads(next((out_dir / "metrics" / "runs").glob("*.json")).read_text())
    return {"max_um": round(metrics["marking_max_um"], 1),
            "mean_um": round(metrics["settled_mean_um"], 2),
            "verdict": metrics["verdict"], "sim_s": round(time.perf_counter() - t0)}


#: the servo program's corrections (``hardware.compensate.<name>``)
CORRECTIONS = ("fit", "backlash", "deadband", "sag", "lead")
#: the corrections each ``--servo`` column switches on
SERVO_SETS = {"servo_none": (), "servo_default": ("sag", "lead"), "servo_all": CORRECTIONS}


def servo_figures(art: Art, folder: Path) -> dict[str, float | int | str | None]:
    """The whole drawing on the servo plant (``stages/draw.py backend=servo``) with each
    set of corrections: ``mean/worst`` marking deviation, mm."""
    from tattotronix.art.artwork import resolve_source

    out: dict[str, float | int | str | None] = {}
    for column, on in SERVO_SETS.items():
        out_dir = folder / f"servo-{art.name}-{column}"
        cmd = [sys.executable, str(ROOT / "stages" / "draw.py"), "backend=servo",
               f"artwork.source={resolve_source(art.source)}", f"artwork.name={art.name}",
               f"paths.out={out_dir}", "draw.progress=false", *art.overrides,
               *(f"hardware.compensate.{k}={str(k in on).lower()}" for k in CORRECTIONS)]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        if proc.returncode != 0:
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:]
            out[column] = f"failed: {tail[0] if tail else proc.returncode}"
            continue
        m = json.loads(next((out_dir / "metrics" / "runs").glob("*.json")).read_text())
        out[column] = f"{m['marking_mean_um'] / 1e3:.2f}/{m['marking_max_um'] / 1e3:.2f}"
    return out


COLUMNS = ("entries", "entries_uncomp", "drags", "drags_uncomp", "time_s", "cycle",
           "bleed_mm", "cover", "missed", "lines_worst", "max_um", "mean_um", "verdict",
           *SERVO_SETS)


def run(names: Sequence[str] = (), sim: bool = False, keep: Path | None = None,
        servo: bool = False) -> list[Result]:
    """Plan (and with ``sim`` simulate, with ``servo`` predict on the servo plant) every
    drawing, or those in ``names``."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        results = []
        for art in artworks(folder):
            if names and art.name not in names:
                continue
            res = Result(art.name)
            try:
                res.figures.update(plan_figures(art))
                if sim:
                    res.figures.update(sim_figures(art, folder))
                if servo:
                    res.figures.update(servo_figures(art, folder))
            except Exception as exc:  # one drawing's failure is a row, not the end
                res.error = f"{type(exc).__name__}: {exc}".splitlines()[0][:160]
            print(_line(res), flush=True)
            results.append(res)
    return results


def _line(res: Result) -> str:
    if res.error:
        return f"{res.name:15s} ERROR {res.error}"
    cells = [f"{k}={res.figures[k]}" for k in COLUMNS if k in res.figures]
    return f"{res.name:15s} " + " ".join(cells)


def _number(value: object) -> float:
    """A figure as a float (NaN where there is none)."""
    return float(value) if isinstance(value, int | float) else math.nan


def bench(repeat: int) -> list[tuple[str, float, str, str]]:
    """For ``benchmarks/run.py``: the planning figures as rows (no simulation)."""
    rows = []
    for res in run():
        if res.error:
            rows.append((f"{res.name}: error", math.nan, "", res.error))
            continue
        f = res.figures
        rows.append((f"{res.name}: entries (compensated)", _number(f["entries"]), "",
                     f"{f['entries_uncomp']} without compensation"))
        rows.append((f"{res.name}: cycle over marking", _number(f["cycle"]), "",
                     "goal <= 1.10"))
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sim", action="store_true", help="also simulate each whole drawing")
    ap.add_argument("--servo", action="store_true",
                    help="also predict each whole drawing on the servo plant, three ways")
    ap.add_argument("--only", nargs="*", default=(), help="drawing names")
    ap.add_argument("--keep", type=Path, help="keep the generated artworks and runs here")
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    results = run(args.only, args.sim, args.keep, args.servo)
    return 1 if any(r.error for r in results) else 0


if __name__ == "__main__":
    raise SystemExit(main())
