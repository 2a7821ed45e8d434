"""The one list of model-discrepancy effect names (thesis Ch. 9-10), shared by the synthetic
truth (:mod:`drake_est.synth`), the diagnosis (:mod:`drake_est.diagnose`) and the friction terms
that implement them (:mod:`drake_est.identification.friction`).

==============================  ===============================================  =============
effect                          model term                                        thesis
==============================  ===============================================  =============
position_dependent_friction     sign(qd) phi_k(q), Gaussian kernels in arm q     (9.13)-(9.16)
motor_position_ripple           LPV periodic components in q, amplitude(qd)      Ch. 10
energy_dependent_friction       sign(qd) E, E = k_e/(tau_e s + 1) |F qd|         (9.21)-(9.24)
asymmetric_coulomb              1[qd < 0] (a different Coulomb level)            (9.3)
gear_coupling                   qd_i, sign(qd_i) of the coupled joints i         (9.12)
payload                         ID with a mass at the flange (rigid body)        rigid body
abrupt_change                   [qd, sign(qd)] 1[t >= t_c]                        Ch. 7, (7.8)
position_dependent_load         phi_k(q) (no sign): gravity/spring, generic axes  (added name)
stribeck                        sign(qd) exp(-|qd/vs|^delta) (ks, vs)             (9.4), Sec. 9.1
time_periodic_disturbance       cos/sin(2 pi f t), f in Hz (not scaling w. speed) Ch. 10 (in time)
==============================  ===============================================  =============
"""
from __future__ import annotations

#: the fixed effect vocabulary (Table 9.2), in the order reports and benchmarks use
EFFECTS = ("position_dependent_friction", "motor_position_ripple", "energy_dependent_friction",
           "asymmetric_coulomb", "gear_coupling", "payload", "abrupt_change")

#: effect names beyond the fixed vocabulary (generic axes, whose nominal model has no gravity)
EXTRA_EFFECTS = ("position_dependent_load", "stribeck", "time_periodic_disturbance")

ALL_EFFECTS = EFFECTS + EXTRA_EFFECTS


def check_effect(name: str, allow_none: bool = True) -> str:
    """Return ``name`` if it is a known effect (or "none"), else raise a one-line DataError."""
    from drake_est.errors import DataError
    if (allow_none and name == "none") or name in ALL_EFFECTS:
        return name
    raise DataError(f"unknown effect '{name}'; choose from: none, {', '.join(ALL_EFFECTS)}")
