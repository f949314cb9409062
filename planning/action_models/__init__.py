"""Learned action models (Stulp & Beetz): features, duration model trees, failure trees."""

from repertoire.planning.action_models.features import (
    ARM_REACH_FEATURES,
    DRIBBLE_FEATURES,
    GOTO_POSE_FEATURES,
    UNMIRRORED_GOTO_POSE_FEATURES,
    angle_at,
    angle_to,
    arm_reach_features,
    distance,
    goto_pose_feature_names,
    goto_pose_features,
    wrap_angle,
)
from repertoire.planning.action_models.model_files import load_model, save_model
from repertoire.planning.action_models.trees import (
    MIN_EPISODES,
    MODEL_VERSION,
    FittedModel,
    LeafBox,
    TreeModel,
    fit_action_model,
    fit_duration_tree,
    fit_failure_tree,
)

__all__ = [
    "ARM_REACH_FEATURES",
    "DRIBBLE_FEATURES",
    "GOTO_POSE_FEATURES",
    "MIN_EPISODES",
    "MODEL_VERSION",
    "FittedModel",
    "LeafBox",
    "TreeModel",
    "UNMIRRORED_GOTO_POSE_FEATURES",
    "angle_at",
    "angle_to",
    "arm_reach_features",
    "distance",
    "fit_action_model",
    "fit_duration_tree",
    "fit_failure_tree",
    "goto_pose_feature_names",
    "goto_pose_features",
    "load_model",
    "save_model",
    "wrap_angle",
]
