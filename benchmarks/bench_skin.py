"""Drawings on the skin (issue 33): how well the simulated arm tracks generated artworks
laid around the forearm phantom, at several limits on the tip's acceleration while marking.

On the skin the wrist turns the needle with the normal while it marks, so each mm/s^2 of
the tip asks more of every joint than on the panel, and the loop's error (the default
controller, MuJoCo) grows with it. For each drawing (the built-ins and the generated
artworks of ``bench_artworks.py``), 60 mm wide at the default placement (its width around
the limb), and for each ``surface.tip_accel_mm_s2``: the worst and the settled mean
marking error (goal: under 20 um and at most 2 um), the drawing's duration, and the ink
in the skin against the plan (IoU). A drawing the arm cannot place is listed with its
refusal.

    python benchmarks/bench_skin.py [--accel 100 70 50 35] [--only logo stars]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_artworks import _number, artworks  # noqa: E402

from tattotronix.app.onskin import plan_on_surface, simulate_on_surface  # noqa: E402
from tattotronix.config.params import compose_settings  # noqa: E402
from tattotronix.errors import TattotronixError  # noqa: E402
from tattotronix.io.outputs import PIPELINE_DATA  # noqa: E402
from tattotronix.robot.description import build_description  # noqa: E402

#: the widths the skin drawings are laid at, mm (the pipeline's emblem-forearm: 60)
WIDTH_MM = 60.0


def skin_figures(source: str, overrides: Sequence[str], accel: float, data: Path
                 ) -> dict[str, float | str]:
    """Plan ``source`` on the phantom with the tip limit ``accel`` mm/s^2 and simulate it
    on MuJoCo; its figures (or its refusal)."""
    cfg = compose_settings([f"artwork.source={source}", f"mask.width_mm={WIDTH_MM:g}",
                            "surface.kind=forearm", f"surface.tip_accel_mm_s2={accel:g}",
                            "backend=mujoco", *overrides])
    desc = build_description(cfg.robot)
    try:
        d = plan_on_surface(cfg, source, Path(source).stem, desc)
        run = simulate_on_surface(cfg, data, desc, d, Path(source).stem)
    except TattotronixError as err:
        return {"refused": str(err).splitlines()[0][:90]}
    s = run.summary()
    return {"worst_um": _number(s["marking_max_um"]), "settled_um": _number(s["settled_mean_um"]),
            "duration_s": float(d.trajectory.t[-1]), "iou": _number(s["ink_iou"])}


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--accel", type=float, nargs="+", default=[100.0, 50.0],
                    help="surface.tip_accel_mm_s2 values, mm/s^2")
    ap.add_argument("--only", nargs="*", default=(), help="drawings by name")
    args = ap.parse_args(argv)
    data = Path(PIPELINE_DATA)  # the generated URDF and MJCF (`dvc repro` makes them)
    print(f"{'drawing':16} {'accel':>6} {'worst um':>9} {'settled um':>10} "
          f"{'duration s':>10} {'IoU':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for art in artworks(Path(tmp)):
            if args.only and art.name not in args.only:
                continue
            for accel in args.accel:
                own = [o for o in art.overrides if not o.startswith("mask.width_mm=")]
                f = skin_figures(art.source, own, accel, data)
                if "refused" in f:
                    print(f"{art.name:16} {accel:6g} refused: {f['refused']}")
                    continue
                print(f"{art.name:16} {accel:6g} {f['worst_um']:9.2f} {f['settled_um']:10.2f} "
                      f"{f['duration_s']:10.1f} {f['iou']:7.4f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
