"""Collision safety: the collision model, the allowed pairs, and trajectory checks.

* :mod:`~tattotronix.collision.shapes`: mesh hulls and the committed k-DOP fallback.
* :mod:`~tattotronix.collision.pairs`: which body pairs are checked (derived, with
  reasons).
* :mod:`~tattotronix.collision.model`: Pinocchio's GeometryModel on coal; clearance at a
  pose, motion bounds, the pen's lowest point.
* :mod:`~tattotronix.collision.check`: a whole trajectory, samples and swept motion.
"""
