"""Dynamics, the joint controller shared by every plant, closed-loop runs and their scoring.

* :mod:`~tattotronix.control.dynamics`: Pinocchio RNEA, CRBA, ABA and J_eff.
* :mod:`~tattotronix.control.analysis`: the loop facts of reference section 5.4.
* :mod:`~tattotronix.control.controller`: PID by pole placement, four structures.
* :mod:`~tattotronix.control.reference`: the reference at the controller's ticks.
* :mod:`~tattotronix.control.simulate`: one closed-loop run on any plant.
* :mod:`~tattotronix.control.tracking`: the errors of reference section 5.5.
* :mod:`~tattotronix.control.ink`: what the simulated needle drew, against the plan.
* :mod:`~tattotronix.control.drawing`: ``draw.py`` on a simulated plant (pick, run, score,
  write).
"""
