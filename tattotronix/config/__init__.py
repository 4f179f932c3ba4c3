"""Configuration: typed schemas, composition of ``conf/`` and the ``params.yaml`` check."""

from __future__ import annotations
