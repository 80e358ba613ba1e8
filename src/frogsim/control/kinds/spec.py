"""What a controller kind's module declares (not a kind: it declares none).

Every kind module of :mod:`frogsim.control.kinds` ends with one declaration,
``KIND = ControllerKind(...)``, which the registry (:mod:`frogsim.control.kinds`) finds and checks
when the package is imported. It names, in one place, everything the rest of frogsim reads of the
kind:

* ``settings``: its settings class (a frozen dataclass derived from
  :class:`frogsim.scenario.kinds.ControllerSettings`; its ``KIND`` is the kind's name in files,
  its fields the settings a file may write, with units, bounds and choices);
* ``code``: its value in the kind column of the table of laws (``L_KIND``), unique among the
  kinds, or None for a kind that writes no row (``program``);
* ``law``: its compiled law (Numba), ``law(laws, mp, c, cs, b, y, p, ts) -> mode``, which the
  driver's sample calls for each of its rows, or None for a kind without rows;
* ``firmware``: its firmware twin (:class:`FirmwareTwin`), or None, written out, for a kind that
  does not run on the robot's board (``frogsim firmware`` then refuses a scenario using it);
* ``tracks``: what its setpoint is compared with in the results' tracking metrics, "pressure"
  (the muscle's, errors in bar) or "angle" (the joint's, errors in degrees), or None;
* ``metrics``: the keys its entry in ``control_metrics()`` carries beyond the ones every
  closed-loop controller has (switchings, air used);
* ``gains``: its settings a search may tune, each with a default search range (:class:`Gain`).

The engines also read the controller's ``setpoint`` (declared by the settings base class: None
for a kind that tracks nothing).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable

#: the tracking metrics of a kind that tracks a muscle's pressure, and of one that tracks an angle
PRESSURE_TRACKING = ("tracking_error_rms_bar", "tracking_error_max_bar")
ANGLE_TRACKING = ("tracking_error_rms_deg", "tracking_error_max_deg")
TRACKS = ("pressure", "angle")


@dataclass(frozen=True)
class Gain:
    """One setting of a kind that a search may tune (a ``frogsim tune``, an Optuna study): the
    settings field ``name`` (its variable path is ``controllers.NAME.<name>``), and its default
    search range ``low``..``high`` written in ``unit`` (a unit of the field's quantity, e.g.
    "bar", "ms", "bar/rad"), searched on a log scale when ``log``. :meth:`bounds` gives the range
    in SI, as :meth:`frogsim.scenario.core.Scenario.replace` takes values."""
    name: str
    unit: str
    low: float
    high: float
    log: bool = False

    def path(self, controller: str) -> str:
        """The variable path of this gain on the scenario's controller ``controller``."""
        return f"controllers.{controller}.{self.name}"

    def bounds(self, settings: type) -> tuple[float, float]:
        """(low, high) in SI, through the unit parser and the quantity kind of ``settings``' field."""
        from frogsim.scenario.units import to_si
        kind = _field_kind(settings, self.name)
        return (to_si(f"{self.low!r} {self.unit}".strip(), kind, f"{settings.KIND}.gains.{self.name}.low"),
                to_si(f"{self.high!r} {self.unit}".strip(), kind, f"{settings.KIND}.gains.{self.name}.high"))


@dataclass(frozen=True)
class FirmwareTwin:
    """A kind's firmware twin: its law in integer arithmetic on ADC counts, twice.

    ``fw_law(P, T, mem, k, cp, ca) -> mode`` (Numba: what the model runs with ``[firmware]``),
    ``c_name`` and ``c_source()`` (the same law in C99 for the board, stdint only), ``sine``
    (True when the C calls the sine generator, whose table is then linked), and ``report``: an
    optional compiled ``report(cs, b, mem)`` that copies what the results read from the twin's
    memory into the row's block of ``cs`` after each firmware sample (the joint-angle kind: its
    count of clipped targets)."""
    fw_law: Callable
    c_name: str
    c_source: Callable[[], str]
    sine: bool = False
    report: Callable | None = None


@dataclass(frozen=True, kw_only=True)
class ControllerKind:
    """A controller kind's declaration (module docstring). Every field but ``gains`` and
    ``module`` is written out by the kind's module, None included: a kind without a firmware
    twin says ``firmware=None``."""
    settings: type
    code: float | None
    law: Callable | None
    firmware: FirmwareTwin | None
    tracks: str | None
    metrics: tuple = ()
    gains: tuple = ()
    module: str = field(default="", compare=False)      # set by the registry: the module declaring it

    @property
    def name(self) -> str:
        """The kind's name in files (its settings class's ``KIND``)."""
        return self.settings.KIND

    def registered(self, module: str) -> "ControllerKind":
        return dataclasses.replace(self, module=module)


def _field_kind(settings: type, name: str) -> str:
    """The quantity kind ("pressure", "time", ...) of ``settings``' field ``name``; ValueError if
    the field is not a quantity."""
    for f in dataclasses.fields(settings):
        if f.name == name:
            kind = f.metadata.get("kind")
            if kind:
                return kind
            break
    raise ValueError(f"{settings.KIND}: gain {name!r} is not a quantity setting of the kind "
                     f"({', '.join(sorted(settings.settings()))})")
