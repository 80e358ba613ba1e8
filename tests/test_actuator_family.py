"""The actuator family: actuator types one module each, found through their registry; the McKibben
muscle its first member (the same numbers as Eq. (5), its slope, the braid's mantle and the
DMSP-20 force law called directly); an unknown type name or code refused; and a new actuator type
is one new module, nothing else edited."""
from __future__ import annotations

import json

import numpy as np
import pytest

import frogsim
from frogsim.errors import ScenarioError
from tests.package_copy import package_copy, run_copy as _run_copy


def test_the_registry_holds_the_mckibben_type_and_the_loader_its_settings():
    from frogsim.circuit import actuators
    from frogsim.scenario import actuators as loader
    from frogsim.scenario.schema import MuscleType
    assert "mckibben" in actuators.TYPES and loader.DEFAULT == "mckibben"
    assert actuators.TYPES["mckibben"].settings is MuscleType is loader.TYPES["mckibben"]
    codes = [a.code for a in actuators.TYPES.values()]
    assert len(codes) == len(set(codes))


def test_an_unknown_actuator_type_is_refused_naming_the_field_and_the_types():
    with pytest.raises(ScenarioError, match=r"muscle_types\.hip\.actuator = 'bellows': must be one of 'mckibben'"):
        frogsim.load_scenario({"name": "x", "duration": "0.1 s", "muscle_types": {"hip": {"actuator": "bellows"}},
                               "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}}})


def test_the_mckibben_entries_are_the_physics_functions_bit_for_bit():
    """Volume, slope, wall area and force of the family's McKibben member are Eq. (5), its
    derivative, the braid's mantle and the DMSP-20 law called with the braid's b0 and n."""
    from frogsim.circuit import actuators
    from frogsim.circuit import layout as L
    from frogsim.circuit.actuators import mckibben
    from frogsim.physics.heat import muscle_wall_area
    from frogsim.physics.muscle import braid_parameters, muscle_volume, muscle_volume_slope
    from frogsim.physics.muscle_force import MODEL_DMSP20, muscle_force
    from frogsim.robot.params import parameter_set_law
    sc = frogsim.load_scenario("paper-cycle")
    m = frogsim.build_model(sc)
    mt = sc.muscle_types[sc.muscles[m.names[0]].type]
    b0, n = braid_parameters(mt.nominal_length, mt.inner_diameter, mt.braid_angle)
    assert m.mp[0, L.M_ACT] == mckibben.CODE
    assert (m.mp[0, L.M_AP + mckibben.P_B0], m.mp[0, L.M_AP + mckibben.P_N]) == (b0, n)
    law = parameter_set_law(sc)
    block = np.array(actuators.force_block([mt], law))
    bl = (law.force_scale, law.strain_scale, law.stiffness, law.stretch_stiffness, law.stretch_quadratic)
    at = actuators.TYPES["mckibben"]
    for x in np.linspace(0.7, 1.05, 15) * mt.nominal_length:
        assert actuators.volume(m.mp, 0, x) == muscle_volume(x, b0, n)
        assert actuators.for_python(at.slope)(m.mp, 0, x) == muscle_volume_slope(x, b0, n)
        assert actuators.for_python(at.wall_area)(m.mp, 0, x) == muscle_wall_area(x, b0, n)
        assert actuators.force(m.mp, 0, 4e5, x, block) == muscle_force(MODEL_DMSP20, 4e5, x, mt.nominal_length, b0,
                                                                       n, *bl)


def test_an_unknown_actuator_code_stops_the_run():
    """A muscle row whose actuator code no type declares: refused before the run (naming the code)
    and by the driver's compiled start, which every engine's run passes (no silent default)."""
    from frogsim.circuit import layout as L
    from frogsim.engine.integrator import begin
    m = frogsim.build_model(frogsim.load_scenario("paper-cycle"))
    m.mp[0, L.M_ACT] = 9.0
    with pytest.raises(KeyError, match="actuator types: code 9.0 is no type's"):
        frogsim.simulate(m)
    with pytest.raises(ValueError, match="actuator code is no actuator type's"):
        begin(m.y0.copy(), 0.0, m.u0.copy(), m.mp, m.laws, m.sched_t, m.sched_u, 1e-3, m.out_t, 1e-4)


ACTUATOR_MODULE = '''
"""A throw-away actuator type: a bellows of constant effective area A (V = A L, F = p A)."""
import math
from dataclasses import dataclass
from typing import ClassVar

from frogsim._jit import jit_inner
from frogsim.circuit.actuators.spec import ActuatorType
from frogsim.circuit.layout import M_AP
from frogsim.scenario.fields import quantity
from frogsim.scenario.schema import MuscleType

CODE = {code}


@dataclass(frozen=True)
class Bellows(MuscleType):
    TYPE: ClassVar[str] = "bellows"
    effective_area: float = quantity("area", gt=0.0, display="cm^2", default=5e-4)

    def volume(self, L):
        return self.effective_area * L


def block(s):
    return (s.effective_area,)


def force_block(law):
    return ()


@jit_inner
def volume(mp, i, L):
    return mp[i, M_AP] * L


@jit_inner
def slope(mp, i, L):
    return mp[i, M_AP]


@jit_inner
def wall_area(mp, i, L):
    return 2.0 * math.sqrt(math.pi * mp[i, M_AP]) * L


@jit_inner
def force(mp, i, p_gauge, L, law, at):
    return max(p_gauge, 0.0) * mp[i, M_AP]


ACTUATOR = ActuatorType(settings=Bellows, code=CODE, block=block, volume=volume, slope=slope,
                        wall_area=wall_area, force=force, force_block=force_block)
'''

ACTUATOR_RUN = r'''
import json
import frogsim
d = {"name": "bellows", "duration": "0.5 s", "output_interval": "1 ms", "supply": {"mode": "none"},
     "muscle_types": {"hip": {"actuator": "bellows", "effective_area": "8 cm^2"}},
     "programs": {"up": {"pressurise": "1 s", "release": "1 s"}},
     "muscles": {"hip": {"type": "hip", "program": "up", "motion": {"kind": "constant"}}}}
sc = frogsim.load_scenario(d)
r = frogsim.simulate(sc)
mt = sc.muscle_types["hip"]
print(json.dumps({"V0": float(r.volumes[0, 0]), "L0": float(r.lengths[0, 0]), "dead": mt.dead_volume,
                  "p_end": float(r.muscle_pressure("hip")[-1]), "ps_end": float(r.source_pressure[-1]),
                  "T_end": float(r.tensions()[-1, 0]), "patm": r.atmospheric_pressure}))
'''


def _actuator_copy(root, modules: dict):
    """A copy of the package under root/src with ``modules`` ({file name: text}) added to
    circuit/actuators/ (:func:`tests.package_copy.package_copy`). Returns root/src."""
    return package_copy(root, {f"circuit/actuators/{name}": text for name, text in modules.items()})


def test_a_duplicate_actuator_code_is_refused_naming_both_modules(tmp_path):
    src = _actuator_copy(tmp_path, {"bellows.py": ACTUATOR_MODULE.format(code=1.0)})
    done = _run_copy(src, "-c", "import frogsim", cwd=tmp_path)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: actuator types: "), done.stderr[-2000:]
    assert "CODE 1.0 of frogsim.circuit.actuators.mckibben (type 'mckibben') is already taken by " \
           "frogsim.circuit.actuators.bellows" in last, last
