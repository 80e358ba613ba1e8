"""Valve catalogue: the numbers behind the valve family's defaults and the valve-type design study.

Each entry is a :class:`Part` value with its ``source``: a document that states it, or "chosen:"
and the reason where no source stating it was at hand. Nothing here is a measurement of ours.

* The paper's switching valve, FESTO MHJ9-LF (paper Sec. 3.3: C = 0.4 L/(s bar), b = 0.38); its
  dead time and the circuit's other valve settings are the parameter set's (params/fan2017.toml).
* A 5/3-way proportional directional valve of the FESTO MPYE-5-1/8-HF class (the valve common in
  McKibben control work): one spool meters both the charge edge (supply to the muscle) and the
  vent edge (the muscle to exhaust), its position set by a 0-10 V command (5 V: centre, shut).
"""
from __future__ import annotations

from dataclasses import dataclass

BAR = 1e5
L_PER_MIN = 1e-3 / 60.0


@dataclass(frozen=True)
class Part:
    """One catalogue value: SI ``value`` with its ``unit`` as written here and its ``source``."""
    value: float
    unit: str
    source: str


#: the paper's switching valve (one per charge path and one per vent path of each muscle)
MHJ9 = {
    "sonic_conductance": Part(0.4e-3 / BAR, "m^3/(s Pa)", "paper Sec. 3.3: FESTO MHJ9-LF, C = 0.4 L/(s bar)"),
    "critical_ratio": Part(0.38, "-", "paper Sec. 3.3: b = 0.38"),
    "valves_per_muscle": Part(2.0, "-", "paper Fig. 6: a charge valve and a discharge valve per muscle"),
    "mass": Part(0.020, "kg", "chosen: a miniature high-speed solenoid valve of the MHJ9 size class "
                              "(about 10 mm wide); no datasheet mass was at hand"),
    "price": Part(60.0, "EUR", "chosen: order of magnitude of a miniature high-speed solenoid valve; "
                               "no price source was at hand"),
}

#: the proportional directional valve, MPYE-5-1/8-HF class (one per muscle)
MPYE_5_1_8_HF = {
    "nominal_flow": Part(700.0 * L_PER_MIN, "m^3/s (ANR)",
                         "FESTO MPYE-5-1/8-HF: standard nominal flow rate 700 L/min (the type's catalogue "
                         "figure, q_nN at 6 bar gauge inlet and 1 bar drop); read from no datasheet here"),
    "nominal_inlet_gauge": Part(6.0 * BAR, "Pa gauge", "ISO 6358 / FESTO nominal flow conditions: 6 bar inlet"),
    "nominal_drop": Part(1.0 * BAR, "Pa", "ISO 6358 / FESTO nominal flow conditions: 1 bar pressure drop"),
    "critical_ratio": Part(0.3, "-", "chosen: no datasheet b was at hand; 0.3 is typical of spool valves "
                                     "(below the 0.38 of the paper's poppet valve)"),
    "bandwidth": Part(100.0, "Hz", "chosen: the order of the MPYE series' critical frequency (about 100 Hz "
                                   "and more); no datasheet value was at hand"),
    "overlap": Part(0.0, "-", "chosen: a critical-centre spool (zero overlap); the datasheet's was not at hand"),
    "leakage_conductance": Part(0.0, "m^3/(s Pa)", "chosen: no leakage (no datasheet figure at hand)"),
    "signal_center": Part(5.0, "V", "FESTO MPYE: 0-10 V setpoint input, 5 V the mid (shut) position"),
    "signal_span": Part(5.0, "V", "FESTO MPYE: 0-10 V setpoint input, 0 V and 10 V the two ends of travel"),
    "valves_per_muscle": Part(1.0, "-", "a 5/3-way valve meters both the charge and the vent edge"),
    "mass": Part(0.30, "kg", "chosen: order of magnitude of a 1/8 inch proportional valve with integrated "
                             "electronics; no datasheet mass was at hand"),
    "price": Part(600.0, "EUR", "chosen: order of magnitude of a proportional directional valve with "
                                "integrated electronics; no price source was at hand"),
}


def value(part_table: dict, name: str) -> float:
    """The SI value of ``name`` in a catalogue table."""
    return part_table[name].value
