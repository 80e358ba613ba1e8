"""A scenario seen through the few top-level settings one step declares it reads.

The cross-field rules (:mod:`frogsim.scenario.rules`) and the parts of a model
(:mod:`frogsim.circuit.model`) each name the top-level settings they read (``source``,
``muscles``, ``duration``...) and receive a :class:`Settings` that holds only those: reading any
other one raises AttributeError at once, on every scenario. So a step's result is a function of
exactly the settings it names, and a batch of variants (:mod:`frogsim.scenario.variants`) may run
it once per distinct combination of them and share the answer among the points: exact by
construction, with no guess of what a step depends on.
"""
from __future__ import annotations

import dataclasses


class Settings:
    """Read-only access to the top-level settings ``names`` of a scenario (or of a variant given as
    a dict of its top-level values).

    The declared settings are copied into the instance's attributes when it is made, so reading
    one is a plain attribute read (a model's build reads about thirty); only a name not declared
    reaches :meth:`__getattr__`, which refuses it."""

    def __init__(self, values: dict, names: tuple, owner: type):
        d = self.__dict__
        for name in names:
            d[name] = values[name]
        d["_names"] = names
        d["_owner"] = owner          # the scenario's class (its fields' metadata)

    def meta(self, name: str) -> dict:
        """The field metadata (kind, bounds, display unit) of top-level setting ``name``."""
        return next(f.metadata for f in dataclasses.fields(self._owner) if f.name == name)

    def __getattr__(self, name):
        # only names that are not attributes come here: those the step did not declare
        raise AttributeError(f"{name!r} is not among the settings this step declares it reads "
                             f"({', '.join(self._names)}); add it to the declaration")

    def __setattr__(self, name, value):
        raise AttributeError(f"{name!r}: a step's settings are read-only")
