"""Calibrating the model to measured traces: weighted least squares with honest intervals.

    frogsim fit FIT.toml --out DIR          (see docs/fitting.md)

:func:`fit` reads a fit spec (traces and all, refusing bad input before anything runs), fits, and
writes the outputs when given a folder; :func:`frogsim.fit.traces.read_trace` reads one trace.
"""
from frogsim.fit.core import FitResult, fit_spec
from frogsim.fit.spec import FitSpec, load_fit_spec
from frogsim.fit.traces import Trace, read_trace

__all__ = ["FitResult", "FitSpec", "Trace", "fit", "fit_spec", "load_fit_spec", "read_trace"]


def fit(spec, out=None, *, progress: bool = False, starts: int | None = None,
        threads: int | None = None) -> FitResult:
    """Fit a spec (FIT.toml path, dict, or loaded FitSpec); with ``out``, write the outputs there
    (fitted parameter file, figures, report.html, summary.json). Returns the FitResult."""
    if not isinstance(spec, FitSpec):
        spec = load_fit_spec(spec, starts=starts, threads=threads)
    if out is not None:
        from frogsim._files import out_folder
        out_folder(out)
    result = fit_spec(spec, progress=progress)
    if out is not None:
        from frogsim.fit.report import write_outputs
        write_outputs(result, out)
    return result
