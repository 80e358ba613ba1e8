"""Unit parsing at the boundary (pint). Everything returned is an SI float."""
from __future__ import annotations

import functools
import re

import pint

from frogsim._files import user_cache_folder
from frogsim.errors import ScenarioError


@functools.lru_cache(maxsize=1)
def registry() -> pint.UnitRegistry:
    """The shared pint registry, built once per process.

    Built from pint's definitions file it takes about 0.2 s; pint can keep the parsed file in a
    disk cache (``cache_folder``, checked against the file's content), which cuts that to about
    0.03 s, for every command and every worker process. The cache lives in frogsim's user cache
    folder. pint writes it without locking, so a process that reads it while another writes it
    (two first runs at once) may find it unreadable: then the registry is built without the
    cache, and the broken cache is removed so that the next run writes it anew.
    """
    folder = user_cache_folder("pint", pint.__version__)
    if folder is not None:
        try:
            return pint.UnitRegistry(cache_folder=folder)
        except Exception:           # an unreadable or unwritable cache: build without it
            import shutil
            shutil.rmtree(folder, ignore_errors=True)
    return pint.UnitRegistry()


# SI unit for every kind of quantity a scenario may hold, with a readable name for messages
SI_UNITS = {
    "pressure": ("Pa", "a pressure such as \"6 bar\" or \"600 kPa\""),
    "volume": ("m**3", "a volume such as \"4 L\" or \"50 cm^3\""),
    "length": ("m", "a length such as \"4 mm\""),
    "time": ("s", "a time such as \"1 s\" or \"2 ms\""),
    "frequency": ("Hz", "a frequency such as \"1 kHz\""),
    "temperature": ("K", "an absolute temperature such as \"293.15 K\", \"20 degC\" or \"68 degF\""),
    "temperature_difference": ("K", "a temperature difference such as \"1 K\", \"500 mK\" or \"2 delta_degC\""),
    "angle": ("rad", "an angle such as \"25 deg\""),
    "velocity": ("m/s", "a velocity such as \"343 m/s\""),
    "volume_flow": ("m**3/s", "a volume flow such as \"45 L/min\""),
    "conductance": ("m**3/(s*Pa)", "a sonic conductance such as \"0.4 L/(s*bar)\""),
    "gas_constant": ("J/(kg*K)", "a specific gas constant such as \"287 J/(kg*K)\""),
    "voltage": ("V", "a voltage such as \"4.5 V\""),
    "heat_transfer_coefficient": ("W/(m**2*K)", "a heat transfer coefficient such as \"20 W/(m^2*K)\""),
    "dimensionless": ("", "a plain number or a percentage such as \"25 %\""),
    "mass": ("kg", "a mass such as \"12 kg\""),
    "area": ("m**2", "an area such as \"0.0335 m^2\""),
    "density": ("kg/m**3", "a density such as \"998.2 kg/m^3\""),
    "acceleration": ("m/s**2", "an acceleration such as \"9.81 m/s^2\""),
    "force": ("N", "a force such as \"30 N\""),
    "stiffness": ("N/m", "a spring stiffness such as \"3000 N/m\""),
    "torque": ("N*m", "a torque such as \"0.2 N*m\""),
    "rotational_damping": ("N*m*s", "a rotational damping such as \"0.02 N*m*s\" (per radian)"),
    "rotational_stiffness": ("N*m/rad", "a rotational stiffness such as \"3800 N*m/rad\""),
    "pressure_per_angle": ("Pa/rad", "a gain such as \"10 bar/rad\""),
    "pressure_time_per_angle": ("Pa*s/rad", "a gain such as \"0.2 bar*s/rad\""),
    "pressure_per_angle_time": ("Pa/(rad*s)", "a gain such as \"20 bar/(rad*s)\""),
    "voltage_per_pressure": ("V/Pa", "a gain such as \"2 V/bar\""),
    "voltage_per_pressure_time": ("V/(Pa*s)", "a gain such as \"20 V/(bar*s)\""),
    "voltage_time_per_pressure": ("V*s/Pa", "a gain such as \"0.01 V*s/bar\""),
}


class AngleMismatch(ValueError):
    """A unit whose angle does not match its kind's ("30 bar" for a gain in bar/rad)."""


def angle_power(units) -> int:
    """The power of the angle in a pint unit ("bar/rad" -> -1, "deg" -> 1, "bar" -> 0).

    pint counts the radian as dimensionless, so "30 bar" converts to bar/rad without a word; the
    angle's power is read from the units as written (each unit's root units) instead."""
    ureg = registry()
    power = 0
    for name, exponent in units.items():
        _, root = ureg.get_root_units(name)
        power += exponent * dict(root._units).get("radian", 0)
    return power


@functools.lru_cache(maxsize=None)
def _kind_angle_power(kind: str) -> int:
    unit, _ = SI_UNITS[kind]
    return angle_power(registry().Unit(unit)._units) if unit else 0


class TemperatureDifference(ValueError):
    """A temperature-difference unit (delta_degC, delta_degF) where a temperature is meant."""


class AbsoluteTemperature(ValueError):
    """An offset temperature unit (degC, degF) where a temperature difference is meant."""


_NUMBER = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def _absolute_temperature(text: str) -> float:
    """An absolute temperature in K from "293.15 K", "20 degC" or "68 degF" (T = scale x + offset:
    pint refuses "20 degC" as a product of a number and an offset unit). A difference unit
    (delta_degC) raises :class:`TemperatureDifference`; a text that is not a number and a
    temperature unit, ValueError."""
    m = _NUMBER.fullmatch(text)
    if not m or not m.group(2):
        raise ValueError(text)
    scale, offset = temperature_scale_offset(m.group(2))
    kelvin = scale * float(m.group(1)) + offset
    # an offset unit's sum rounds ("-123.15 degC" gives 149.99999999999997 K): kept to 1e-9 K
    return round(kelvin, 9) if offset else kelvin


def _is_offset(units) -> bool:
    ureg = registry()
    return any(not ureg._units[ureg.get_name(name)].is_multiplicative for name in units)


@functools.lru_cache(maxsize=4096)
def parse_quantity(text: str, kind: str) -> float:
    """Parse text such as "6 bar" into an SI float of the given kind; raise ValueError if not.

    Units are checked by dimension, the angle counted as one (see :func:`angle_power`): a gain
    in bar/rad refuses "30 bar", an angle refuses a plain "25", a percentage refuses "0.3 rad".
    A "temperature" is absolute: K, degC or degF, never a difference unit (delta_degC raises
    :class:`TemperatureDifference`); a "temperature_difference" is K, mK or delta_degC, never an
    offset unit (degC raises :class:`AbsoluteTemperature`)."""
    if kind == "temperature":
        return _absolute_temperature(text)
    unit, _ = SI_UNITS[kind]
    if kind == "temperature_difference":
        m = _NUMBER.fullmatch(text)
        if m and m.group(2) and _is_offset(registry().Unit(m.group(2))._units):
            raise AbsoluteTemperature(text)
    q = registry().Quantity(text)
    if angle_power(q._units) != _kind_angle_power(kind):
        raise AngleMismatch(text)
    if kind == "dimensionless":
        return float(q.to("dimensionless").magnitude)
    return float(q.to(unit).magnitude)


MAX_TEXT = 100     # characters of a quantity's text ("0.4 L/(s*bar)" has 13)
# a power must raise a unit name (a letter before it) to a small whole exponent: "m^3", "s**-2";
# pint would otherwise evaluate "10**10**10" exactly, which never ends
_POWER = re.compile(r"(\*\*|\^)")
_SMALL_EXPONENT = re.compile(r"\s*[-+]?\s*\d{1,2}(?![\d.eE])\s*(?!\*\*|\^)")


def text_problem(text: str) -> str:
    """Why a quantity's text is refused before pint sees it ("" if it may be parsed)."""
    if len(text) > MAX_TEXT:
        return f"longer than {MAX_TEXT} characters"
    lowered = text.lower()
    if lowered.count("%") + lowered.count("percent") > 1:
        return "a percentage is written once, e.g. \"38 %\""
    for m in _POWER.finditer(text):
        before = text[:m.start()].rstrip()
        if before.endswith(")"):            # "(m/s)^2": a group of unit names, no numbers in it
            opened = before.rfind("(")
            if opened >= 0 and not any(c.isdigit() for c in before[opened:]):
                before = before[:opened] + "u"
        if not before or not (before[-1].isalpha() or before[-1] == "_"):
            return "a power applies to a unit name only, e.g. \"m^3\" (write numbers as 1e5)"
        if not _SMALL_EXPONENT.match(text, m.end()):
            return "a unit's power must be a whole number of one or two digits, e.g. \"m^3\""
    return ""


def to_si(value, kind: str, field: str) -> float:
    """Turn a scenario value into SI, or raise ScenarioError naming the field."""
    unit, what = SI_UNITS[kind]
    if isinstance(value, bool):
        raise ScenarioError(field, value, f"expected {what}")
    if isinstance(value, (int, float)):
        if kind == "dimensionless":
            return float(value)
        raise ScenarioError(field, value, f"expected {what}: write the unit out")
    if not isinstance(value, str):
        raise ScenarioError(field, value, f"expected {what}")
    problem = text_problem(value)
    if problem:
        raise ScenarioError(field, value, f"expected {what}: {problem}")
    try:
        return parse_quantity(value.strip(), kind)
    except TemperatureDifference:
        raise ScenarioError(field, value, f"expected {what}: {value.strip()!r} is a temperature difference "
                                          "(delta_degC, delta_degF), not a temperature") from None
    except AbsoluteTemperature:
        raise ScenarioError(field, value, f"expected {what}: degC and degF are absolute temperatures "
                                          "(20 degC is 293.15 K); write a difference in K or delta_degC") from None
    except AngleMismatch:
        expected = _kind_angle_power(kind)
        need = {0: "must not hold an angle", 1: "must be an angle (rad, deg)",
                -1: "must be per angle (per rad or per deg)"}.get(expected, f"must hold angle^{expected}")
        raise ScenarioError(field, value, f"expected {what}: the unit {need}") from None
    except Exception:  # pint raises several error types for bad text or dimensions
        raise ScenarioError(field, value, f"expected {what}") from None


@functools.lru_cache(maxsize=256)
def display_factor(unit: str, kind: str) -> float:
    """Size of one display unit in SI ("bar", "pressure" -> 1e5); "" -> 1."""
    return parse_quantity(f"1 {unit}", kind) if unit else 1.0


@functools.lru_cache(maxsize=256)
def temperature_scale_offset(unit: str) -> tuple[float, float]:
    """(scale, offset) with T [K] = scale * x + offset for a reading x in ``unit``.

    degC and degF are offset units: 20 degC is 293.15 K, not 20 K (scale 1, offset 273.15; degF
    scale 5/9, offset 255.372). A difference unit (delta_degC, delta_degF) is refused with
    :class:`TemperatureDifference`; any other unit that is not a temperature, with ValueError
    (or pint's own error)."""
    ureg = registry()
    u = ureg.Unit(unit)
    if any(name.startswith("delta_") for name in u._units):
        raise TemperatureDifference(unit)
    offset = float(ureg.Quantity(0.0, u).to("K").magnitude)
    scale = float(ureg.Quantity(1.0, u).to("K").magnitude) - offset
    if not scale > 0:
        raise ValueError(unit)
    return scale, offset
