"""Friction models and their identification (thesis Ch. 9).

Sign convention (used everywhere in drake_est): the friction torque ``F`` is the
torque the actuator must supply to overcome friction, so that the measured motor
torque is ``tau = ID(q, dq, ddq) + F`` (Eq. (9.8)); ``F`` has the sign of the
velocity.  The torque friction *exerts on the joint* is ``-F``.

Models are built from *terms*; each term maps the joint data to regressor
columns with names, so every model below is linear in its parameters (except the
energy dynamics, which Algorithm 6 handles in :mod:`.energy`):

================================  ==========================================  =============
term                              columns                                     Eq.
================================  ==========================================  =============
:class:`Coulomb`                  ``sign(v)``                                 (9.1)
:class:`Viscous`                  ``v``                                       (9.2)
:class:`AsymmetricCoulomb`        ``sign(v+)``, ``sign(v-)``                  (9.3)
:class:`BFETerm` on ``q``         normalized RBFs of arm position, split      (9.13)-(9.16)
                                  by velocity sign
:class:`BFETerm` on ``qm, dq``    RBFs in motor position x velocity,          Sec. 9.6
                                  ``qm = mod(g q, 2 pi)``                     (9.17)-(9.18)
:class:`BFETerm` on ``q, dq, E``  P x V x E expansion                         Sec. 9.4
:class:`CoupledJoint`             ``sign(dq_k)``, ``dq_k`` of gear-coupled     (9.12)
                                  wrist joints
:class:`Gravity`                  ``sin q``, ``cos q`` (single joint)         footnote 9.2
================================  ==========================================  =============

``JointFriction`` fits any list of terms to one joint by (ridge) least squares
(Eq. (6.8), solved by SVD in :func:`drake_est.regression.ridge_fit`, the penalty on
the basis-function weights chosen by cross-validation), predicts, and
serializes to a JSON-able dict (:meth:`JointFriction.to_dict`), which is what
:class:`drake_est.systems.friction.FrictionModel` consumes.

Data selection (9.9): :func:`select_steady` keeps samples with a velocity
significantly different from zero and small acceleration and reports how many
were dropped for each reason.

Modules of this package (one idea each; every public name is importable from the package):
``terms`` (the terms and the energy dynamics), ``model`` (:class:`JointFriction`),
``energy`` (Algorithm 6), ``fit`` (data selection, builders, :func:`fit_friction`),
``multijoint`` (friction + gravity of several joints).
"""
from __future__ import annotations

from drake_est.identification.friction.terms import (AsymmetricCoulomb, BFETerm, Coulomb, CoupledJoint,
                                                     EnergyDynamics, Gravity, Offset, TWO_PI, Term,
                                                     Viscous, _cols, _sign, coupled_joints, motor_position)  # noqa: F401
from drake_est.identification.friction.extensions import (ExtensionTerm, RippleRegressors, columns_at,  # noqa: F401
                                                          gaussian_features, term_from_dict, unit_energy)
from drake_est.identification.friction.model import (JointFriction, _check_identifiable, _gram_ridge)  # noqa: F401
from drake_est.identification.friction.energy import (EnergyFit, fit_energy, friction_power, initial_guess,
                                                      oe_fit, simulate_energy_system)  # noqa: F401
from drake_est.identification.friction.fit import (FrictionResult, MODELS, NOMINAL_KINDS, Selection,
                                                   _choose_structure, _cv_subsample, add_energy_expansion,
                                                   build_model, evaluate, fit_friction, friction_target,
                                                   nominal_terms, select_steady, split_holdout)  # noqa: F401
from drake_est.identification.friction.multijoint import (MultiJointFit, fit_multi_joint, gravity_regressor)  # noqa: F401
from drake_est.regression import ridge_cv  # noqa: F401  (old location of the CV helper)

__all__ = ['TWO_PI', 'motor_position', 'Term', 'Coulomb', 'Viscous', 'AsymmetricCoulomb', 'Offset', 'Gravity',
           'CoupledJoint', 'coupled_joints', 'BFETerm', 'term_from_dict', 'ExtensionTerm', 'RippleRegressors', 'columns_at', 'gaussian_features',
           'unit_energy', 'EnergyDynamics',
           'JointFriction', 'EnergyFit', 'fit_energy', 'friction_power', 'initial_guess', 'oe_fit',
           'simulate_energy_system', 'Selection', 'select_steady', 'NOMINAL_KINDS', 'nominal_terms',
           'MODELS', 'build_model', 'add_energy_expansion', 'evaluate', 'split_holdout', 'FrictionResult',
           'fit_friction', 'friction_target', 'gravity_regressor', 'MultiJointFit', 'fit_multi_joint']
