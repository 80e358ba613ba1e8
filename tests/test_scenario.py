"""Scenario loading: units in, SI out; gauge made explicit; every parameter value has a source."""
import tomllib
from pathlib import Path

import pytest

import frogsim
from frogsim.errors import ScenarioError

PARAMS = Path(frogsim.__file__).parent / "params" / "fan2017.toml"


def test_units_parsed_to_si():
    sc = frogsim.load_scenario("paper-cycle")
    assert sc.source.volume == pytest.approx(4e-3)                      # "4 L"
    assert sc.source.initial_pressure_gauge == pytest.approx(6e5)       # "6 bar" gauge
    assert sc.valves.charge.sonic_conductance == pytest.approx(4e-9)    # 0.4 L/(s bar) in m^3/(s Pa)
    assert sc.muscle_types["hip"].nominal_length == pytest.approx(0.18)
    assert sc.controller.rate == pytest.approx(1000.0)


def test_every_parameter_value_has_a_source():
    raw = tomllib.loads(PARAMS.read_text())
    raw.pop("meta")

    def leaves(node, path=""):
        for k, v in node.items():
            p = f"{path}.{k}" if path else k
            if isinstance(v, dict) and "value" not in v:
                yield from leaves(v, p)
            else:
                yield p, v
    for path, v in leaves(raw):
        assert isinstance(v, dict) and v.get("source"), f"{path} has no source"


def test_overrides_by_dotted_path():
    raw = frogsim.load_scenario("paper-cycle").raw
    sc = frogsim.load_scenario(frogsim.with_overrides(raw, {"source.volume": "8 L"}))
    assert sc.source.volume == pytest.approx(8e-3)
    with pytest.raises(ScenarioError, match="source.volume"):
        frogsim.load_scenario(frogsim.with_overrides(raw, {"source.volume": "0 L"}))


def test_unknown_muscle_type_and_program():
    raw = frogsim.load_scenario("paper-cycle").raw
    with pytest.raises(ScenarioError, match="muscles.hip_left.type"):
        frogsim.load_scenario(frogsim.with_overrides(raw, {"muscles.hip_left.type": "elbow"}))
    with pytest.raises(ScenarioError, match="muscles.hip_left.program"):
        frogsim.load_scenario(frogsim.with_overrides(raw, {"muscles.hip_left.program": "nope"}))


def test_stroke_longer_than_program_is_refused():
    raw = frogsim.load_scenario("paper-cycle").raw
    with pytest.raises(ScenarioError, match="motion"):
        frogsim.load_scenario(frogsim.with_overrides(raw, {"muscles.hip_left.motion.rise": "1.5 s"}))


def test_joint_angle_csv_through_crank(tmp_path):
    # a crank of radius r turned by dtheta shortens the muscle by ~ r dtheta for small angles
    # (crank perpendicular at rest); 0.2 rad on a 30 mm crank: 6 mm of 180 mm = 3.3 % contraction
    csv = tmp_path / "angles.csv"
    csv.write_text("time_s,hip_deg\n0,0\n0.1,0\n0.4,11.459\n2,11.459\n")
    raw = frogsim.load_scenario("paper-cycle").raw
    raw = frogsim.with_overrides(raw, {"muscles.hip_left.motion": {"kind": "joint_angles", "file": str(csv),
                                                                   "column": "hip_deg"}})
    r = frogsim.simulate(frogsim.load_scenario(raw))
    Lh = r.lengths[:, r.index("hip_left")]
    assert Lh[0] == pytest.approx(0.18)
    assert 0.18 - Lh[-1] == pytest.approx(0.030 * 0.2, rel=0.03)


def test_joint_angles_beyond_limit_refused(tmp_path):
    csv = tmp_path / "angles.csv"
    # law of cosines, anchor d = 250 mm, crank r = 60 mm: at rest s0 = sqrt(d^2 + r^2) = 257.1 mm;
    # turned 120 deg the crank angle is -30 deg, s = sqrt(d^2 + r^2 - 2 d r cos 30) = 200.3 mm:
    # 56.8 mm shorter = 31.6 % of the 180 mm hip muscle, beyond its 25 % limit
    csv.write_text("time_s,hip_deg\n0,0\n1,120\n")
    raw = frogsim.load_scenario("paper-cycle").raw
    raw = frogsim.with_overrides(raw, {"muscle_types.hip.crank_radius": "60 mm",
                                       "muscles.hip_left.motion": {"kind": "joint_angles", "file": str(csv),
                                                                   "column": "hip_deg"}})
    with pytest.raises(ScenarioError, match="max_contraction"):
        frogsim.load_scenario(raw)


def test_override_creates_optional_table_but_not_through_a_value():
    raw = frogsim.load_scenario({"name": "x", "duration": "1 s",
                                 "programs": {"s": {"pressurise": "0.5 s", "release": "0.5 s"}},
                                 "muscles": {"hip": {"type": "hip", "program": "s"}}}).raw
    assert "solver" not in raw
    sc = frogsim.load_scenario(frogsim.with_overrides(raw, {"solver.rtol": "1e-9"}))
    assert sc.solver.rtol == pytest.approx(1e-9)
    with pytest.raises(ScenarioError, match="duration"):
        frogsim.with_overrides(raw, {"duration.value": "2 s"})


def test_unit_registry_survives_a_broken_disk_cache(tmp_path, monkeypatch):
    """pint's disk cache is written without locking; a broken one (two first runs at once, a
    killed process) gives a registry built without it, and is removed for the next run."""
    from frogsim.scenario import units
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    units.registry.cache_clear()
    try:
        assert units.registry().cache_folder is not None         # the cache is written
        broken = list(tmp_path.rglob("*.pickle"))
        assert broken
        for f in broken:
            f.write_bytes(b"not a pickle")
        units.registry.cache_clear()
        reg = units.registry()
        assert reg.cache_folder is None
        assert reg.Quantity("6 bar").to("Pa").magnitude == pytest.approx(6e5, rel=1e-15)
        assert not list(tmp_path.rglob("*.pickle"))                # removed: the next run writes it anew
        units.registry.cache_clear()
        assert units.registry().cache_folder is not None
    finally:
        units.registry.cache_clear()
