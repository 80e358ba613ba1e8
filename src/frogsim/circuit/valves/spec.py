"""The declaration every valve type's module ends with: ``VALVE = ValveType(...)``."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable


@dataclass(frozen=True)
class ValveType:
    """What the rest of frogsim reads of a valve type (docs/architecture.md, "Adding a valve type").

    * ``settings``: its settings class (a frozen dataclass derived from
      :class:`frogsim.scenario.valves.ValveSettings`, ``TYPE`` its name in ``[valves] type``);
    * ``code``: its value in the muscle rows' valve column ``mp[i, M_VALVE]`` (a float > 0, unique);
    * ``block(settings) -> tuple``: its parameter block, at most ``VALVE_PARAMS`` floats, written
      at ``mp[i, M_VP:]`` (SI);
    * ``flows(mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref) -> (m_c, m_d)``
      (compiled, allocation-free): the mass flows [kg/s] into muscle i through its charge path
      (from p_up, T_up) and out through its vent path (to p_e, T_e), given the valve vector's two
      entries u_c = u[2i], u_d = u[2i+1] (each path's opening, 0 shut .. 1 fully open) and the
      muscle's p_i [Pa abs], T_i [K]; a flow is 0.0 exactly where its path is shut (so that the
      right-hand side skips it), negative against its direction;
    * ``openings(mp, i, command, memory, dt) -> (u_c, u_d, memory)`` (compiled): the controller's
      view, what a sampled law's command (a mode -1 vent / 0 hold / +1 charge, or a continuous
      command in -1..1) sets the two entries to over the next period dt [s], and the valve's one
      memory value carried from sample to sample (a spool's position);
    * ``continuous``: True when the valve takes a continuous command (a spool), False when only the
      sign of a command counts (open or shut).
    """
    settings: type
    code: float
    block: Callable
    flows: Callable
    openings: Callable
    continuous: bool = False
    module: str = ""

    @property
    def name(self) -> str:
        return self.settings.TYPE

    def registered(self, module: str) -> "ValveType":
        return replace(self, module=module)
