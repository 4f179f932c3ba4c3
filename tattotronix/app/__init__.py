"""The application layer: what a user does with a drawing, each once.

* :mod:`~tattotronix.app.api`: the Python API (``tattotronix.plan``, ``plan_strokes``,
  :class:`~tattotronix.app.api.Plan`: stats, preview, simulate, predict, draw, save);
* :mod:`~tattotronix.app.draw`: ``draw.py``, and the one place a backend is chosen
  (:func:`~tattotronix.app.draw.play`: the simulated plants, the servo plant, the arm);
* :mod:`~tattotronix.app.drawings`: which drawing to play (stored, re-timed or planned
  here) and what a run writes (its metrics, ink images and log).

It sits above the domain layers (``hardware``, ``control``, ``plants``, ``pipeline`` and
below) and under the studies and the stages, which call it.
"""
