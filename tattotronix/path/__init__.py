"""Toolpaths: outlines, hatch fill, lifts, resampling, ordering, panel mapping.

Entry point: :func:`tattotronix.path.plan.plan_toolpath` (mask to ordered 3-D path), with
:class:`tattotronix.path.params.ToolpathParams` built from the config. Modules:

* ``regions``: 8-connected regions and their outer and hole loops (OpenCV tracing);
* ``polyline``: smoothing and constant-step resampling that keeps the end point;
* ``fill``: boustrophedon hatch at exactly the pitch, on ink;
* ``strokes``: regions to strokes (mm), in the original's order;
* ``inklookup`` and ``costs``: on-ink tests and the time cost between strokes;
* ``order``: the original's order and ours (greedy, 2-opt, seams);
* ``path3d``: lifts, plunges with the slow approach, drags; ``timing``: times and figures;
* ``panel``: the panel fit check and the arm-frame mapping; ``figure``: the PNG;
* ``laps``: the wall time of each planning step (for the benchmark).
"""

from __future__ import annotations
