"""Moved: the Drake cart-pole Diagram (``add_cartpole``, ``CartPoleTrueSystem``, ``PLANT_FROM_THESIS``,
``THESIS_FROM_PLANT``) lives in :mod:`drake_est.systems.cartpole_plant`, which builds a Diagram from the
plant and the :class:`~drake_est.systems.controllers.CartAccelerationActuator` LeafSystem; the algorithm
package ``drake_est.control`` does not import ``drake_est.systems``.  The names are forwarded here so that
old imports keep working."""

_MOVED = ("add_cartpole", "CartPoleTrueSystem", "PLANT_FROM_THESIS", "THESIS_FROM_PLANT")


def __getattr__(name):
    if name in _MOVED:
        from drake_est.systems import cartpole_plant
        return getattr(cartpole_plant, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
