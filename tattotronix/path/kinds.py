"""The path point kinds, shared by the toolpath, the trajectory, the control and reports.

A point's kind says how the needle reaches it: ``TRAVEL`` (above the panel), ``MARK``
(in the skin, inking) or ``APPROACH`` (the slow last stretch of a plunge).
"""

from __future__ import annotations

__all__ = ["APPROACH", "MARK", "TRAVEL"]

TRAVEL, MARK, APPROACH = 0, 1, 2
