"""The first run's compilation in parts: the parts cover the engine, the scheduler keeps their
order, and the engine's internal pieces (compiled for compiled callers only) refuse Python calls."""
from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import textwrap
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

import frogsim
from frogsim._jit import _CompiledCallersOnly
from test_compiled_counting import _dispatchers
from frogsim.engine import warmup

SRC = str(Path(frogsim.__file__).resolve().parent.parent)


def _step_pieces():
    """The package's dispatchers compiled for compiled callers only (read as the counting test
    reads every dispatcher)."""
    return {name: d for name, d in _dispatchers().items() if isinstance(d, _CompiledCallersOnly)}


def test_step_pieces_refuse_python_calls():
    pieces = _step_pieces()
    assert "frogsim.engine.methods.dopri_rosenbrock._dopri_step" in pieces and \
        "frogsim.circuit.rhs.manifold_pressure" in pieces
    for name, d in pieces.items():
        with pytest.raises(TypeError, match="compiled callers only"):
            d(0.0)
        assert d.targetoptions["no_cpython_wrapper"] and not d.targetoptions["_nrt"], name


def test_step_pieces_are_referenced_by_compiled_code_only():
    """Read every module: a name that resolves to a piece compiled for compiled callers only may
    appear inside compiled functions, and in the warm-up (which compiles them without a call),
    nowhere else (a call from Python would raise at run time); the assignment that defines one
    (control/sampled.py's dispatch, made by a function at import) is not a use, nor is handing
    one to the registry in an integration method's, an actuator type's or a sensor type's
    declaration (``METHOD = IntegrationMethod(...)``, ``ACTUATOR = ActuatorType(...)``,
    ``SENSOR = SensorType(...)``, whose compiled parts only the families' compiled dispatch calls,
    or :func:`frogsim.circuit.actuators.for_python` compiles again for Python) or in the method's ``warm`` (its parts of
    the warm-up, which compiles them without a call)."""
    import ast
    import importlib
    import inspect
    import pkgutil
    from numba.core.registry import CPUDispatcher
    bad = []
    for info in pkgutil.walk_packages(frogsim.__path__, "frogsim."):
        if info.name.endswith("__main__") or info.name == "frogsim.engine.warmup":
            continue
        mod = importlib.import_module(info.name)
        tree = ast.parse(inspect.getsource(mod))
        glb = vars(mod)

        def visit(node, compiled):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                compiled = compiled or isinstance(glb.get(node.name), CPUDispatcher)
            if isinstance(node, ast.Name) and not isinstance(node.ctx, ast.Store) and not compiled \
                    and isinstance(glb.get(node.id), _CompiledCallersOnly):      # defining one is no use
                bad.append(f"{info.name}: {node.id} (line {node.lineno})")
            for child in ast.iter_child_nodes(node):
                visit(child, compiled)
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] in (
                    ["METHOD"], ["ACTUATOR"], ["SENSOR"]):
                continue
            if info.name.startswith("frogsim.engine.methods.") and isinstance(node, ast.FunctionDef) \
                    and node.name == "warm":
                continue
            visit(node, False)
    assert not bad, "compiled-callers-only pieces used outside compiled code: " + "; ".join(bad)


def test_every_part_needs_only_parts_listed_before_it():
    seen = set()
    for name, (needs, what) in warmup.PARTS.items():
        assert set(needs) <= seen, f"{name} needs {set(needs) - seen}, listed after it"
        assert what
        seen.add(name)
    with pytest.raises(ValueError, match="unknown part"):
        warmup.warm_up("no-such-part")


@pytest.mark.parametrize("seed", range(5))
def test_scheduler_hands_out_parts_in_order_after_what_they_need(monkeypatch, seed):
    """Two workers, parts of made-up lengths: a part starts only after the parts it needs have
    ended; a part listed after the driver starts only after the driver has; and a process never
    passes over a part it could take: when a part starts, every part listed before it whose
    needs had ended (10 ms before, the time the scheduler may take to see an end) and which is
    not held for the driver has started already."""
    rng = random.Random(seed)
    lengths = {name: rng.choice((0.02, 0.05, 0.1)) for name in warmup.PARTS}
    log, lock = [], threading.Lock()

    def fake(part):
        with lock:
            log.append(("start", part, time.perf_counter()))
        time.sleep(lengths[part])
        with lock:
            log.append(("end", part, time.perf_counter()))
    monkeypatch.setattr(warmup, "warm_up", fake)
    with ThreadPoolExecutor(2) as pool:
        warmup.warm_up_parts(pool, 2)
    starts = {p: t for kind, p, t in log if kind == "start"}
    ends = {p: t for kind, p, t in log if kind == "end"}
    order = list(warmup.PARTS)
    assert set(starts) == set(order)
    held = order[order.index("driver") + 1:]
    for name, (needs, _) in warmup.PARTS.items():
        for n in needs:
            assert starts[name] >= ends[n], f"{name} started before {n} ended"
        if name in held:
            assert starts[name] >= starts["driver"], f"{name} started before the driver"
        for earlier in order[:order.index(name)]:
            ready = all(ends[n] <= starts[name] - 0.01 for n in warmup.PARTS[earlier][0])
            if ready and not (earlier in held and starts["driver"] > starts[name]):
                assert starts[earlier] <= starts[name], f"{name} started while {earlier}, listed before it, was ready"


def test_a_failing_part_raises(monkeypatch):
    def fake(part):
        if part == "rhs":
            raise RuntimeError("boom")
    monkeypatch.setattr(warmup, "warm_up", fake)
    with ThreadPoolExecutor(2) as pool, pytest.raises(RuntimeError, match="boom"):
        warmup.warm_up_parts(pool, 2)


@pytest.mark.slow
def test_warm_parts_leave_the_engine_nothing_to_compile(tmp_path):
    """With every part compiled into a fresh cache (in one process), a run of the paper's cycle in
    a second process (its model built from the scenario) compiles nothing of the physics, the
    circuit, the driver, the controllers or the measures: the parts were compiled for the argument
    types a run passes."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=SRC)
    warm = "from frogsim._jit import cache_is_warm\nfrom frogsim.engine.integrator import advance\n" \
           "print(cache_is_warm(advance))\n"
    # the first process finds the cache cold, then compiles every part into it; the driver's part
    # compiles no method's member (each is a part of its own, compiled beside the right-hand side)
    first = textwrap.dedent("""
        import json
        from numba.core import event
        in_driver = []
        part = [None]
        class Listener(event.Listener):
            def on_start(self, e):
                f = e.data["dispatcher"].py_func
                if part[0] == "driver":
                    in_driver.append(f"{f.__module__}.{f.__qualname__}")
            def on_end(self, e):
                pass
        event.register("numba:compile", Listener())
    """) + warm + textwrap.dedent("""
        from frogsim.engine.warmup import PARTS, warm_up
        for p in PARTS:
            part[0] = p
            warm_up(p)
        print(json.dumps(in_driver))
    """)
    out = subprocess.run([sys.executable, "-c", first], env=env, check=True, timeout=600, capture_output=True,
                         text=True).stdout.split("\n")
    assert out[0] == "False"
    in_driver = json.loads(out[1])
    assert "frogsim.engine.integrator.advance" in in_driver
    members = [c for c in in_driver if c.startswith(("frogsim.engine.methods", "frogsim.engine.stepsize",
                                                     "frogsim.circuit.rhs"))]
    assert not members, f"compiled inside the driver's part, not in a part of their own: {members}"
    # a second process finds it warm (its listener on before it looks), and its run of the paper's
    # cycle compiles nothing
    script = textwrap.dedent("""
        import json
        from numba.core import event
        compiled = []
        class Listener(event.Listener):
            def on_start(self, e):
                f = e.data["dispatcher"].py_func
                compiled.append(f"{f.__module__}.{f.__qualname__}")
            def on_end(self, e):
                pass
        event.register("numba:compile", Listener())
    """) + warm + textwrap.dedent("""
        from frogsim.studies.paper import HIP, run
        r = run()
        r.rise(HIP)
        r.pressurise_window(HIP)
        print(json.dumps(compiled))
    """)
    out = subprocess.run([sys.executable, "-c", script], env=env, check=True, timeout=600, capture_output=True,
                         text=True).stdout.strip().splitlines()
    assert out[0] == "True"
    compiled = json.loads(out[-1])
    engine = [c for c in compiled if c.startswith(("frogsim.engine.integrator", "frogsim.circuit.rhs",
                                                  "frogsim.control.sampled", "frogsim.engine.measures",
                                                  "frogsim.physics"))]
    assert not engine, f"compiled again after the warm-up: {engine}"



def test_the_engine_runs_as_plain_python_with_numba_disabled():
    """NUMBA_DISABLE_JIT=1 (the engine as plain Python, for a debugger) still runs: the pieces
    compiled for compiled callers only stay plain functions then, and the warm-up has nothing to
    compile. The hip's rise time agrees with the compiled run's (they differ at most by fused
    multiply-adds)."""
    from frogsim.studies.paper import HIP, run
    compiled = run().rise_time(HIP)
    script = ("from frogsim.studies.paper import HIP, run\n"
              "from frogsim.engine.warmup import PARTS, warm_up\n"
              "for p in PARTS: warm_up(p)\n"
              "print(repr(run().rise_time(HIP)))")
    out = subprocess.run([sys.executable, "-c", script], env=dict(os.environ, NUMBA_DISABLE_JIT="1",
                                                                  PYTHONPATH=SRC),
                         check=True, timeout=600, capture_output=True, text=True).stdout
    assert float(out.split()[-1]) == pytest.approx(compiled, rel=1e-9)
