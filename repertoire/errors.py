"""Project-wide exception types.

Every public entry point raises :class:`RepertoireError` (a ``ValueError``) or a
subclass when it is given bad input, with a message that says what was wrong
and what is expected.
"""


class RepertoireError(ValueError):
    """Bad input to a repertoire entry point."""


class ScenarioError(RepertoireError):
    """A scenario YAML file or dataclass is malformed or mistyped."""


class UnknownNameError(RepertoireError):
    """A diagram, study or artefact name is not registered."""


class SolverError(RuntimeError):
    """A MathematicalProgram did not solve; the message names the solver and why."""


class UnderdeterminedFitWarning(UserWarning):
    """A least-squares fit has parameters its data barely determine.

    E.g. DMP basis functions over gaps between samples; the message says which and what to
    pass instead.
    """
