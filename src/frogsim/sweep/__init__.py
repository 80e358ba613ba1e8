"""Design exploration: sweep specifications, batched runs, metrics, results as NetCDF.

    import frogsim.sweep
    spec = frogsim.sweep.load_spec("examples/sweep-source-saturation.toml")   # or a dict
    ds = frogsim.sweep.run_sweep(spec, out="results.nc", workers=2)           # -> xarray.Dataset

See docs/sweeps.md for the spec format, the NetCDF layout and resuming.
"""
from frogsim.sweep.metrics import METRICS, register_metric
from frogsim.sweep.metrics import STATES
from frogsim.sweep.runner import read_results, run_sweep
from frogsim.sweep.spec import SweepSpec, load_spec

__all__ = ["METRICS", "STATES", "SweepSpec", "load_spec", "read_results", "register_metric", "run_sweep"]
