"""Drake ``LeafSystem`` wrappers and Diagram builders, mirroring pydrake's namespaces (docs/conventions.md).

Thin wrappers only; the algorithms live in ``estimation/``, ``control/``, ``identification/``,
``calibration/``, ``spectral/``. Import the submodule you need (nothing is imported here, so that
``import drake_est.systems.X`` stays cheap):

* :mod:`~drake_est.systems.builders` -- ``Add...``/``Make...`` Diagram builders configured by dataclasses;
* :mod:`~drake_est.systems.estimators`, :mod:`~drake_est.systems.particle_filter` -- state estimators;
* :mod:`~drake_est.systems.controllers` -- controllers;
* :mod:`~drake_est.systems.identifiers` -- online identifiers (LTV);
* :mod:`~drake_est.systems.friction` -- friction models;
* :mod:`~drake_est.systems.sensors` -- F/T sensor, laser scanner, ...;
* :mod:`~drake_est.systems.dynamics` -- learned dynamics;
* :mod:`~drake_est.systems.primitives` -- signal systems (periodic components);
* :mod:`~drake_est.systems.contract` -- the contract every LeafSystem meets (``contract_cases()``).
"""
