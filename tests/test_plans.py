"""Plans: PDDL planning in-process, causal links, instantiation (Algorithm 2, Figure 10)."""

import math

import numpy as np
import pytest
from repertoire.planning.plans import (
    AbstractPlan,
    ActionDurationModel,
    ActionRegistry,
    ActionTemplate,
    BeliefState,
    CausalLink,
    GroundAction,
    ParameterTemplate,
    PlanningError,
    Range,
    derive_causal_links,
    insert_subgoal,
    instantiate_plan,
    plan_pddl,
    refinement_problem,
)
from repertoire.planning.refinement import PiecewiseLinearModel, refine_sequence
from repertoire.studies._refinement_common import SOCCER_DOMAIN, SOCCER_PROBLEM

from repertoire.errors import RepertoireError


def _pose(index: int, suffix: str = "") -> tuple[ParameterTemplate, ...]:
    return tuple(ParameterTemplate(q + suffix, q, index) for q in ("x", "y", "phi", "v"))


def soccer_registry() -> ActionRegistry:
    registry = ActionRegistry()
    for name in ("approachBall", "dribbleBall"):
        registry.register(ActionTemplate(name, _pose(0) + _pose(1, "_g")))
    return registry


def fig10_belief() -> BeliefState:
    return BeliefState(
        values={
            ("robot", "x"): 0.0, ("robot", "y"): 1.0, ("robot", "phi"): 0.0, ("robot", "v"): 0.0,
            ("ball", "x"): 3.0, ("ball", "y"): 1.0,
            ("final", "x"): 1.0, ("final", "y"): 3.0, ("final", "phi"): 2.6, ("final", "v"): 0.0,
        },
        constraints={("atball", "v"): (0.0, 0.3)},
        defaults={"x": (-4.5, 4.5), "y": (-3.0, 3.0), "phi": (-math.pi, math.pi), "v": (0.0, 1.0)},
    )  # fmt: skip


def test_fig10_plan_links_and_instantiation():
    plan = plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM)
    assert [(a.name, a.args) for a in plan.actions] == [
        ("approachball", ("pos1", "pos2")),
        ("dribbleball", ("pos2", "pos3")),
    ]
    # Figure 10's links with sequential step numbers (approach = 1, dribble = 2, goal = 3)
    assert set(plan.links) == {
        CausalLink(0, ("robot", ("pos1",)), 1),
        CausalLink(0, ("ball", ("pos2",)), 1),
        CausalLink(1, ("atball", ("pos2",)), 2),
        CausalLink(0, ("final", ("pos3",)), 2),
        CausalLink(0, ("final", ("pos3",)), 3),
        CausalLink(2, ("atball", ("pos3",)), 3),
    }
    assert plan.links_by_label() == {
        "pos1": [(0, "robot")],
        "pos2": [(0, "ball"), (1, "atball")],
        "pos3": [(0, "final"), (2, "atball")],
    }
    inst = instantiate_plan(plan, soccer_registry(), fig10_belief())
    pi = math.pi
    # Algorithm 2, below line 14
    assert inst.parameters_of(0) == {
        "x": 0.0, "y": 1.0, "phi": 0.0, "v": 0.0,
        "x_g": 3.0, "y_g": 1.0, "phi_g": Range(-pi, pi), "v_g": Range(0.0, 0.3),
    }  # fmt: skip
    assert inst.parameters_of(1) == {
        "x": 3.0, "y": 1.0, "phi": Range(-pi, pi), "v": Range(0.0, 0.3),
        "x_g": 1.0, "y_g": 3.0, "phi_g": 2.6, "v_g": 0.0,
    }  # fmt: skip
    # shared identities: approach's goal angle is the dribble's start angle
    assert inst.free_ids == ["pos2.phi", "pos2.v"]
    assert inst.actions[0].parameter_ids["phi_g"] == inst.actions[1].parameter_ids["phi"]
    assert inst.parameters_of(1, {"pos2.phi": 0.5})["phi"] == 0.5


def test_unreachable_goal_is_named():
    problem = SOCCER_PROBLEM.replace("(atball pos3))", "(atball pos3) (robot pos3))")
    with pytest.raises(PlanningError, match=r"goal \(robot pos3\) is unreachable"):
        plan_pddl(SOCCER_DOMAIN, problem)


def test_jointly_unreachable_goals_are_said_so():
    problem = SOCCER_PROBLEM.replace("(atball pos3))", "(atball pos3) (robot pos1))")
    with pytest.raises(PlanningError, match="each reachable but not together"):
        plan_pddl(SOCCER_DOMAIN, problem)


def test_bad_pddl():
    with pytest.raises(PlanningError, match="could not parse"):
        plan_pddl(SOCCER_DOMAIN, "(define (problem")
    with pytest.raises(PlanningError, match="non-empty"):
        plan_pddl(" ", SOCCER_PROBLEM)


def test_pddl_beyond_strips_is_named():
    # pyperplan has no negative preconditions or equality: a PlanningError (a ValueError)
    # naming them, not unified-planning's own exception
    domain = SOCCER_DOMAIN.replace(":typing)", ":typing :negative-preconditions)").replace(
        "(and (robot ?from) (ball ?to))", "(and (robot ?from) (ball ?to) (not (final ?to)))"
    )
    with pytest.raises(PlanningError, match=r"STRIPS with typing only.*NEGATIVE_CONDITIONS"):
        plan_pddl(domain, SOCCER_PROBLEM)


def test_causal_links_reject_invalid_sequence():
    step = GroundAction("dribbleball", ("pos2", "pos3"), (("atball", ("pos2",)),))
    with pytest.raises(PlanningError, match=r"step 1 \(dribbleball\) needs \(atball pos2\)"):
        derive_causal_links([], [step], [])


def test_causal_links_use_latest_achiever():
    a = GroundAction("a", (), (), (("p", ()),))
    b = GroundAction("b", (), (("p", ()),), (("p", ()),))
    links = derive_causal_links([("p", ())], [a, b], [("p", ())])
    assert links == (CausalLink(1, ("p", ()), 2), CausalLink(2, ("p", ()), 3))


def test_action_without_executable_counterpart():
    plan = AbstractPlan((GroundAction("kickball", ("pos1",)),), ())
    with pytest.raises(RepertoireError, match="'kickball' has no executable counterpart"):
        instantiate_plan(plan, soccer_registry(), fig10_belief())


def test_empty_ranges_are_refused():
    with pytest.raises(RepertoireError, match="empty or NaN range"):
        Range(1.0, 0.0)
    belief = fig10_belief()
    belief.constraints[("atball", "v")] = (2.0, 3.0)  # outside the default [0, 1]
    plan = plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM)
    with pytest.raises(RepertoireError, match="empty range"):
        instantiate_plan(plan, soccer_registry(), belief)


def test_template_validation():
    with pytest.raises(RepertoireError, match="unique parameter names"):
        ActionTemplate("a", (ParameterTemplate("x", "x", 0), ParameterTemplate("x", "x", 1)))
    registry = soccer_registry()
    with pytest.raises(RepertoireError, match="already registered"):
        registry.register(ActionTemplate("approachBall", ()))


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def _leg_features(p: dict) -> np.ndarray:
    """Table 7's features of a leg: dist, |angle_to|, |angle_at| and the goal speed."""
    dx, dy = p["x_g"] - p["x"], p["y_g"] - p["y"]
    heading = np.arctan2(dy, dx)
    return np.column_stack(
        [np.hypot(dx, dy), np.abs(_wrap(heading - p["phi"])), np.abs(_wrap(p["phi_g"] - heading)),
         p["v_g"]]
    )  # fmt: skip


def _fig10_plan():
    return instantiate_plan(
        plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM), soccer_registry(), fig10_belief()
    )


def _linear(coef) -> PiecewiseLinearModel:
    d = len(coef)
    return PiecewiseLinearModel([[-np.inf] * d], [[np.inf] * d], [coef], [0.5])


@pytest.mark.parametrize(
    ("part", "key", "bad", "message"),
    [
        # a NaN bound used to drop out of max/min: the range was silently unconstrained
        ("constraints", ("atball", "v"), (math.nan, 0.3), r"constraint \('atball', 'v'\) is \(nan"),
        ("constraints", ("atball", "v"), (0.1, math.nan), r"constraint \('atball', 'v'\) is \(0.1"),
        ("constraints", ("atball", "v"), (0.3, 0.1), r"is \(0.3, 0.1\); expected two numbers"),
        ("constraints", ("atball", "v"), 0.3, r"is 0.3; expected \(lo, hi\)"),
        ("defaults", "v", (math.nan, 1.0), r"default range of 'v' is \(nan, 1.0\)"),
        ("defaults", "phi", ("-pi", "pi"), r"default range of 'phi' is \('-pi', 'pi'\)"),
        ("values", ("final", "v"), math.nan, r"value \('final', 'v'\) is nan; expected a finite"),
        ("values", ("robot", "x"), math.inf, r"value \('robot', 'x'\) is inf; expected a finite"),
        ("values", ("robot", "x"), "0", r"value \('robot', 'x'\) is '0'; expected a finite"),
    ],
)
def test_bad_belief_entries_are_named(part, key, bad, message):
    belief = fig10_belief()
    getattr(belief, part)[key] = bad
    plan = plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM)
    with pytest.raises(RepertoireError, match=message):
        instantiate_plan(plan, soccer_registry(), belief)


def test_unbounded_free_parameter_is_named_by_refinement():
    belief = fig10_belief()
    belief.defaults["phi"] = (-math.inf, math.inf)  # fine for a bound phi, not for a free one
    plan = instantiate_plan(plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM), soccer_registry(), belief)
    assert plan.ranges["pos2.phi"] == Range(-math.inf, math.inf)
    assert plan.ranges["pos1.phi"] == Range(0.0, 0.0)
    models = {
        n: ActionDurationModel(_linear([0.0] * 4), _leg_features)
        for n in ("approachBall", "dribbleBall")
    }
    with pytest.raises(
        RepertoireError,
        match=r"free parameters \['pos2.phi'\] have the non-finite ranges \[\[-inf, inf\]\]",
    ):
        refinement_problem(plan, models)


def test_figure_11_refinement_of_the_instantiated_plan():
    plan = instantiate_plan(
        plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM), soccer_registry(), fig10_belief()
    )
    models = {
        # approaching: turning at the goal costs 0.8 s/rad, arriving faster saves time
        "approachBall": ActionDurationModel(_linear([1.0, 0.3, 0.8, -1.0]), _leg_features),
        # dribbling: turning towards the target costs 2 s/rad, a fast start 2 s per m/s
        "dribbleBall": ActionDurationModel(_linear([2.0, 2.0, 0.1, 2.0]), _start_speed),
    }
    problem = refinement_problem(plan, models)
    assert problem.names == ("pos2.phi", "pos2.v")
    assert [t.uses for t in problem.terms] == [(0, 1), (0, 1)]
    greedy = refine_sequence(problem, 1, "de", seed=0)
    refined = refine_sequence(problem, 2, "de", seed=0)
    ga = refine_sequence(problem, 2, "ga", seed=0)
    # greedy: arrive heading straight at the ball (phi = 0) at full speed 0.3
    np.testing.assert_allclose(greedy.params, [0.0, 0.3], atol=1e-3)
    # refined: arrive already facing the target (3 pi / 4) and slow, cheaper overall
    np.testing.assert_allclose(refined.params, [3 * np.pi / 4, 0.0], atol=1e-3)
    assert refined.cost < greedy.cost - 2.0
    assert ga.cost == pytest.approx(refined.cost, abs=0.05)


LEG_READS = (("x", "y", "x_g", "y_g"), ("x", "y", "phi", "x_g", "y_g"),
             ("x", "y", "x_g", "y_g", "phi_g"), ("v_g",))  # fmt: skip


def test_refinement_of_the_plan_stays_inside_the_approach_models_data():
    # Figure 11's plan with an approach model that saw |angle_at| <= 1 rad only: the
    # refined approach angle 3 pi / 4 (|angle_at| 2.36) is an extrapolation; inside the
    # data the dribble's 2 s/rad beat the approach's 0.8 s/rad up to the edge, phi = 1
    plan = _fig10_plan()
    domain = ([0.0, 0.0, 0.0, 0.0], [10.0, np.pi, 1.0, 0.3])
    approach = ActionDurationModel(_linear([1.0, 0.3, 0.8, -1.0]), _leg_features, domain, LEG_READS)
    dribble = ActionDurationModel(_linear([2.0, 2.0, 0.1, 2.0]), _start_speed)
    models = {"approachBall": approach, "dribbleBall": dribble}
    problem = refinement_problem(plan, models)
    assert problem.terms[0].feature_uses == ((), (), (0,), (1,))
    refined = refine_sequence(problem, 2, "de", seed=0)
    np.testing.assert_allclose(refined.params, [1.0, 0.0], atol=1e-3)
    with pytest.raises(RepertoireError, match="a duration model with a domain needs `reads`"):
        refinement_problem(plan, {**models, "approachBall": ActionDurationModel(
            approach.model, _leg_features, domain)})  # fmt: skip
    with pytest.raises(RepertoireError, match=r"`reads` names \['heading'\], not parameters"):
        refinement_problem(plan, {**models, "approachBall": ActionDurationModel(
            approach.model, _leg_features, domain, (("heading",),) * 4)})  # fmt: skip


def _start_speed(p: dict) -> np.ndarray:
    features = _leg_features(p)
    features[:, 3] = p["v"]
    return features


def test_refinement_problem_bad_input():
    plan = instantiate_plan(
        plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM), soccer_registry(), fig10_belief()
    )
    with pytest.raises(RepertoireError, match="no duration model for action 'dribbleBall'"):
        refinement_problem(
            plan, {"approachBall": ActionDurationModel(_linear([0.0] * 4), _leg_features)}
        )


def _from_left(p: dict) -> np.ndarray:
    """Failure model stand-in: the approach succeeds arriving from the left, >= 0.5 m."""
    dx, dy = p["x_g"] - p["x"], p["y_g"] - p["y"]
    return (np.abs(np.arctan2(dy, dx)) <= np.radians(30.0)) & (np.hypot(dx, dy) >= 0.5)


def test_figure_16_subgoal_inserted_into_the_plan_and_refined():
    registry = soccer_registry()
    registry.register(ActionTemplate("goToPose", _pose(0) + _pose(1, "_g")))
    belief = fig10_belief()
    belief.values[("robot", "x")] = 4.0  # right of the ball at x = 3: direct approach fails
    plan = instantiate_plan(plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM), registry, belief)
    asserted = insert_subgoal(plan, 0, registry, belief, replacement="goToPose")
    assert [(a.name, a.args) for a in asserted.actions] == [
        ("goToPose", ("pos1", "subgoal1")),
        ("goToPose", ("subgoal1", "pos2")),
        ("dribbleBall", ("pos2", "pos3")),
    ]
    assert asserted.actions[0].parameter_ids["x"] == "pos1.x"
    assert asserted.actions[1].parameter_ids["x_g"] == "pos2.x"
    assert asserted.actions[1].parameter_ids["phi"] == asserted.actions[0].parameter_ids["phi_g"]
    assert asserted.free_ids == [
        "pos2.phi", "pos2.v", "subgoal1.x", "subgoal1.y", "subgoal1.phi", "subgoal1.v"
    ]  # fmt: skip
    assert asserted.ranges["subgoal1.x"] == Range(-4.5, 4.5)
    leg = ActionDurationModel(_linear([1.0, 0.3, 0.3, 0.0]), _leg_features)
    models = {
        "goToPose": leg,
        "dribbleBall": ActionDurationModel(_linear([2, 2, 0.1, 2]), _start_speed),
    }
    problem = refinement_problem(asserted, models, succeeds={1: _from_left})
    result = refine_sequence(problem, 3, "ga", seed=1)
    values = dict(zip(problem.names, result.params, strict=True))
    sub = {"x": values["subgoal1.x"], "y": values["subgoal1.y"], "x_g": 3.0, "y_g": 1.0}
    assert _from_left({k: np.array([v]) for k, v in sub.items()})[0]
    assert np.isfinite(result.cost)
    # a subgoal the failure model rejects is INVALID (+inf), as in Algorithm 4
    bad = result.params.copy()
    bad[problem.names.index("subgoal1.x")] = 3.5
    assert problem.cost(bad)[0] == np.inf


def test_insert_subgoal_second_leg_ends_at_the_to_argument():
    # a three-argument action (from, to, ball): the legs are from -> subgoal -> to
    # (index 1, as the parameters), not -> the last argument
    registry = ActionRegistry()
    registry.register(ActionTemplate("kick", _pose(0) + _pose(1, "_g")))
    registry.register(ActionTemplate("goToPose", _pose(0) + _pose(1, "_g")))
    belief = fig10_belief()
    plan = instantiate_plan(
        AbstractPlan((GroundAction("kick", ("pos1", "pos3", "pos2")),), ()), registry, belief
    )
    asserted = insert_subgoal(plan, 0, registry, belief, replacement="goToPose")
    assert [a.args for a in asserted.actions] == [("pos1", "subgoal1"), ("subgoal1", "pos3")]
    assert asserted.actions[1].parameter_ids["x_g"] == "pos3.x"
    registry.register(ActionTemplate("wait", _pose(0)))
    one = instantiate_plan(AbstractPlan((GroundAction("wait", ("pos1",)),), ()), registry, belief)
    with pytest.raises(RepertoireError, match=r"no symbolic 'to' argument \(index 1\)"):
        insert_subgoal(one, 0, registry, belief, replacement="goToPose")


def test_insert_subgoal_bad_input():
    registry = soccer_registry()
    plan = _fig10_plan()
    with pytest.raises(RepertoireError, match="'goToPose' has no executable counterpart"):
        insert_subgoal(plan, 0, registry, fig10_belief(), replacement="goToPose")
    with pytest.raises(RepertoireError, match="already used"):
        insert_subgoal(plan, 0, registry, fig10_belief(), replacement="dribbleBall", label="pos2")
    with pytest.raises(RepertoireError, match="action index 5"):
        insert_subgoal(plan, 5, registry, fig10_belief(), replacement="dribbleBall")


KITCHEN_DOMAIN = """
(define (domain kitchen) (:requirements :strips :typing) (:types place cup)
 (:predicates (robot ?p - place) (cupat ?c - cup ?p - place) (holding ?c - cup)
              (handempty) (target ?c - cup ?p - place))
 (:action gotopose :parameters (?from ?to - place)
   :precondition (robot ?from) :effect (and (robot ?to) (not (robot ?from))))
 (:action grip :parameters (?at - place ?c - cup)
   :precondition (and (robot ?at) (cupat ?c ?at) (handempty))
   :effect (and (holding ?c) (not (cupat ?c ?at)) (not (handempty))))
 (:action put :parameters (?at - place ?c - cup)
   :precondition (and (robot ?at) (holding ?c) (target ?c ?at))
   :effect (and (cupat ?c ?at) (handempty) (not (holding ?c)))))
"""
KITCHEN_PROBLEM = """
(define (problem s1) (:domain kitchen) (:objects door table1 table2 - place cup1 - cup)
 (:init (robot door) (cupat cup1 table1) (handempty) (target cup1 table2))
 (:goal (cupat cup1 table2)))
"""


def test_kitchen_scenario_1_plan_has_four_actions_sharing_waypoints():
    plan = plan_pddl(KITCHEN_DOMAIN, KITCHEN_PROBLEM)
    assert [(a.name, a.args) for a in plan.actions] == [
        ("gotopose", ("door", "table1")),
        ("grip", ("table1", "cup1")),
        ("gotopose", ("table1", "table2")),
        ("put", ("table2", "cup1")),
    ]
    assert CausalLink(1, ("robot", ("table1",)), 2) in plan.links
    assert CausalLink(2, ("holding", ("cup1",)), 4) in plan.links
    assert CausalLink(4, ("cupat", ("cup1", "table2")), 5) in plan.links
    registry = ActionRegistry()
    registry.register(ActionTemplate("goToPose", _pose(0) + _pose(1, "_g")))
    for name in ("grip", "put"):  # the base pose where the arm works, and the reach
        registry.register(ActionTemplate(name, _pose(0) + (ParameterTemplate("d", "reach", 0),)))
    belief = BeliefState(
        values={("robot", q): 0.0 for q in ("x", "y", "phi", "v")},
        constraints={("cupat", "reach"): (0.4, 0.8), ("target", "reach"): (0.4, 0.8)},
        defaults={"x": (-3, 3), "y": (-3, 3), "phi": (-math.pi, math.pi), "v": (0, 1),
                  "reach": (0.0, 1.0)},
    )  # fmt: skip
    inst = instantiate_plan(plan, registry, belief)
    # the pose at table1 is one set of free parameters shared by goto, grip and goto
    assert inst.actions[0].parameter_ids["x_g"] == inst.actions[1].parameter_ids["x"]
    assert inst.actions[1].parameter_ids["x"] == inst.actions[2].parameter_ids["x"]
    assert inst.ranges["table1.reach"] == Range(0.4, 0.8)  # the precondition of grip
    assert len(inst.free_ids) == 10  # two 4-D waypoints and two reach distances
