"""Deprecated location: energy-dependent friction moved to :mod:`drake_est.identification.friction.energy`
(issue #18: the friction package holds one idea per module).  This alias keeps old imports working."""
import warnings as _warnings

from drake_est.identification.friction.energy import *  # noqa: F401,F403
from drake_est.identification.friction.energy import (EnergyFit, fit_energy, friction_power,  # noqa: F401
                                                      initial_guess, oe_fit, simulate_energy_system)

_warnings.warn("drake_est.identification.energy moved to drake_est.identification.friction.energy",
               DeprecationWarning, stacklevel=2)
