"""Studies registered by name: each is a function returning data plus a function drawing it.

``STUDIES[name]`` is a :class:`Study`; ``run_study(name)`` returns its :class:`StudyData`.
"""
from frogsim.studies.registry import STUDIES, Study, StudyData, register, run_study, studies_in  # noqa: F401
from frogsim.studies import paper  # noqa: F401,E402  (registers the paper's studies)
from frogsim.studies import design  # noqa: F401,E402  (registers the design studies)
from frogsim.studies import robot  # noqa: F401,E402  (registers the robot's in-air study)
from frogsim.studies import control  # noqa: F401,E402  (registers the closed-loop control study)
from frogsim.studies import control_joint  # noqa: F401,E402  (registers the joint-angle control study)
from frogsim.studies import hysteresis  # noqa: F401,E402  (registers the hysteresis study)
from frogsim.studies import heat  # noqa: F401,E402  (registers the wall heat transfer study)
from frogsim.studies import valve_type  # noqa: F401,E402  (registers the valve-type design study)
from frogsim.studies import control_tune  # noqa: F401,E402  (registers the gains-tuning study)
