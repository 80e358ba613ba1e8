"""Control: controllers sampled at their rate. Gaits as data (phase timing of valves and palms)
turned into valve programs and palm commands on the controller's grid; the closed-loop kinds, one
module each (:mod:`frogsim.control.kinds`, registered on import); the table of laws
(:mod:`frogsim.control.table`) and the driver's side of the sampled laws
(:mod:`frogsim.control.sampled`)."""
import frogsim.control.kinds  # noqa: F401  (registers every controller kind)
import frogsim.control.table  # noqa: F401  (registers the table builder)
