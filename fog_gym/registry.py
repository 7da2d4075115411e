"""The sensor registry: sensor config type → sensor class. Standard library only, so that the rig's config
(:mod:`fog_gym.config`) can check config types without importing the sensors; :mod:`fog_gym.sensors` registers
the built-in sensors and re-exports :func:`register` and :func:`sensor_class`.

Example:
    >>> class Cfg: pass
    >>> @register(Cfg)
    ... class Sensor: pass
    >>> sensor_class(Cfg) is Sensor
    True
    >>> _ = REGISTRY.pop(Cfg)
"""

from __future__ import annotations

#: Sensor config type → sensor class (see :func:`register`).
REGISTRY: dict[type, type] = {}


def register(config_type: type):
    """Class decorator: a rig's sensors whose config is a ``config_type`` are built by the class (its ``build``)."""
    if not isinstance(config_type, type):
        raise TypeError(f"config_type must be a class, got {config_type!r}")

    def deco(cls: type) -> type:
        REGISTRY[config_type] = cls
        return cls

    return deco


def registered_type(config_type: type) -> type | None:
    """The registered config type that ``config_type`` is (itself or its nearest base along its MRO), or None."""
    for t in getattr(config_type, "__mro__", (config_type,)):
        if t in REGISTRY:
            return t
    return None


def sensor_class(config_type: type) -> type:
    """The sensor class registered for ``config_type`` (the most specific one along its MRO)."""
    t = registered_type(config_type)
    if t is None:
        names = ", ".join(sorted(t.__name__ for t in REGISTRY))
        raise ValueError(f"config type must be one of the registered sensor configs ({names}), got {config_type.__name__}")
    return REGISTRY[t]
