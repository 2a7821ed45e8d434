"""Deprecated location: :class:`PeriodicComponentsSystem` lives in :mod:`drake_est.systems.primitives`
(LeafSystems live in ``drake_est.systems``; this name is kept for old imports)."""
from drake_est.systems.primitives import PeriodicComponentsSystem  # noqa: F401
