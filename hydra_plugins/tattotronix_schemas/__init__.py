"""Hydra plugin that registers TATTOTRONIX's config schemas in the ConfigStore.

Hydra imports every module under the ``hydra_plugins`` namespace when it starts, in any
process: a stage, a test, or DVC's own composition during ``dvc exp run``. Importing this
module is what makes ``conf/<group>/*.yaml`` able to name ``_schema`` in its defaults list.
"""

from __future__ import annotations

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin

from tattotronix.config.schema import register

register()


class TattotronixSchemas(SearchPathPlugin):
    """A no-op search-path plugin: the import above is its whole purpose."""

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        """Leave the search path unchanged."""
