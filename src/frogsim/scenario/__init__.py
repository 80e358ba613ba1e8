"""Scenarios: the typed, SI, validated description of a run.

Units are parsed here and nowhere else (:mod:`frogsim.scenario.units` is the only module that
imports pint). A scenario file is read once (:mod:`frogsim.scenario.load`) into frozen dataclasses
(:mod:`frogsim.scenario.schema`); past that, a variant is made with :meth:`Scenario.replace`
(dotted path -> SI value), checked by the same field bounds and cross-field rules as the loader.
"""
