"""Controller kinds, one module each (docs/control.md, "Adding a controller kind").

A kind's module holds its typed settings (a frozen dataclass registered with
:func:`frogsim.scenario.kinds.register`, its fields carrying units, bounds and choices), its
cross-field checks (``check``), how it writes its rows of the compiled table of laws
(``write_rows``, columns of :mod:`frogsim.control.table`) and its compiled law ``law(laws, c, cs,
b, y, p, ts) -> mode`` with its code ``CODE`` in the table's kind column (a law that models the
valves, the sliding-mode one, also takes the model's muscle rows ``mp`` after ``laws``: the
valves' constants are read there, not copied into the table). A kind that runs on the robot's
board also holds its firmware twins: ``fw_law(P, T, mem, k, cp, ca)`` (Numba, the law in integer
arithmetic on ADC counts, run by the model with ``[firmware]``), ``C_NAME`` and ``c_source()``
(the same law in C for the board) and the writer of its parameters and tables
(:mod:`frogsim.control.fixed`, :mod:`frogsim.control.firmware`). Every module of this
package is imported here, which registers its settings; the compiled dispatch of
:func:`frogsim.control.sampled.sample_controllers` lists the kinds that have a law, one branch
each (Numba compiles calls to functions it can name, and caches them by their source files).
"""
import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_module.name}")
