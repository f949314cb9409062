"""ActionModelPredictor: a learned action model as a LeafSystem.

Action parameters come in; the predicted duration, the predicted success and
the out-of-training-range flag go out (Stulp & Beetz, section 4: the robot
asks its action models before it executes a plan).
"""

from collections.abc import Callable

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, ValueProducer
from repertoire.planning.action_models import GOTO_POSE_FEATURES, TreeModel, goto_pose_features

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError


def goto_pose_parameter_features(parameters: np.ndarray) -> np.ndarray:
    """Table 7 features of GoToPose parameters ``[x, y, phi, v, x_g, y_g, phi_g, v_g]``."""
    p = np.asarray(parameters, dtype=float)
    if p.shape != (8,):
        raise RepertoireError(f"GoToPose parameters are 8 values, got shape {p.shape}")
    return goto_pose_features(p[:4], p[4:])


goto_pose_parameter_features.feature_names = GOTO_POSE_FEATURES


class ActionModelPredictor(LeafSystem):
    """Predicts an action's duration and success from its parameters.

    Input ports:
        parameters: the action's parameters (``num_parameters`` values).

    Output ports:
        duration: ``[predicted duration]`` [s] (the leaf's hyperplane, clamped to the
            durations of the leaf's training episodes).
        success: ``[1.0]`` if the failure tree predicts success, else ``[0.0]``.
        out_of_range: ``[1.0]`` if any feature lies outside either model's
            training range (the prediction is an extrapolation), else ``[0.0]``.
    """

    def __init__(
        self,
        duration_model: TreeModel,
        failure_model: TreeModel,
        num_parameters: int,
        features: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        """Creates the predictor.

        Args:
            duration_model: a ``"duration"`` TreeModel.
            failure_model: a ``"failure"`` TreeModel on the same features.
            num_parameters: size of the parameters input (a whole number >= 1).
            features: parameters -> feature vector (default: the parameters
                are the features). A function with a ``feature_names`` attribute (as
                :func:`goto_pose_parameter_features` has) must name the models' features.

        Raises:
            RepertoireError: models of the wrong kinds or on different features, a bad
                ``num_parameters``, or a feature function whose ``feature_names`` are not
                the models' (for instance the mirrored Table 7 features with models
                fitted on the un-mirrored ones).
        """
        super().__init__()
        if duration_model.kind != "duration" or failure_model.kind != "failure":
            raise RepertoireError(
                "ActionModelPredictor needs a duration tree and a failure tree, got kinds "
                f"{duration_model.kind!r}, {failure_model.kind!r}"
            )
        if duration_model.feature_names != failure_model.feature_names:
            raise RepertoireError(
                f"the models' features differ: {duration_model.feature_names} vs "
                f"{failure_model.feature_names}"
            )
        if not is_whole(num_parameters) or num_parameters < 1:
            raise RepertoireError(
                f"num_parameters must be a whole number >= 1, got {num_parameters!r}"
            )
        num_parameters = int(num_parameters)
        if features is None and num_parameters != len(duration_model.feature_names):
            raise RepertoireError(
                f"without a feature function num_parameters must equal the "
                f"{len(duration_model.feature_names)} features, got {num_parameters}"
            )
        named = getattr(features, "feature_names", None)
        if named is not None and list(named) != list(duration_model.feature_names):
            raise RepertoireError(
                f"the feature function computes {list(named)} but the models were fitted "
                f"on {list(duration_model.feature_names)}"
            )
        self._duration = duration_model
        self._failure = failure_model
        self._features = features or (lambda p: np.asarray(p, dtype=float))
        self._in = self.DeclareVectorInputPort("parameters", num_parameters)
        cache = self.DeclareCacheEntry(
            "prediction",
            ValueProducer(
                allocate=AbstractValue.Make(np.zeros(3)).Clone,
                calc=lambda context, value: value.set_value(self._predict(context)),
            ),
            {self._in.ticket()},
        )
        self._cache = cache
        for i, name in enumerate(("duration", "success", "out_of_range")):
            self.DeclareVectorOutputPort(
                name,
                1,
                lambda context, output, i=i: output.SetAtIndex(0, self._cache.Eval(context)[i]),
                {cache.ticket()},
            )

    def _predict(self, context: Context) -> np.ndarray:
        f = np.asarray(self._features(self._in.Eval(context)), dtype=float)[None, :]
        duration = float(self._duration.predict(f)[0])
        success = 0.0 if bool(self._failure.predict_failure(f)[0]) else 1.0
        outside = bool(self._duration.out_of_range(f)[0] or self._failure.out_of_range(f)[0])
        return np.array([duration, success, float(outside)])
