"""The application layer: what a user does with a drawing, each once.

* :mod:`~tattotronix.app.api`: the Python API (``tattotronix.plan``, ``plan_strokes``,
  :class:`~tattotronix.app.api.Plan`: stats, preview, simulate, predict, draw, save);
* :mod:`~tattotronix.app.draw`: ``draw.py``, and the one place a backend is chosen
  (:func:`~tattotronix.app.draw.play`: the simulated plants, the servo plant, the arm);
* :mod:`~tattotronix.app.drawings`: which drawing to play (stored, re-timed or planned
  here) and what a run writes (its metrics, ink images and log);
* :mod:`~tattotronix.app.pipeline`: artwork to toolpath to IK to trajectory in one process,
  with the stages' settings (the stages run the same calls one file at a time).

It sits above the domain layers (``hardware``, ``control``, ``plants`` and below) and
under the studies and the stages, which call it. The domain layers take their own
settings, not the root ``Config`` (``tests/test_layers.py`` holds that none does).
"""
