"""The shared ecology interface: knobs, the environment contract, measurements and video, independent of any task."""

from ecology.contract import (
    EcologicalEnv,
    InvalidAction,
    VisitGrid,
    check_action,
    check_autoreset_mode,
    check_render_mode,
    check_reset_mask,
    make_test_mdp_kwargs,
    render_mode_missing,
)
from ecology.knobs import (
    NUM_VALIDATION_LAYOUTS,
    REWARD_MODES,
    SCHEDULE_HELP,
    TEST_MDP,
    VALIDATION_SEED_BASE,
    Ecology,
    Schedule,
    parse_schedule,
    schedule_value,
    validation_seeds,
)
from ecology.measure import (
    corner_cells,
    corner_share,
    count_entropy,
    hitting_time,
    marginal_entropy,
    visitation_counts,
)
from ecology.video import write_video

__all__ = [
    "NUM_VALIDATION_LAYOUTS",
    "REWARD_MODES",
    "SCHEDULE_HELP",
    "TEST_MDP",
    "VALIDATION_SEED_BASE",
    "EcologicalEnv",
    "Ecology",
    "InvalidAction",
    "Schedule",
    "VisitGrid",
    "check_action",
    "check_autoreset_mode",
    "check_render_mode",
    "check_reset_mask",
    "render_mode_missing",
    "corner_cells",
    "corner_share",
    "count_entropy",
    "hitting_time",
    "marginal_entropy",
    "parse_schedule",
    "schedule_value",
    "make_test_mdp_kwargs",
    "validation_seeds",
    "visitation_counts",
    "write_video",
]
