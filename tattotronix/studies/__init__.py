"""Design studies: one module per study (kinematics, ...), each a library of functions that
return result dataclasses, driven by a thin ``stages/<study>.py``.

Modules are imported explicitly (``from tattotronix.studies.kinematics import ...``); this
package imports nothing, so one study's dependencies never load with another's.
"""

from __future__ import annotations
