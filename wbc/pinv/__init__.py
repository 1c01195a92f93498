"""The thesis's pseudo-inverse baselines (com-control-thesis 2018, ch. 1.6-1.7, 3 and 4).

* :mod:`.pseudoinverse` — Moore–Penrose, weighted, damped, weighted-damped, adaptive λ;
* :mod:`.joint_limits` — gradient-projection costs and the Chan–Dubey weights;
* :mod:`.rooted` — the support sole as the root of the kinematics on our floating base;
* :mod:`.principal_masses` — the five principal masses and their targets;
* :mod:`.com_placement` — static CoM placement: MCMT, DE, MS, DEAV, MSAV;
* :mod:`.schemes` — walking schemes: VAT, CJ, VATL, CJL;
* :mod:`.benchmark` — Tables 3.3.2/3.3.3 and the walking step on our model.
"""

from ..limits.joint_costs import COSTS, ChanDubeyWeights
from .benchmark import (
    run_com_placement_benchmark,
    run_walking_benchmark,
    settled_start,
    thesis_like_step,
    track_step,
)
from .com_placement import (
    METHODS,
    THESIS_COM_TOLERANCE,
    ComPlacement,
    PlacementResult,
    default_com_target,
    place_com,
)
from .joint_limits import gradient_projection
from .principal_masses import PrincipalMasses, com_mass_matrix, principal_mass_targets
from .pseudoinverse import (
    AdaptiveDamping,
    damped_pinv,
    moore_penrose,
    null_space_projector,
    weighted_damped_pinv,
    weighted_pinv,
)
from .rooted import SoleRooted
from .schemes import SCHEME_NAMES, SchemeInfo, ThesisScheme
from .thesis_data import TABLE_3_3_1, annex_b_weights

__all__ = [
    "COSTS",
    "METHODS",
    "SCHEME_NAMES",
    "TABLE_3_3_1",
    "THESIS_COM_TOLERANCE",
    "AdaptiveDamping",
    "ChanDubeyWeights",
    "ComPlacement",
    "PlacementResult",
    "PrincipalMasses",
    "SchemeInfo",
    "SoleRooted",
    "ThesisScheme",
    "annex_b_weights",
    "com_mass_matrix",
    "damped_pinv",
    "default_com_target",
    "gradient_projection",
    "moore_penrose",
    "null_space_projector",
    "place_com",
    "principal_mass_targets",
    "run_com_placement_benchmark",
    "run_walking_benchmark",
    "settled_start",
    "thesis_like_step",
    "track_step",
    "weighted_damped_pinv",
    "weighted_pinv",
]
