"""Identify the servos from a photographed calibration sheet (docs/servos.md,
"Identification from a drawn sheet"; tattotronix/app/identify.py).

    python stages/calibrate.py sheet=sheet.png                  # the sheet, to print at 1:1
    python stages/calibrate.py photo=PHOTO [out=servo_figures.yaml] [overrides]
    python stages/calibrate.py demo=true [seed=N] [out=FILE]    # no arm: a synthetic photo

1. ``sheet=``: writes the sheet (four ArUco markers, 0.1 mm pixels: print it at 254 dpi,
   1:1) and tape it on the panel, its centre on the panel's centre, upright.
2. Draw the pattern on it, from Python: ``import tattotronix as tt; from
   tattotronix.app.identify import calibration_plan;
   calibration_plan().draw(tt.Arm(dry_run=False))``.
3. ``photo=``: finds the markers (a photo where one is missing is refused, in one line),
   rectifies the sheet, extracts the ink, fits each moving joint's backlash and dead band
   so that the servo plant draws what the photo shows, and writes ``out`` (default
   ``servo_figures.yaml``): give it as ``hardware.servo_figures_file=FILE`` and the
   corrections (and the servo plant) use the identified figures.

``demo=true`` makes the photo itself: a servo arm whose backlash and dead band differ from
the catalogue's (drawn within ``study.robustness.spread``, from ``seed``) draws the pattern on the
servo plant, its ink is photographed synthetically, and the figures are identified from
that photo; it prints the truth beside them.
"""

from __future__ import annotations

import logging
import math
import sys
import tempfile
from pathlib import Path

from tattotronix.errors import TattotronixError  # first: the package, before any library

log = logging.getLogger("tattotronix.calibrate")

_KEYS = ("sheet", "photo", "out", "demo", "seed")


def main(argv: list[str]) -> int:
    """Parse ``sheet=``, ``photo=``, ``out=``, ``demo=``, ``seed=``; the rest are overrides."""
    import cv2
    import numpy as np
    import yaml

    from tattotronix.app.identify import SheetModel, calibration_plan, identify
    from tattotronix.config.schema import ServoSpreadConfig
    from tattotronix.hardware.calibsheet import read_photo, sheet_image, synthetic_photo
    from tattotronix.hardware.servo_model import spread_servos

    logging.basicConfig(level=logging.INFO, format="[%(name)s] %(message)s")
    args = {k: v for k, _, v in (a.partition("=") for a in argv) if k in _KEYS}
    overrides = [a for a in argv if a.partition("=")[0] not in _KEYS]
    try:
        if "sheet" in args:
            path = Path(args["sheet"])
            cv2.imwrite(str(path), sheet_image())
            print(f"wrote {path}: print it at 1:1 (254 dpi: 0.1 mm pixels)")
            return 0
        demo = args.get("demo", "false").lower() == "true"
        if "photo" not in args and not demo:
            print("calibrate: give sheet=FILE, photo=FILE or demo=true", file=sys.stderr)
            return 2
        # the photo first: a photo that cannot be read is refused before anything is planned
        ink = None if demo else read_photo(Path(args["photo"]), name=f"photo={args['photo']}")
        work = Path(tempfile.mkdtemp(prefix="tattotronix-calibration-"))
        plan = calibration_plan(overrides, workdir=work)
        model = SheetModel.of_plan(plan)
        truth = None
        if demo:
            only = ServoSpreadConfig(**{f"{k}_pct": 0.0 for k in (
                "stall", "speed", "band", "nonlinearity", "armature", "latency")})
            rng = np.random.default_rng(int(args.get("seed", "0")))
            truth = spread_servos(model.catalogue(), only, rng)
            photo = synthetic_photo(model.ink(truth), model.grid, rng)
            cv2.imwrite(str(work / "photo.png"), photo)
            log.info("the synthetic photo: %s", work / "photo.png")
            ink = read_photo(photo, model.grid, "the synthetic photo")
        assert ink is not None
        found = identify(ink, model)
    except TattotronixError as exc:
        print(f"calibrate: error: {exc}", file=sys.stderr)
        return 2
    joints: dict[str, dict[str, float]] = {}
    for j, (name, spec) in enumerate(zip(plan.desc.joint_names, found.specs, strict=True)):
        if not any(name in f for f in found.factors.values()):
            continue
        row = {"backlash_deg": round(math.degrees(spec.backlash_rad), 4),
               "deadband_deg": round(math.degrees(spec.deadband_rad), 4)}
        if truth is not None:
            row["true_backlash_deg"] = round(math.degrees(truth[j].backlash_rad), 4)
            row["true_deadband_deg"] = round(math.degrees(truth[j].deadband_rad), 4)
        joints[name] = row
        print(f"{name}: " + ", ".join(f"{k} {v:g}" for k, v in row.items()))
    out = Path(args.get("out", "servo_figures.yaml"))
    text = yaml.safe_dump({"joints": joints, "residual_mm": round(found.residual_mm, 4),
                           "residual_catalogue_mm": round(found.residual_before_mm, 4)},
                          sort_keys=False)
    tmp = out.with_name(f".{out.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(out)
    print(f"wrote {out}: the photo's ink is {found.residual_mm:.3f} mm from the servo plant's "
          f"with these figures ({found.residual_before_mm:.3f} mm with the catalogue's); "
          f"use it with hardware.servo_figures_file={out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
