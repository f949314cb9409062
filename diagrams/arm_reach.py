"""arm7 reaching with two joints (registered as ``arm_reach``).

The arm7 station of ``arm_hold`` (PD actuators plus inverse-dynamics
feed-forward, :func:`~repertoire.diagrams.arm.add_arm_station`) with the table
moved out of reach: :class:`~repertoire.systems.arm_reach.Reach` drives
``shoulder_flexion`` (joint a) and ``elbow`` (joint b), as the paper's
PowerCube arm used two of its joints; the other five hold the home pose and
the hand stays open. The target is a constant source named ``target``.
"""

import dataclasses

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import Adder, ConstantVectorSource, MatrixGain
from repertoire.diagrams.arm import ArmScenario, add_arm_controllers, add_arm_station
from repertoire.diagrams.biped import validate_control_period
from repertoire.diagrams.registry import register_diagram
from repertoire.models.arm7 import ARM_JOINTS, HAND_OPEN, ArmWorld, arm7_home_configuration
from repertoire.systems.arm_reach import REACH_GAINS, Reach
from repertoire.systems.go_to_pose import ActionStatus

from repertoire.criteria import Bound
from repertoire.errors import ScenarioError

REACH_JOINTS = ("shoulder_flexion", "elbow")
JOINT_LIMITS = (-0.9, 2.8, 0.0, 2.6)  # arm7.urdf limits of the two joints [rad]


@dataclasses.dataclass
class ReachScenario:
    """arm7 reaching with two joints.

    Attributes:
        start: ``[theta^a, thetadot^a, theta^b, thetadot^b]`` at t = 0 (Table 6).
        target: ``[theta_g^a, thetadot_g^a, theta_g^b, thetadot_g^b]``.
        time_step: plant step [s].
        control_period: Reach update period [s].
        gains: overrides of Reach's gains (``REACH_GAINS`` keys).
    """

    start: list[float] = dataclasses.field(default_factory=lambda: [0.45, 0.0, 1.45, 0.0])
    target: list[float] = dataclasses.field(default_factory=lambda: [1.2, 0.0, 0.6, 0.0])
    time_step: float = 2e-3
    control_period: float = 0.01
    gains: dict[str, float] = dataclasses.field(default_factory=dict)

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        for name in ("start", "target"):
            v = getattr(self, name)
            if len(v) != 4 or not np.all(np.isfinite(v)):
                raise ScenarioError(f"{name} must be 4 finite values, got {v}")
        lo_a, hi_a, lo_b, hi_b = JOINT_LIMITS
        if not (lo_a <= self.start[0] <= hi_a and lo_b <= self.start[2] <= hi_b):
            raise ScenarioError(
                f"start angles {self.start} outside the joint limits {JOINT_LIMITS}"
            )
        unknown = set(self.gains) - set(REACH_GAINS)
        if unknown:
            raise ScenarioError(f"unknown gains {sorted(unknown)}; expected {list(REACH_GAINS)}")
        if not (np.isfinite(self.time_step) and 0 < self.time_step <= 0.01):
            raise ScenarioError(f"time_step must be in (0, 0.01] s, got {self.time_step}")
        validate_control_period(self.control_period, self.time_step)

    def arm_scenario(self) -> ArmScenario:
        """The arm station's scenario: home pose with the two joints at the start."""
        q = arm7_home_configuration()
        q[ARM_JOINTS.index(REACH_JOINTS[0])] = self.start[0]
        q[ARM_JOINTS.index(REACH_JOINTS[1])] = self.start[2]
        return ArmScenario(
            time_step=self.time_step, initial_q=q.tolist(), world=ArmWorld(table_center=[3.0, 0.0])
        )


@register_diagram(
    "arm_reach",
    scenario_type=ReachScenario,
    description="arm7 reaching joint targets with two joints (the Reach action)",
    duration=3.0,
    check=lambda diagram, context: check_reach(diagram, context),
    criteria={"status_succeeded": Bound(1.0, 1.0), "joint_error_rad": Bound(0.0, 0.05)},
    initialize=lambda diagram, context, scenario: set_start_velocity(
        diagram, context, scenario.start[1], scenario.start[3]
    ),
)
def build_arm_reach(scenario: ReachScenario, *, meshcat=None) -> Diagram:
    """Builds arm7 with Reach driving shoulder_flexion and elbow.

    Returns:
        The Diagram ``arm_reach`` with subsystems ``plant``, ``reach``, ``target``,
        ``joint_state`` (the two joints' measured state in Table 6 order) and the
        arm station's controllers.
    """
    from repertoire.diagrams.arm import add_meshcat

    scenario.validate()
    arm_scenario = scenario.arm_scenario()
    arm_scenario.validate()
    builder = DiagramBuilder()
    station = add_arm_station(builder, arm_scenario)
    plant = station.plant
    controllers = add_arm_controllers(builder, station)
    nq, nx = plant.num_positions(), plant.num_positions() + plant.num_velocities()
    # measured [theta_a, thetadot_a, theta_b, thetadot_b] from the plant state
    S = np.zeros((4, nx))
    for k, name in enumerate(REACH_JOINTS):
        joint = plant.GetJointByName(name, station.arm)
        S[2 * k, joint.position_start()] = 1.0
        S[2 * k + 1, nq + joint.velocity_start()] = 1.0
    joint_state = builder.AddNamedSystem("joint_state", MatrixGain(S))
    reach = builder.AddNamedSystem(
        "reach",
        Reach(
            period=scenario.control_period,
            gains=scenario.gains,
            joint_limits=JOINT_LIMITS,
            initial_state=scenario.start,
        ),
    )
    target = builder.AddNamedSystem(
        "target", ConstantVectorSource(np.asarray(scenario.target, dtype=float))
    )
    # arm desired state [q_d(7), v_d(7)]: the home pose plus Reach's two joints
    ia, ib = (ARM_JOINTS.index(j) for j in REACH_JOINTS)
    M = np.zeros((14, 4))
    M[ia, 0] = M[ib, 1] = M[7 + ia, 2] = M[7 + ib, 3] = 1.0
    base = np.concatenate([arm_scenario.initial_q, np.zeros(7)])
    base[[ia, ib]] = 0.0
    to_arm = builder.AddNamedSystem("reach_to_arm", MatrixGain(M))
    held = builder.AddNamedSystem("held_joints", ConstantVectorSource(base))
    add = builder.AddNamedSystem("arm_desired", Adder(2, 14))
    hand = builder.AddNamedSystem(
        "hand_desired_state", ConstantVectorSource(np.concatenate([HAND_OPEN, np.zeros(3)]))
    )
    builder.Connect(plant.get_state_output_port(), joint_state.get_input_port())
    builder.Connect(joint_state.get_output_port(), reach.get_state_input_port())
    builder.Connect(target.get_output_port(), reach.get_target_input_port())
    builder.Connect(reach.get_desired_state_output_port(), to_arm.get_input_port())
    builder.Connect(to_arm.get_output_port(), add.get_input_port(0))
    builder.Connect(held.get_output_port(), add.get_input_port(1))
    builder.Connect(add.get_output_port(), controllers.arm_desired_state)
    builder.Connect(hand.get_output_port(), controllers.hand_desired_state)
    add_meshcat(builder, station.scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("arm_reach")
    return diagram


def set_start_velocity(diagram: Diagram, context: Context, thetadot_a: float, thetadot_b: float):
    """Gives the two joints (and Reach's reference) a start velocity in ``context``."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyMutableContextFromRoot(context)
    for name, rate in zip(REACH_JOINTS, (thetadot_a, thetadot_b)):
        plant.GetJointByName(name).set_angular_rate(pc, rate)
    reach = diagram.GetSubsystemByName("reach")
    theta = [plant.GetJointByName(n).get_angle(pc) for n in REACH_JOINTS]
    reach.start_at(reach.GetMyMutableContextFromRoot(context), theta, (thetadot_a, thetadot_b))


def reach_status(diagram: Diagram, context: Context) -> ActionStatus:
    """The Reach status in an ``arm_reach`` diagram's context."""
    reach = diagram.GetSubsystemByName("reach")
    return reach.get_status_output_port().Eval(reach.GetMyContextFromRoot(context))


def joint_state(diagram: Diagram, context: Context) -> np.ndarray:
    """``[theta^a, thetadot^a, theta^b, thetadot^b]`` measured."""
    sel = diagram.GetSubsystemByName("joint_state")
    return sel.get_output_port().Eval(sel.GetMyContextFromRoot(context))


def check_reach(diagram: Diagram, context: Context) -> dict[str, float]:
    """The world's figures: ``status_succeeded`` (1/0) and ``joint_error_rad``."""
    target = diagram.GetSubsystemByName("target")
    goal = target.get_output_port().Eval(target.GetMyContextFromRoot(context))
    s = joint_state(diagram, context)
    return {
        "status_succeeded": float(reach_status(diagram, context) == ActionStatus.SUCCEEDED),
        "joint_error_rad": float(np.hypot(goal[0] - s[0], goal[2] - s[2])),
    }
