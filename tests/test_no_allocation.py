"""The compiled hot loops allocate nothing per call, and nothing compiled leaks.

The stepping driver and the coupled engine's kernel are compiled without Numba's reference
counting (``frogsim._jit.jit``): they may only use arrays they are given. Were one of them to
receive a new array from a function that allocates, that array would never be freed. Numba's
own allocation statistics (``NUMBA_NRT_STATS=1``, set before Numba starts, hence a subprocess)
show both: stepping on after the first step allocates nothing, and everything allocated (by a
run, or by a batch of runs in one compiled call) is freed.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

SCRIPT = textwrap.dedent("""
    import gc, json
    import numpy as np
    from numba.core.runtime import rtsys
    import frogsim
    from frogsim.engine import coupled as C

    def live():
        s = rtsys.get_allocation_stats()
        return s.alloc, s.free, s.mi_alloc, s.mi_free

    raw = frogsim.load_robot_scenario("swim").raw
    st = C.CoupledStepper(frogsim.load_robot_scenario(raw, cycles=1), steps_per_action=10)
    n = st.n
    rng = np.random.default_rng(3)
    acts = [(rng.integers(0, 2, 2 * n).astype(float), float(rng.integers(0, 2))) for _ in range(40)]
    st.reset()
    st.step(*acts[0])                       # compiled (or loaded) and run once
    before = live()
    for u, palm in acts[1:]:
        st.step(u, palm)                    # 39 x 10 MuJoCo steps, each one call of the driver
    during = live()
    # a whole pneumatic run and a batch of 20 runs in one compiled call, then everything dropped
    from frogsim.engine.batch import build_models, run_outputs
    base = frogsim.load_scenario("paper-cycle")
    r = frogsim.simulate(base)
    models = build_models(base, [{"source.initial_pressure_gauge": 3e5 + 1e4 * k} for k in range(20)])
    out = run_outputs(models, columns=(np.array([5]), np.array([0])))
    del r, st, models, out
    gc.collect()
    after = live()
    print(json.dumps({"before": before, "during": during, "after": after}))
""")


def test_stepping_allocates_nothing_and_nothing_leaks(tmp_path):
    env = {**os.environ, "NUMBA_NRT_STATS": "1",
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1] / "src"),
                                          os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True,
                          timeout=900, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    before, during, after = out["before"], out["during"], out["after"]
    # 390 MuJoCo steps, each calling the kernel and the driver: not one allocation among them
    assert during[0] == before[0] and during[2] == before[2], out
    # after a whole run and its result dropped, every compiled allocation has been freed
    assert after[0] == after[1] and after[2] == after[3], out
