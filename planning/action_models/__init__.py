"""Learned action models (Stulp & Beetz): features, duration model trees, failure trees."""

from repertoire.planning.action_models.features import (
    angle_at,
    angle_to,
    distance,
    goto_pose_features,
    wrap_angle,
)
from repertoire.planning.action_models.trees import (
    MIN_EPISODES,
    MODEL_VERSION,
    FittedModel,
    LeafBox,
    TreeModel,
    fit_action_model,
    fit_duration_tree,
    fit_failure_tree,
    load_model,
    save_model,
)

__all__ = [
    "MIN_EPISODES",
    "MODEL_VERSION",
    "FittedModel",
    "LeafBox",
    "TreeModel",
    "angle_at",
    "angle_to",
    "distance",
    "fit_action_model",
    "fit_duration_tree",
    "fit_failure_tree",
    "goto_pose_features",
    "load_model",
    "save_model",
    "wrap_angle",
]
