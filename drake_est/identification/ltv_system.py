"""Moved: :class:`LtvIdentifier` now lives in :mod:`drake_est.systems.identifiers` (outputs renamed
``state_matrix``/``input_matrix``); this alias keeps the old import working."""
from drake_est.systems.identifiers import LtvIdentifier  # noqa: F401
