"""Abstract plans, causal links and instantiation into executable actions.

Section 6.1 and Algorithm 2 of Stulp & Beetz, "Refining the execution of abstract
actions with learned action models" (JAIR 2008). A PDDL planner (unified-planning's
pyperplan engine, called in-process) returns a sequential plan of symbolic actions;
:func:`derive_causal_links` recovers which earlier step (0 = the initial state) achieved
each precondition; :func:`instantiate_plan` maps every symbolic action to an executable
action template from an :class:`ActionRegistry` and asks a :class:`BeliefState` for each
parameter's value or range. Parameters left with a range are *free*; parameters derived
from the same symbolic label and the same physical quantity share one identity (the
paper's parameter IDs), so the approach's goal angle and the dribble's start angle are
one free parameter.

The planner is optional (extra ``pddl``): pyperplan is GPL-3.0 and the project is
BSD-3-Clause, so it is imported only when :func:`plan_pddl` runs. Everything else here
works on :class:`AbstractPlan` values from any source.
"""

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from repertoire.planning.refinement import DurationTerm, RefinementProblem

from repertoire.checks import is_real
from repertoire.errors import RepertoireError, SolverError

Atom = tuple[str, tuple[str, ...]]
"""A ground predicate: (name, arguments), e.g. ``("atball", ("pos2",))``."""

INITIAL_STEP = 0
"""Step index of the initial state in causal links (the paper's '0')."""


class PlanningError(RepertoireError):
    """A PDDL problem is malformed or has no plan."""


@dataclass(frozen=True)
class GroundAction:
    """One step of a sequential plan with its ground preconditions and effects.

    Args:
        name: symbolic action name, e.g. ``"approachball"``.
        args: symbolic arguments (object labels), e.g. ``("pos1", "pos2")``.
        preconditions: positive ground atoms the step requires.
        add_effects: atoms the step makes true.
        delete_effects: atoms the step makes false.
    """

    name: str
    args: tuple[str, ...]
    preconditions: tuple[Atom, ...] = ()
    add_effects: tuple[Atom, ...] = ()
    delete_effects: tuple[Atom, ...] = ()


@dataclass(frozen=True)
class CausalLink:
    """Step ``producer`` achieves ``atom``, which step ``consumer`` needs.

    Steps are numbered 1..n for the plan's actions, 0 for the initial state and n + 1
    for the goal.
    """

    producer: int
    atom: Atom
    consumer: int


@dataclass(frozen=True)
class AbstractPlan:
    """A sequential plan with its causal links.

    Args:
        actions: the plan's steps in execution order (step i + 1 is ``actions[i]``).
        links: causal links derived from the sequence.
        goal: the goal atoms.
    """

    actions: tuple[GroundAction, ...]
    links: tuple[CausalLink, ...]
    goal: tuple[Atom, ...] = ()

    def links_by_label(self) -> dict[str, list[tuple[int, str]]]:
        """The paper's ``pddl_links``: label -> [(producer step, predicate name)].

        For Figure 10 (sequential numbering): ``{"pos1": [(0, "robot")], "pos2": [(0,
        "ball"), (1, "atball")], "pos3": [(0, "final"), (2, "atball")]}``.
        """
        out: dict[str, list[tuple[int, str]]] = {}
        for link in self.links:
            for label in link.atom[1]:
                entry = (link.producer, link.atom[0])
                bucket = out.setdefault(label, [])
                if entry not in bucket:
                    bucket.append(entry)
        for bucket in out.values():
            bucket.sort()
        return out


def derive_causal_links(
    initial: Sequence[Atom], actions: Sequence[GroundAction], goal: Sequence[Atom]
) -> tuple[CausalLink, ...]:
    """Causal links of a sequential plan: each need is linked to its latest achiever.

    Args:
        initial: atoms true in the initial state.
        actions: the plan's steps in order.
        goal: goal atoms (consumed by step ``len(actions) + 1``).

    Returns:
        One link per precondition and goal atom, from the last step before the consumer
        that added it (0 if it held initially and nothing re-added it).

    Raises:
        PlanningError: a precondition or goal atom is not true when it is needed (the
            sequence is not a valid plan); the message names the step and the atom.
    """
    achiever: dict[Atom, int] = {atom: INITIAL_STEP for atom in initial}
    links: list[CausalLink] = []
    steps = [*actions, GroundAction("goal", (), tuple(goal))]
    for i, step in enumerate(steps, start=1):
        for atom in step.preconditions:
            if atom not in achiever:
                where = "the goal" if i == len(steps) else f"step {i} ({step.name})"
                raise PlanningError(
                    f"{where} needs {_fmt_atom(atom)}, which no earlier step achieves and "
                    "the initial state does not hold; expected a valid sequential plan"
                )
            links.append(CausalLink(achiever[atom], atom, i))
        for atom in step.delete_effects:
            achiever.pop(atom, None)
        for atom in step.add_effects:
            achiever[atom] = i
    return tuple(links)


def _fmt_atom(atom: Atom) -> str:
    return "(" + " ".join([atom[0], *atom[1]]) + ")"


# --------------------------------------------------------------------------------------
# The PDDL planner (optional dependency)


def plan_pddl(domain: str, problem: str) -> AbstractPlan:
    """Plans a PDDL problem in-process with unified-planning's pyperplan engine.

    Args:
        domain: PDDL domain text (STRIPS with typing).
        problem: PDDL problem text.

    pyperplan takes no time limit (unified-planning warns and ignores one); its
    searches keep a closed list over the finite state space of a ground STRIPS problem,
    so they terminate.

    Returns:
        The sequential plan with its causal links.

    Raises:
        PlanningError: unparsable PDDL, PDDL beyond STRIPS with typing (named), or no
            plan exists; then the message names the goal atoms that are unreachable on
            their own (or says they are only jointly unreachable).
        RepertoireError: unified-planning / up-pyperplan are not installed.
    """
    up_problem = _parse(domain, problem)
    initial = _initial_atoms(up_problem)
    goal = _goal_atoms(up_problem)
    ground = _solve(up_problem)
    if ground is None:
        unreachable = [atom for atom in goal if _solve(_with_goal(up_problem, atom)) is None]
        if unreachable:
            names = ", ".join(_fmt_atom(a) for a in unreachable)
            raise PlanningError(f"the PDDL problem has no plan: goal {names} is unreachable")
        names = ", ".join(_fmt_atom(a) for a in goal)
        raise PlanningError(
            f"the PDDL problem has no plan: goals {names} are each reachable but not together"
        )
    return AbstractPlan(ground, derive_causal_links(initial, ground, goal), goal)


def _import_up():
    try:
        import unified_planning.shortcuts as shortcuts
        from unified_planning.io import PDDLReader
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RepertoireError(
            "plan_pddl needs unified-planning and up-pyperplan: pip install "
            "'repertoire[pddl]' (pyperplan is GPL-3.0, hence optional)"
        ) from exc
    shortcuts.get_environment().credits_stream = None
    return shortcuts, PDDLReader


def _parse(domain: str, problem: str):
    _, reader_cls = _import_up()
    if not domain.strip() or not problem.strip():
        raise PlanningError("domain and problem must be non-empty PDDL texts")
    try:
        return reader_cls().parse_problem_string(domain, problem)
    except Exception as exc:  # the reader raises several unrelated exception types
        raise PlanningError(f"could not parse the PDDL domain/problem: {exc}") from exc


def _atoms_of(node, binding: Mapping[str, str]) -> list[Atom]:
    """Positive ground atoms of a conjunction of fluent expressions."""
    if node.is_and():
        return [a for arg in node.args for a in _atoms_of(arg, binding)]
    if node.is_fluent_exp():
        args = []
        for arg in node.args:
            if arg.is_parameter_exp():
                args.append(binding[arg.parameter().name])
            elif arg.is_object_exp():
                args.append(arg.object().name)
            else:
                raise PlanningError(f"unsupported PDDL argument {arg}: expected STRIPS")
        return [(node.fluent().name, tuple(args))]
    if node.is_not() or node.is_true():
        return []  # negative preconditions achieve nothing to link
    raise PlanningError(f"unsupported PDDL expression {node}: expected STRIPS conjunctions")


def _initial_atoms(up_problem) -> list[Atom]:
    return [
        a
        for fluent, value in up_problem.explicit_initial_values.items()
        if value.is_true()
        for a in _atoms_of(fluent, {})
    ]


def _goal_atoms(up_problem) -> tuple[Atom, ...]:
    return tuple(a for g in up_problem.goals for a in _atoms_of(g, {}))


def _with_goal(up_problem, atom: Atom):
    single = up_problem.clone()
    single.clear_goals()
    fluent = single.fluent(atom[0])
    single.add_goal(fluent(*[single.object(o) for o in atom[1]]))
    return single


def _solve(up_problem) -> tuple[GroundAction, ...] | None:
    shortcuts, _ = _import_up()
    status = shortcuts.up.engines.PlanGenerationResultStatus
    with shortcuts.OneshotPlanner(name="pyperplan") as planner:
        if not planner.supports(up_problem.kind):
            supported = planner.supported_kind().features
            extra = sorted(set(up_problem.kind.features) - set(supported))
            raise PlanningError(
                f"pyperplan plans STRIPS with typing only; this PDDL problem also uses "
                f"{extra}: rewrite it without them"
            )
        result = planner.solve(up_problem)
    if result.status in (status.SOLVED_SATISFICING, status.SOLVED_OPTIMALLY):
        return tuple(_ground(ai) for ai in result.plan.actions)
    if result.status in (status.UNSOLVABLE_PROVEN, status.UNSOLVABLE_INCOMPLETELY):
        return None
    raise SolverError(f"pyperplan (unified-planning) returned {result.status.name}")


def _ground(action_instance) -> GroundAction:
    action = action_instance.action
    args = tuple(str(p) for p in action_instance.actual_parameters)
    binding = {p.name: a for p, a in zip(action.parameters, args, strict=True)}
    pre = tuple(a for c in action.preconditions for a in _atoms_of(c, binding))
    adds: list[Atom] = []
    dels: list[Atom] = []
    for effect in action.effects:
        if not effect.condition.is_true():
            raise PlanningError(f"{action.name}: conditional effects are not supported")
        (adds if effect.value.is_true() else dels).extend(_atoms_of(effect.fluent, binding))
    return GroundAction(action.name, args, pre, tuple(adds), tuple(dels))


# --------------------------------------------------------------------------------------
# Executable action templates and instantiation (Algorithm 2)


@dataclass(frozen=True)
class ParameterTemplate:
    """One parameter of an executable action.

    Args:
        name: the parameter's name in the action, e.g. ``"phi_g"``.
        quantity: the belief-state quantity it holds, e.g. ``"phi"``; parameters of the
            same quantity derived from the same symbolic label share an identity.
        index: which symbolic argument of the PDDL action it belongs to (Algorithm 2,
            line 8): 0 for ``?from``, 1 for ``?to``.
    """

    name: str
    quantity: str
    index: int


@dataclass(frozen=True)
class ActionTemplate:
    """An executable action's name and parameters (issue 11's actions fill these)."""

    name: str
    parameters: tuple[ParameterTemplate, ...]

    def __post_init__(self) -> None:
        names = [p.name for p in self.parameters]
        if not self.name or len(set(names)) != len(names):
            raise RepertoireError(
                f"action template {self.name!r} needs a name and unique parameter names, "
                f"got {names}"
            )
        if any(p.index < 0 for p in self.parameters):
            raise RepertoireError(f"action template {self.name!r}: indices must be >= 0")


@dataclass
class ActionRegistry:
    """Maps symbolic action names (case-insensitive, as PDDL) to executable templates."""

    templates: dict[str, ActionTemplate] = field(default_factory=dict)

    def register(self, template: ActionTemplate, *, symbolic_name: str | None = None) -> None:
        """Registers ``template`` for ``symbolic_name`` (default: the template's name)."""
        key = (symbolic_name or template.name).lower()
        if key in self.templates:
            raise RepertoireError(f"an executable action is already registered for {key!r}")
        self.templates[key] = template

    def template(self, name: str) -> ActionTemplate:
        """The template whose own name is ``name`` (as in an ExecutableAction)."""
        for template in self.templates.values():
            if template.name == name:
                return template
        raise RepertoireError(
            f"no executable action template named {name!r}; registered: "
            f"{sorted(t.name for t in self.templates.values())}"
        )

    def get(self, symbolic_name: str) -> ActionTemplate:
        """The template for a symbolic action, or a clear error naming what exists."""
        try:
            return self.templates[symbolic_name.lower()]
        except KeyError:
            raise RepertoireError(
                f"abstract action {symbolic_name!r} has no executable counterpart; "
                f"registered: {sorted(self.templates)}"
            ) from None


@dataclass(frozen=True)
class Range:
    """A closed interval; ``lo == hi`` is a bound value."""

    lo: float
    hi: float

    def __post_init__(self) -> None:
        if math.isnan(self.lo) or math.isnan(self.hi) or self.lo > self.hi:
            raise RepertoireError(f"empty or NaN range [{self.lo}, {self.hi}]: expected lo <= hi")

    @property
    def is_bound(self) -> bool:
        """True if the range holds one value."""
        return self.lo == self.hi


@dataclass
class BeliefState:
    """Maps symbolic predicates to values and ranges (Algorithm 2, line 10).

    Args:
        values: (predicate, quantity) -> value, for predicates that hold in the current
            state (producer step 0), e.g. ``("robot", "x"): 0.0``.
        constraints: (predicate, quantity) -> (lo, hi), for predicates achieved by plan
            steps, e.g. ``("atball", "v"): (0.0, 0.3)``.
        defaults: quantity -> (lo, hi), the range when no predicate says more, e.g.
            ``"phi": (-pi, pi)``.
    """

    values: dict[tuple[str, str], float] = field(default_factory=dict)
    constraints: dict[tuple[str, str], tuple[float, float]] = field(default_factory=dict)
    defaults: dict[str, tuple[float, float]] = field(default_factory=dict)

    def value(self, quantity: str, predicates: Sequence[tuple[int, str]]) -> Range:
        """Composes what the predicates say about ``quantity`` (intersection of ranges).

        Raises:
            RepertoireError: no default for the quantity, a default or constraint that is
                not a ``(lo, hi)`` pair of numbers with ``lo <= hi`` (NaN included), a
                value that is not a finite number, the composed range is empty, or a
                value held in the current state lies outside the constraints.
        """
        if quantity not in self.defaults:
            raise RepertoireError(
                f"belief state has no default range for quantity {quantity!r}; "
                f"known: {sorted(self.defaults)}"
            )
        lo, hi = _belief_range(f"default range of {quantity!r}", self.defaults[quantity])
        bound: float | None = None
        for step, predicate in predicates:
            key = (predicate, quantity)
            if step == INITIAL_STEP and key in self.values:
                bound = self.values[key]
                if not (is_real(bound) and math.isfinite(bound)):
                    raise RepertoireError(
                        f"belief state value {key} is {bound!r}; expected a finite number"
                    )
                bound = float(bound)
            elif key in self.constraints:
                c_lo, c_hi = _belief_range(f"constraint {key}", self.constraints[key])
                lo, hi = max(lo, c_lo), min(hi, c_hi)
        if lo > hi:
            raise RepertoireError(
                f"free parameter {quantity!r}: predicates {list(predicates)} compose to the "
                f"empty range [{lo}, {hi}]"
            )
        if bound is not None:
            if not lo <= bound <= hi:
                raise RepertoireError(
                    f"{quantity!r} = {bound} in the belief state lies outside [{lo}, {hi}]"
                )
            return Range(bound, bound)
        return Range(lo, hi)


def _belief_range(what: str, pair) -> tuple[float, float]:
    """``pair`` as ``(lo, hi)`` floats (infinite allowed), or a RepertoireError naming ``what``.

    A NaN bound would drop out of ``max``/``min`` silently and leave the range unconstrained.
    """
    try:
        lo, hi = pair
    except (TypeError, ValueError):
        raise RepertoireError(f"belief state {what} is {pair!r}; expected (lo, hi)") from None
    if not (is_real(lo) and is_real(hi)) or math.isnan(lo) or math.isnan(hi) or lo > hi:
        raise RepertoireError(
            f"belief state {what} is {pair!r}; expected two numbers (not NaN) with lo <= hi"
        )
    return float(lo), float(hi)


@dataclass(frozen=True)
class ExecutableAction:
    """An instantiated action: each parameter name -> the identity of its value."""

    name: str
    args: tuple[str, ...]
    parameter_ids: dict[str, str]


@dataclass(frozen=True)
class InstantiatedPlan:
    """Executable actions with shared parameter identities, bound values and free ranges.

    Args:
        actions: the executable actions in order.
        ranges: identity (``"<label>.<quantity>"``) -> its range; bound ones have
            ``lo == hi``. Insertion order is first use along the plan.
    """

    actions: tuple[ExecutableAction, ...]
    ranges: dict[str, Range]

    @property
    def free_ids(self) -> list[str]:
        """Identities of free parameters, in order of first use."""
        return [k for k, r in self.ranges.items() if not r.is_bound]

    def parameters_of(self, i: int, values: Mapping[str, float] | None = None) -> dict:
        """Action ``i``'s parameters: a float when bound (or given), else the Range."""
        values = values or {}
        out: dict[str, float | Range] = {}
        for name, pid in self.actions[i].parameter_ids.items():
            r = self.ranges[pid]
            out[name] = float(values[pid]) if pid in values else (r.lo if r.is_bound else r)
        return out


def instantiate_plan(
    plan: AbstractPlan, registry: ActionRegistry, belief: BeliefState
) -> InstantiatedPlan:
    """Algorithm 2: maps symbolic actions to executable ones with free parameters.

    Args:
        plan: the abstract plan with causal links.
        registry: symbolic name -> executable action template.
        belief: the belief state that turns predicates into values and ranges.

    Returns:
        The instantiated plan; parameters of the same quantity reached through the same
        symbolic label share one identity and one range.

    Raises:
        RepertoireError: an action has no executable counterpart, a template index has
            no symbolic argument, or a parameter's range is empty.
    """
    if not plan.actions:
        raise RepertoireError("the abstract plan has no actions to instantiate")
    links = plan.links_by_label()
    actions: list[ExecutableAction] = []
    ranges: dict[str, Range] = {}
    for step in plan.actions:
        template = registry.get(step.name)
        ids: dict[str, str] = {}
        for par in template.parameters:
            if par.index >= len(step.args):
                raise RepertoireError(
                    f"{template.name}.{par.name} uses symbolic argument {par.index}, but "
                    f"{step.name} has only {len(step.args)}: {step.args}"
                )
            label = step.args[par.index]
            pid = f"{label}.{par.quantity}"
            if pid not in ranges:
                ranges[pid] = belief.value(par.quantity, links.get(label, []))
            ids[par.name] = pid
        actions.append(ExecutableAction(template.name, step.args, ids))
    return InstantiatedPlan(tuple(actions), ranges)


# --------------------------------------------------------------------------------------
# From an instantiated plan to a refinement problem


@dataclass(frozen=True)
class ActionDurationModel:
    """An executable action's duration model and its feature function.

    Args:
        model: the learned duration model (leaves as boxes + hyperplanes).
        features: action parameters (name -> (n,) values) -> (n, d) features, e.g. the
            paper's Table 7 features (distance, angle_to, angle_at, v) of a goToPose.
        domain: optional ``(lower, upper)`` feature box where the model is trusted (its
            training range): refinement then searches only where the features the free
            parameters drive lie inside it (:class:`DurationTerm`'s ``domain``).
        reads: with ``domain``, per feature the names of the action parameters it reads
            (e.g. ``("x", "y", "x_g", "y_g", "phi_g")`` for a goToPose's ``angle_at``).
    """

    model: object
    features: Callable[[dict[str, np.ndarray]], np.ndarray]
    domain: tuple | None = None
    reads: tuple[tuple[str, ...], ...] | None = None


@dataclass(frozen=True)
class _PlanActionFeatures:
    """Feature map of one plan action over the plan's free-parameter vector."""

    features: Callable[[dict[str, np.ndarray]], np.ndarray]
    bound: dict[str, float]
    free: dict[str, int]
    succeeds: Callable[[dict[str, np.ndarray]], np.ndarray] | None = None

    def __call__(self, params: np.ndarray) -> np.ndarray:
        p = np.atleast_2d(params)
        values = {name: np.full(p.shape[0], v) for name, v in self.bound.items()}
        values.update({name: p[:, i] for name, i in self.free.items()})
        features = np.array(self.features(values), dtype=float)
        if self.succeeds is not None:  # NaN features lie in no leaf: predicted +inf
            ok = np.asarray(self.succeeds(values), dtype=bool).reshape(-1)
            features[~ok] = np.nan
        return features


def refinement_problem(
    plan: InstantiatedPlan,
    models: Mapping[str, ActionDurationModel],
    *,
    succeeds: Mapping[int, Callable[[dict[str, np.ndarray]], np.ndarray]] | None = None,
) -> RefinementProblem:
    """The refinement problem of an instantiated plan (one term per executable action).

    The problem's parameters are the plan's free identities (``plan.free_ids``, names
    included); every action's term reads its bound values and the free parameters it
    shares with its neighbours. Feature functions are arbitrary (angles), so solve with
    ``"ga"`` or ``"de"``, or use :class:`~repertoire.planning.refinement.AffineFeatures`
    directly where features are affine.

    Args:
        plan: from :func:`instantiate_plan`.
        models: executable action name -> its duration model and feature function.
        succeeds: action index -> a failure model's success prediction from the
            action's parameters (name -> (n,) values) -> (n,) booleans. Where it
            predicts failure, the action's predicted duration is +inf: Algorithm 4's
            INVALID, which the GA ranks last (used after :func:`insert_subgoal`).

    Raises:
        RepertoireError: an action has no model, the plan has no free parameter, or a
            ``succeeds`` index is not an action of the plan.
    """
    succeeds = dict(succeeds or {})
    if any(not 0 <= i < len(plan.actions) for i in succeeds):
        raise RepertoireError(
            f"succeeds names actions {sorted(succeeds)}, the plan has {len(plan.actions)}"
        )
    free_ids = plan.free_ids
    if not free_ids:
        raise RepertoireError("the plan has no free parameters: nothing to refine")
    index = {pid: i for i, pid in enumerate(free_ids)}
    terms = []
    for i, action in enumerate(plan.actions):
        if action.name not in models:
            raise RepertoireError(
                f"no duration model for action {action.name!r}; have {sorted(models)}"
            )
        entry = models[action.name]
        bound = {
            n: plan.ranges[pid].lo for n, pid in action.parameter_ids.items() if pid not in index
        }
        free = {n: index[pid] for n, pid in action.parameter_ids.items() if pid in index}
        feats = _PlanActionFeatures(entry.features, bound, free, succeeds.get(i))
        name = f"{i}:{action.name}"
        feature_uses = None
        if entry.domain is not None:
            feature_uses = _feature_uses(entry.reads, action.parameter_ids, free, name)
        uses = tuple(sorted(set(free.values())))
        terms.append(DurationTerm(entry.model, feats, uses, name, entry.domain, feature_uses))
    lower = np.array([plan.ranges[pid].lo for pid in free_ids])
    upper = np.array([plan.ranges[pid].hi for pid in free_ids])
    return RefinementProblem(tuple(terms), lower, upper, tuple(free_ids))


def _feature_uses(reads, parameters, free: dict[str, int], name: str):
    """Per feature, the free-parameter indices of the action parameters it ``reads``."""
    if reads is None or isinstance(reads, str):
        raise RepertoireError(
            f"action {name}: a duration model with a domain needs `reads`, per feature the "
            f"names of the action parameters it reads (of {sorted(parameters)})"
        )
    rows = [(r,) if isinstance(r, str) else tuple(r) for r in reads]
    unknown = sorted({n for r in rows for n in r} - set(parameters))
    if unknown:
        raise RepertoireError(
            f"action {name}: `reads` names {unknown}, not parameters of the action "
            f"({sorted(parameters)})"
        )
    return tuple(tuple(sorted({free[n] for n in r if n in free})) for r in rows)


def insert_subgoal(
    plan: InstantiatedPlan,
    i: int,
    registry: ActionRegistry,
    belief: BeliefState,
    *,
    replacement: str,
    label: str = "subgoal1",
) -> InstantiatedPlan:
    """Algorithm 3, lines 18-20: action ``i`` becomes two ``replacement`` legs via a subgoal.

    The first leg starts where action ``i`` started and ends at the new symbolic label;
    the second starts there and ends where action ``i`` ended. The label's parameters
    are new identities with the belief state's default ranges, free for refinement
    (with :func:`refinement_problem`'s ``succeeds`` on the second leg, so only subgoals
    the failure model accepts are chosen). Parameters are matched by index (0 = from,
    1 = to) and quantity, as in Algorithm 2.

    Args:
        plan: the instantiated plan.
        i: index of the action predicted to fail.
        registry: holds the templates of action ``i`` and of ``replacement``.
        belief: supplies the default ranges of the subgoal's quantities.
        replacement: symbolic name of the action that replaces it (e.g. ``"goToPose"``).
        label: the subgoal's symbolic label (must be new to the plan).

    Raises:
        RepertoireError: bad index, a label already in use, or a replacement parameter
            with no counterpart of the same index and quantity in action ``i``.
    """
    if not 0 <= i < len(plan.actions):
        raise RepertoireError(f"action index {i} is not in 0..{len(plan.actions) - 1}")
    if any(pid.split(".", 1)[0] == label for pid in plan.ranges):
        raise RepertoireError(f"subgoal label {label!r} is already used by the plan")
    action = plan.actions[i]
    if len(action.args) < 2:
        raise RepertoireError(
            f"action {i} ({action.name} {action.args}) has no symbolic 'to' argument (index 1) "
            "for the second leg to end at"
        )
    old = registry.template(action.name)
    new = registry.get(replacement)
    ids = {(p.index, p.quantity): action.parameter_ids[p.name] for p in old.parameters}
    ranges = dict(plan.ranges)
    legs = []
    for leg in (0, 1):
        leg_ids = {}
        for par in new.parameters:
            if par.index not in (0, 1):
                raise RepertoireError(f"{new.name}.{par.name}: index {par.index} is not 0 or 1")
            if par.index != leg:  # the subgoal's side of this leg
                pid = f"{label}.{par.quantity}"
                if pid not in ranges:
                    ranges[pid] = belief.value(par.quantity, [])
            elif (par.index, par.quantity) in ids:
                pid = ids[(par.index, par.quantity)]
            else:
                raise RepertoireError(
                    f"{new.name}.{par.name} ({par.quantity} at index {par.index}) has no "
                    f"counterpart in {old.name}"
                )
            leg_ids[par.name] = pid
        args = (action.args[0], label) if leg == 0 else (label, action.args[1])
        legs.append(ExecutableAction(new.name, args, leg_ids))
    actions = (*plan.actions[:i], *legs, *plan.actions[i + 1 :])
    return InstantiatedPlan(actions, ranges)
