"""The package's layers hold: no module imports one of a higher layer, and no import cycles.

The order is the one of DESIGN.md (lowest first). Imports are read from the source (module level,
inside functions alike; ``if TYPE_CHECKING:`` blocks, which never run, are left out). A test plants
an upward import in a copy of the package and checks the checker catches it.
"""
from __future__ import annotations

import ast
import functools
import shutil
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "frogsim"

#: lowest first; a module may import its own layer and those before it
LAYERS = (
    ("errors", "_jit", "_registry", "_parallel", "_plotting", "_files", "_budget", "_words"),
    ("physics",),
    ("components",),
    ("scenario",),
    ("circuit",),
    ("control",),
    ("robot",),
    ("engine",),
    ("envs",),
    ("sweep",),
    ("fit",),
    ("optimize",),
    ("export",),
    ("io",),
    ("studies",),
    ("cli", "__init__", "__main__"),
)
RANK = {name: k for k, names in enumerate(LAYERS) for name in names}
PINT_ALLOWED = {"frogsim.scenario.units"}


def _module_name(path: Path, root: Path) -> str:
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__" and len(parts) > 1:
        parts = parts[:-1] if len(parts) > 2 else parts
    return ".".join(parts)


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _type_checking(node) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports(root: Path = PACKAGE) -> dict[str, set[str]]:
    """module -> the modules (frogsim.* or third-party top names) it imports."""
    paths = sorted(root.rglob("*.py"))
    files = frozenset(path.relative_to(root).as_posix() for path in paths)
    return {_module_name(path, root): set(_module_imports(path.read_text(), str(path.relative_to(root)), files))
            for path in paths}


@functools.lru_cache(maxsize=None)
def _module_imports(text: str, name: str, files: frozenset) -> frozenset:
    """What one module's text imports (``files``: the tree's modules, to tell ``from frogsim.x import
    y`` of a module y from that of a name): a module read again unchanged, in the package or a copy
    of it, is not parsed again."""
    tree = ast.parse(text, name)
    found = set()

    def visit(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                for sub in child.orelse:
                    visit(sub)
                continue
            if isinstance(child, ast.Import):
                found.update(a.name for a in child.names)
            elif isinstance(child, ast.ImportFrom) and child.module and child.level == 0:
                found.add(child.module)
                found.update(f"{child.module}.{a.name}" for a in child.names
                             if "/".join([*child.module.split(".")[1:], f"{a.name}.py"]) in files)
            visit(child)
    visit(tree)
    return frozenset(found)


def upward_imports(root: Path = PACKAGE) -> list[str]:
    bad = []
    for mod, deps in _imports_of(root).items():
        here = RANK[_layer(mod)]
        for dep in deps:
            if dep.split(".")[0] != "frogsim" or dep == "frogsim":
                continue
            there = RANK.get(_layer(dep))
            if there is None or there > here:
                bad.append(f"{mod} imports {dep}")
    return sorted(bad)


def cycles(root: Path = PACKAGE) -> list[list[str]]:
    """Import cycles among the package's modules (strongly connected components of size > 1)."""
    graph = {m: {d for d in deps if d in imports_cache(root)} for m, deps in imports_cache(root).items()}
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    for v in graph:
        if v not in index:
            strong(v)
    return out


_CACHE: dict = {}


def imports_cache(root: Path) -> dict:
    if root not in _CACHE:
        _CACHE[root] = imports(root)
    return _CACHE[root]


def _imports_of(root: Path) -> dict:
    """A tree's imports, read once for this file (the package's tests all read the same tree; a
    planted copy is read once all its plants are in)."""
    return imports_cache(root)


def test_every_module_has_a_layer():
    unknown = sorted({_layer(m) for m in _imports_of(PACKAGE)} - set(RANK))
    assert not unknown, f"modules outside the layer list (add them to LAYERS and DESIGN.md): {unknown}"


def test_no_upward_imports():
    assert upward_imports() == []


def test_no_import_cycles():
    assert cycles(PACKAGE) == []


def test_only_the_units_module_imports_pint():
    users = sorted(m for m, deps in _imports_of(PACKAGE).items() if any(d.split(".")[0] == "pint" for d in deps))
    assert set(users) <= PINT_ALLOWED, users


def test_a_planted_upward_import_is_caught(tmp_path):
    """Three plants in one copy of the package, read once: an upward import, pint outside the units
    module, and a cycle (two modules of one layer importing each other); each check finds its own
    and only the upward import is upward."""
    copy = tmp_path / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    target = copy / "physics" / "gas.py"
    target.write_text(target.read_text() + "\n\ndef _planted():\n    from frogsim.studies import paper\n")
    (copy / "physics" / "flow.py").write_text((copy / "physics" / "flow.py").read_text()
                                              + "\nimport pint\n")
    (copy / "physics" / "air.py").write_text((copy / "physics" / "air.py").read_text()
                                             + "\nfrom frogsim.physics import hydro\n")
    (copy / "physics" / "hydro.py").write_text((copy / "physics" / "hydro.py").read_text()
                                               + "\nfrom frogsim.physics import air\n")
    assert upward_imports(copy) == ["frogsim.physics.gas imports frogsim.studies",
                                    "frogsim.physics.gas imports frogsim.studies.paper"]
    assert "frogsim.physics.flow" in [m for m, d in _imports_of(copy).items() if "pint" in d]
    assert ["frogsim.physics.air", "frogsim.physics.hydro"] in cycles(copy)


#: modules outside control/kinds/ that import a kind's module by name, each with what it reads
#: there that no declaration holds; everything else reaches the kinds through their registry
#: (frogsim.control.kinds), so that a new kind is one new module
KIND_IMPORTS = {
    # the program table of the muscles without a closed-loop law; a joint's two laws sharing one
    # loop in the board's C (fs_joint_angle_pair)
    "frogsim.control.firmware": {"program", "joint_angle"},
    # the angle loop's schedule in the firmware's cycle estimate
    "frogsim.export.fit": {"joint_angle"},
}


def kind_imports(root: Path = PACKAGE) -> list[str]:
    """Imports of a kind's module from outside control/kinds/ that KIND_IMPORTS does not list."""
    folder = root / "control" / "kinds"
    found = {p.stem for p in folder.glob("*.py")}
    helpers = {"__init__", "spec", "common"}
    bad = []
    for mod, deps in imports(root).items():
        if mod.startswith("frogsim.control.kinds"):
            continue
        for dep in deps:
            parts = dep.split(".")
            if parts[:3] == ["frogsim", "control", "kinds"] and len(parts) > 3 and parts[3] in found - helpers \
                    and parts[3] not in KIND_IMPORTS.get(mod, ()):
                bad.append(f"{mod} imports {dep}")
    return sorted(bad)


def test_the_kinds_are_reached_through_their_registry(tmp_path):
    assert kind_imports() == []
    copy = tmp_path / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    target = copy / "control" / "sampled.py"
    target.write_text(target.read_text() + "\n\ndef _planted():\n    from frogsim.control.kinds import pwm\n")
    assert kind_imports(copy) == ["frogsim.control.sampled imports frogsim.control.kinds.pwm"]


#: modules outside circuit/valves/ that import a valve type's module by name, each with what it
#: reads there that no declaration holds: none; the engines, the laws and the studies reach the
#: valve types through their registry (frogsim.circuit.valves), so that a new valve type is one new
#: module
VALVE_IMPORTS: dict = {}


def valve_imports(root: Path = PACKAGE) -> list[str]:
    """Imports of a valve type's module from outside circuit/valves/ that VALVE_IMPORTS does not list."""
    folder = root / "circuit" / "valves"
    found = {p.stem for p in folder.glob("*.py")} - {"__init__", "spec"}
    bad = []
    for mod, deps in imports(root).items():
        if mod.startswith("frogsim.circuit.valves"):
            continue
        for dep in deps:
            parts = dep.split(".")
            if parts[:3] == ["frogsim", "circuit", "valves"] and len(parts) > 3 and parts[3] in found \
                    and parts[3] not in VALVE_IMPORTS.get(mod, ()):
                bad.append(f"{mod} imports {dep}")
    return sorted(bad)


#: modules outside engine/methods/ that import a method's module by name, each with what it
#: reads there that no declaration holds; everything else reaches the integration methods through
#: their registry (frogsim.engine.methods), so that a new method is one new module
METHOD_IMPORTS: dict = {}
#: what a method's module may import of the engine layer: the family's own helpers and the shared
#: step-size control (never the driver, which reads the methods through the registry)
METHOD_ENGINE_DEPS = {"frogsim.engine", "frogsim.engine.methods", "frogsim.engine.methods.spec",
                      "frogsim.engine.stepsize"}


def method_imports(root: Path = PACKAGE) -> list[str]:
    """Imports of a method's module from outside engine/methods/ that METHOD_IMPORTS does not
    list, and imports of the engine by a method's module beyond METHOD_ENGINE_DEPS."""
    folder = root / "engine" / "methods"
    found = {p.stem for p in folder.glob("*.py")}
    helpers = {"__init__", "spec"}
    bad = []
    for mod, deps in imports(root).items():
        inside = mod.startswith("frogsim.engine.methods")
        for dep in deps:
            parts = dep.split(".")
            if inside:
                if parts[:2] == ["frogsim", "engine"] and dep not in METHOD_ENGINE_DEPS \
                        and not dep.startswith("frogsim.engine.methods."):
                    bad.append(f"{mod} imports {dep}")
            elif parts[:3] == ["frogsim", "engine", "methods"] and len(parts) > 3 and parts[3] in found - helpers \
                    and parts[3] not in METHOD_IMPORTS.get(mod, ()):
                bad.append(f"{mod} imports {dep}")
    return sorted(bad)


def test_the_valve_types_are_reached_through_their_registry(tmp_path):
    """The valve family (circuit/valves/, layer 4) is read through its registry only; a planted
    import of one valve type's module from the right-hand side is caught."""
    assert (PACKAGE / "circuit" / "valves" / "__init__.py").exists()
    assert _layer("frogsim.circuit.valves.proportional") == "circuit"
    assert valve_imports() == []
    copy = tmp_path / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    target = copy / "circuit" / "rhs.py"
    target.write_text(target.read_text() + "\n\ndef _planted():\n    from frogsim.circuit.valves import proportional\n")
    assert valve_imports(copy) == ["frogsim.circuit.rhs imports frogsim.circuit.valves.proportional"]


def test_the_integration_methods_are_reached_through_their_registry(tmp_path):
    assert method_imports() == []
    copy = tmp_path / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    target = copy / "engine" / "integrator.py"
    target.write_text(target.read_text() + "\n\ndef _planted():\n    from frogsim.engine.methods import rk4\n")
    method = copy / "engine" / "methods" / "rk4.py"
    method.write_text(method.read_text() + "\n\ndef _planted():\n    from frogsim.engine import integrator\n")
    assert method_imports(copy) == ["frogsim.engine.integrator imports frogsim.engine.methods.rk4",
                                    "frogsim.engine.methods.rk4 imports frogsim.engine.integrator"]


#: modules outside circuit/actuators/ that import an actuator type's module by name: none; the
#: right-hand side, the coupled kernel, the results and the studies reach the actuator types through
#: their registry (frogsim.circuit.actuators), so that a new actuator type is one new module
ACTUATOR_IMPORTS: dict = {}


def actuator_imports(root: Path = PACKAGE) -> list[str]:
    """Imports of an actuator type's module from outside circuit/actuators/ that ACTUATOR_IMPORTS
    does not list."""
    folder = root / "circuit" / "actuators"
    found = {p.stem for p in folder.glob("*.py")} - {"__init__", "spec"}
    bad = []
    for mod, deps in imports(root).items():
        if mod.startswith("frogsim.circuit.actuators"):
            continue
        for dep in deps:
            parts = dep.split(".")
            if parts[:3] == ["frogsim", "circuit", "actuators"] and len(parts) > 3 and parts[3] in found \
                    and parts[3] not in ACTUATOR_IMPORTS.get(mod, ()):
                bad.append(f"{mod} imports {dep}")
    return sorted(bad)


def test_the_actuator_types_are_reached_through_their_registry(tmp_path):
    """The actuator family (circuit/actuators/, layer 4) is read through its registry only: no
    module outside it names the McKibben module or calls Eq. (5)'s volume directly in the
    engines; a planted import of the McKibben module from the coupled kernel is caught."""
    assert _layer("frogsim.circuit.actuators.mckibben") == "circuit"
    assert actuator_imports() == []
    for engine in ("circuit/rhs.py", "engine/coupled_kernel.py", "engine/coupled.py", "engine/pneumatic.py"):
        text = (PACKAGE / engine).read_text()
        assert "muscle_volume(" not in text and "muscle_force(" not in text, engine
    copy = tmp_path / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    target = copy / "engine" / "coupled_kernel.py"
    target.write_text(target.read_text() + "\n\ndef _planted():\n    from frogsim.circuit.actuators import mckibben\n")
    assert actuator_imports(copy) == ["frogsim.engine.coupled_kernel imports frogsim.circuit.actuators.mckibben"]


def sensor_imports(root: Path = PACKAGE) -> list[str]:
    """Imports of a sensor type's module from outside circuit/sensors/ (none is allowed: the
    firmware rows, the plan and the model's sample reach the sensors through their registry)."""
    folder = root / "circuit" / "sensors"
    found = {p.stem for p in folder.glob("*.py")} - {"__init__", "spec"}
    bad = []
    for mod, deps in imports(root).items():
        if mod.startswith("frogsim.circuit.sensors"):
            continue
        for dep in deps:
            parts = dep.split(".")
            if parts[:3] == ["frogsim", "circuit", "sensors"] and len(parts) > 3 and parts[3] in found:
                bad.append(f"{mod} imports {dep}")
    return sorted(bad)


def test_the_sensor_types_are_reached_through_their_registry(tmp_path):
    assert _layer("frogsim.circuit.sensors.encoder") == "circuit"
    assert sensor_imports() == []
    copy = tmp_path / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    target = copy / "control" / "fixed.py"
    target.write_text(target.read_text() + "\n\ndef _planted():\n    from frogsim.circuit.sensors import encoder\n")
    assert sensor_imports(copy) == ["frogsim.control.fixed imports frogsim.circuit.sensors.encoder"]
