"""Dynamics, the joint controller shared by every plant, closed-loop runs and their scoring.

* :mod:`~tattotronix.control.dynamics`: Pinocchio RNEA, CRBA, ABA and J_eff.
* :mod:`~tattotronix.control.analysis`: the loop facts (docs/control.md, "Loop facts").
* :mod:`~tattotronix.control.controller`: PID by pole placement, four structures.
* :mod:`~tattotronix.control.reference`: the reference at the controller's ticks.
* :mod:`~tattotronix.control.simulate`: one closed-loop run on any plant.
* :mod:`~tattotronix.control.tracking`: the errors as the original scored them
  (docs/original.md, "5.5 Tracking error").
* :mod:`~tattotronix.control.ink`: what the simulated needle drew, against the plan.
* :mod:`~tattotronix.control.drawing`: a timed drawing played closed loop on a plant, and
  its ink (which drawing, and what a run writes, are the application's: ``tattotronix.app``).
"""
