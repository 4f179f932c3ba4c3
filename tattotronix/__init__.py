"""TATTOTRONIX: a config-driven pipeline for a 5-DOF tattoo and drawing arm.

The library is layered: a module imports only from its own layer's package and the layers
below it, ``a | b`` share a layer and never import each other, and no imports form a cycle
at any depth (``lint-imports``, with the contracts in ``pyproject.toml``). Top to bottom:

* ``devtools``: tools run on the project (the stages' code deps); nothing imports them.
* ``stage``: the runner of ``stages/<name>.py``, above the library it calls; only they import it.
* ``report``: figures, the animation and the robot report present the results of every layer.
* ``studies``: design studies, which run the pipeline, the control loop and the servo model.
* ``hardware``: servo board, program and deploy gate, for drawings control and collision clear.
* ``control``: a drawing simulated in closed loop on a plant, planned through the pipeline.
* ``plants``: the simulated arms, built from the robot models, that control drives.
* ``pipeline``: artwork to toolpath to IK to trajectory in one process, from the layers below.
* ``trajectory``: times the IK'd path; its travel moves are checked by collision.
* ``collision``: the collision model, its pairs and the trajectory check, on the robot.
* ``kinematics``: the chain and the IK, which solve the toolpath's points (and read their kinds).
* ``path``: the artwork's ink mask to a toolpath on the panel.
* ``robot | art``: the two independent inputs: the robot description and models, the artwork.
* ``config``: the Hydra config and its typed schema, read by every layer above.
* ``io | plotting``: independent leaf utilities: output files and provenance, matplotlib helpers.
* ``errors``: the exceptions every layer raises; imports nothing of the project.
"""

from __future__ import annotations

__version__ = "0.1.0"

