"""Composing DMPs in diagrams: the 10-D DmpSystem and ``add_dmp``.

* :class:`DmpSystem` - a Diagram wrapping a learned DMP (an n-DOF :class:`DmpParameters`
  or the paper's 10-D :class:`TaskSpaceDmp`: position + quaternion + fingers) with goal
  inputs and optional obstacle coupling (eq. 10) on the position;
* :func:`add_dmp` - add a DmpSystem to a DiagramBuilder.

Chaining (sec. III-C) is :class:`repertoire.systems.dmp_sequencer.DmpSequencer`.
"""

import numpy as np
from pydrake.systems.framework import (
    BasicVector,
    Context,
    Diagram,
    DiagramBuilder,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Demultiplexer,
    Multiplexer,
    PassThrough,
)
from repertoire.planning.dmp import DmpParameters, TaskSpaceDmp, check_unit_quaternions
from repertoire.planning.dmp_chain import stack_task_space_dmp
from repertoire.planning.dmp_math import check_finite_vector, check_positive
from repertoire.planning.dmp_quaternion import learned_side, quaternion_rate
from repertoire.systems.dmp import (
    CanonicalSystem,
    ManifoldQuaternionSystem,
    ObstacleCoupling,
    QuaternionGoalSign,
    QuaternionNormalizer,
    TransformationSystem,
    goal_input,
)
from repertoire.systems.dmp_discrete import DiscreteDmpSystem

from repertoire.errors import RepertoireError


class GoalMultiplexer(LeafSystem):
    """A Multiplexer whose unconnected inputs stand for given values (the learned goals).

    The fused 10-D DMP takes one stacked goal; this joins the parts' goal inputs into it, so
    an unconnected part (say ``goal_fingers``) keeps its learned goal, as an unconnected
    goal of a single DMP does (:func:`repertoire.systems.dmp.goal_input`).

    Input ports:
        goal_0 .. goal_{k-1} (the size of ``defaults[i]``): the parts' goals; unconnected:
            ``defaults[i]``.

    Output ports:
        goal (the sizes summed): the parts in order.
    """

    def __init__(self, defaults: "list[np.ndarray]") -> None:
        super().__init__()
        self._defaults = [np.array(d, dtype=float).reshape(-1) for d in defaults]
        if not self._defaults or any(d.size == 0 for d in self._defaults):
            raise RepertoireError("GoalMultiplexer needs one non-empty default per input")
        self._ports = [
            self.DeclareVectorInputPort(f"goal_{i}", d.size) for i, d in enumerate(self._defaults)
        ]
        n = sum(d.size for d in self._defaults)
        self.DeclareVectorOutputPort("goal", n, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(
            np.concatenate(
                [
                    goal_input(p, context, d)
                    for p, d in zip(self._ports, self._defaults, strict=True)
                ]
            )
        )


class _VectorDmp:
    """Builder-side handle of one vector DMP (discrete fused or continuous pair)."""

    def __init__(
        self,
        builder: DiagramBuilder,
        dmp: DmpParameters,
        time_step: float | None,
        coupling: bool,
        name: str,
        canonical: CanonicalSystem | None = None,
    ) -> None:
        self.time_step = time_step
        self.tau = dmp.tau
        if time_step is not None:
            self.system = builder.AddNamedSystem(
                name, DiscreteDmpSystem(dmp, time_step=time_step, coupling_input=coupling)
            )
            self.phase = self.system.get_phase_output_port()
            self.canonical = None
        else:
            if canonical is None:
                canonical = builder.AddNamedSystem(
                    name + "_canonical", CanonicalSystem(dmp.tau, dmp.alpha)
                )
            self.canonical = canonical
            self.system = builder.AddNamedSystem(
                name, TransformationSystem(dmp, coupling_input=coupling)
            )
            builder.Connect(canonical.get_phase_output_port(), self.system.get_phase_input_port())
            self.phase = canonical.get_phase_output_port()


class DmpSystem(Diagram):
    """A learned DMP as a Diagram with goal inputs (the paper's Fig. 7 when 10-D).

    For a :class:`DmpParameters` (n DOF):

    Input ports:
        goal (n).
        obstacle (n, only with ``obstacle_avoidance=True``; needs n == 2 or 3): eq. 10 on
            the position with the paper's ``v = tau dx/dt`` (the DMP's tau), so the path
            around the obstacle is the same at any tau.
        obstacle_velocity (n, only with ``obstacle_avoidance=True``, optional): the
            obstacle's velocity; eq. 10's angle is taken to the velocity relative to it
            (unconnected: a static obstacle).

    Output ports:
        position (n), velocity (n), acceleration (n), phase (1).

    For a :class:`TaskSpaceDmp` (position 3 + quaternion 4 + k fingers, one phase):

    Input ports:
        goal_position (3): p_WE goal [m].
        goal_orientation (4): goal quaternion (w, x, y, z), either sign: both modes turn
            the learned way round (also past 180 deg). The on-manifold part lifts it
            relative to the start; so does the component part (R^4,
            :class:`repertoire.systems.dmp.QuaternionGoalSign`), which starts on
            the learned start's side: :meth:`set_start` negates an orientation with
            ``q0 . dmp.orientation.q0 < 0`` (the same orientation; the output then has the
            learned side's sign).
        goal_fingers (k, if the DMP has fingers).
        obstacle (3, only with ``obstacle_avoidance=True``): obstacle position p_WO.
        obstacle_velocity (3, only with ``obstacle_avoidance=True``, optional): its
            velocity (unconnected: a static obstacle).

    Output ports:
        position (3), velocity (3), acceleration (3), orientation (4, unit),
        angular_velocity (3, world frame), fingers (k), finger_velocity (k), phase (1).

    With ``time_step`` (default 1 ms) the vector parts are exact discrete-time
    :class:`DiscreteDmpSystem`s (for a TaskSpaceDmp fused into one 10-D system, the paper's
    Fig. 7, with multiplexed goals); with ``time_step=None`` they are continuous
    :class:`CanonicalSystem` + :class:`TransformationSystem` pairs. The on-manifold
    quaternion part is always discrete (``time_step`` or 1 ms).

    Every goal input may be left unconnected: it then stands for the learned goal (the
    demonstration's last sample), so an unwired DmpSystem reproduces its demonstration.
    """

    def __init__(
        self,
        dmp: DmpParameters | TaskSpaceDmp,
        *,
        time_step: float | None = 1e-3,
        obstacle_avoidance: bool = False,
        gamma: float = 1000.0,
        beta: float = 20.0 / np.pi,
    ) -> None:
        super().__init__()
        if time_step is not None:
            check_positive("time_step", time_step)
        if not isinstance(obstacle_avoidance, (bool, np.bool_)):
            raise RepertoireError(
                f"obstacle_avoidance must be True or False, got {obstacle_avoidance!r}"
            )
        self.dmp = dmp
        self._fused = None
        self._manifold = None
        self._goal_sign = None
        self._slices: dict = {}
        builder = DiagramBuilder()
        if isinstance(dmp, DmpParameters):
            self._build_vector(builder, dmp, time_step, obstacle_avoidance, gamma, beta)
        elif isinstance(dmp, TaskSpaceDmp):
            self._build_task_space(builder, dmp, time_step, obstacle_avoidance, gamma, beta)
        else:
            raise RepertoireError(
                f"DmpSystem needs DmpParameters or TaskSpaceDmp, got {type(dmp).__name__}"
            )
        builder.BuildInto(self)

    # ------------------------------------------------------------------ building
    def _coupling(
        self, builder, position, velocity, tau: float, gamma: float, beta: float
    ) -> OutputPort:
        """Adds eq. 10 on a DMP's position and velocity outputs; returns its coupling port.

        Exports the ``obstacle`` and ``obstacle_velocity`` inputs (the one place both the
        vector and the fused task-space DmpSystem wire the coupling).

        Args:
            builder: The DmpSystem's builder.
            position: The position output port (2-D or 3-D).
            velocity: The matching velocity output port.
            tau: The DMP's temporal scaling [s] (eq. 10 turns ``tau`` times the velocity).
            gamma: Gain of eq. 10.
            beta: Angular decay of eq. 10.
        """
        obs = builder.AddNamedSystem(
            "obstacle_coupling", ObstacleCoupling(gamma, beta, n_dims=position.size(), tau=tau)
        )
        builder.Connect(position, obs.GetInputPort("position"))
        builder.Connect(velocity, obs.GetInputPort("velocity"))
        builder.ExportInput(obs.GetInputPort("obstacle"), "obstacle")
        builder.ExportInput(obs.GetInputPort("obstacle_velocity"), "obstacle_velocity")
        self.obstacle_coupling = obs
        return obs.GetOutputPort("coupling")

    def _build_vector(self, builder, dmp, time_step, obstacle, gamma, beta) -> None:
        if obstacle and dmp.n_dims not in (2, 3):
            raise RepertoireError(f"obstacle avoidance needs a 2-D or 3-D DMP, got {dmp.n_dims}-D")
        vec = _VectorDmp(builder, dmp, time_step, obstacle, "dmp")
        self._parts = {"position": vec}
        self._export_position(builder, vec, "goal", obstacle, gamma, beta)
        builder.ExportOutput(vec.phase, "phase")

    def _export_position(self, builder, vec: _VectorDmp, goal: str, obstacle, gamma, beta) -> None:
        """Exports the goal input and the three vector outputs (with coupling if asked)."""
        builder.ExportInput(vec.system.get_goal_input_port(), goal)
        if obstacle:
            sys = vec.system
            coupling = self._coupling(
                builder,
                sys.get_position_output_port(),
                sys.get_velocity_output_port(),
                vec.tau,
                gamma,
                beta,
            )
            builder.Connect(coupling, sys.get_coupling_input_port())
        builder.ExportOutput(vec.system.get_position_output_port(), "position")
        builder.ExportOutput(vec.system.get_velocity_output_port(), "velocity")
        builder.ExportOutput(vec.system.get_acceleration_output_port(), "acceleration")

    def _build_fused(self, builder, dmp: TaskSpaceDmp, time_step, obstacle, gamma, beta) -> bool:
        """All vector parts in one DiscreteDmpSystem (one Python call per step)."""
        try:
            stacked = stack_task_space_dmp(dmp)
        except RepertoireError:  # parts on different bases or formulations: one system each
            return False
        fused = stacked.parameters
        self._stacked_v0 = fused.v0
        self._slices = stacked.slices
        parts = list(stacked.slices)
        sizes = [sl.stop - sl.start for sl in stacked.slices.values()]
        n = sum(sizes)
        sysd = builder.AddNamedSystem(
            "task_space_dmp", DiscreteDmpSystem(fused, time_step=time_step, coupling_input=obstacle)
        )
        self._fused = sysd
        mux = builder.AddNamedSystem(
            "goal_mux", GoalMultiplexer([fused.goal[sl] for sl in stacked.slices.values()])
        )
        builder.Connect(mux.get_output_port(0), sysd.get_goal_input_port())
        demux = {}
        for sig, port in (
            ("position", sysd.get_position_output_port()),
            ("velocity", sysd.get_velocity_output_port()),
            ("acceleration", sysd.get_acceleration_output_port()),
        ):
            demux[sig] = builder.AddNamedSystem(f"{sig}_demux", Demultiplexer(sizes))
            builder.Connect(port, demux[sig].get_input_port(0))
        index = {name: i for i, name in enumerate(parts)}
        builder.ExportInput(mux.get_input_port(index["position"]), "goal_position")
        for sig in ("position", "velocity", "acceleration"):
            builder.ExportOutput(demux[sig].get_output_port(index["position"]), sig)
        if obstacle:  # on the position block; 0 on the others
            coupling = self._coupling(
                builder,
                demux["position"].get_output_port(index["position"]),
                demux["velocity"].get_output_port(index["position"]),
                fused.tau,
                gamma,
                beta,
            )
            pad = builder.AddNamedSystem("coupling_mux", Multiplexer([3, n - 3]))
            zeros = builder.AddNamedSystem("coupling_zeros", ConstantVectorSource(np.zeros(n - 3)))
            builder.Connect(coupling, pad.get_input_port(0))
            builder.Connect(zeros.get_output_port(), pad.get_input_port(1))
            builder.Connect(pad.get_output_port(0), sysd.get_coupling_input_port())
        if "orientation" in index:
            i = index["orientation"]
            norm = builder.AddNamedSystem("quaternion_normalizer", QuaternionNormalizer())
            builder.Connect(demux["position"].get_output_port(i), norm.get_quaternion_input_port())
            builder.Connect(
                demux["velocity"].get_output_port(i), norm.get_quaternion_rate_input_port()
            )
            sign = builder.AddNamedSystem("goal_sign", QuaternionGoalSign(dmp.orientation))
            self._goal_sign = sign
            builder.Connect(sign.GetOutputPort("goal"), mux.get_input_port(i))
            builder.ExportInput(sign.GetInputPort("goal"), "goal_orientation")
            builder.ExportOutput(norm.get_orientation_output_port(), "orientation")
            builder.ExportOutput(norm.get_angular_velocity_output_port(), "angular_velocity")
        else:
            man = builder.AddNamedSystem(
                "orientation_dmp", ManifoldQuaternionSystem(dmp.orientation, time_step=time_step)
            )
            builder.Connect(sysd.get_phase_output_port(), man.get_phase_input_port())
            builder.ExportInput(man.get_goal_input_port(), "goal_orientation")
            builder.ExportOutput(man.get_orientation_output_port(), "orientation")
            builder.ExportOutput(man.get_angular_velocity_output_port(), "angular_velocity")
            self._manifold = man
        if "fingers" in index:
            i = index["fingers"]
            builder.ExportInput(mux.get_input_port(i), "goal_fingers")
            builder.ExportOutput(demux["position"].get_output_port(i), "fingers")
            builder.ExportOutput(demux["velocity"].get_output_port(i), "finger_velocity")
        phase = builder.AddNamedSystem("phase", PassThrough(1))
        builder.Connect(sysd.get_phase_output_port(), phase.get_input_port())
        builder.ExportOutput(phase.get_output_port(), "phase")
        self._parts = {}
        return True

    def _build_task_space(self, builder, dmp: TaskSpaceDmp, time_step, obstacle, gamma, beta):
        if time_step is not None and self._build_fused(
            builder, dmp, time_step, obstacle, gamma, beta
        ):
            return
        pos = _VectorDmp(builder, dmp.position, time_step, obstacle, "position_dmp")
        self._parts = {"position": pos}
        self._export_position(builder, pos, "goal_position", obstacle, gamma, beta)
        ori = dmp.orientation
        if ori.mode == "component":
            comp = _VectorDmp(
                builder,
                ori.component_parameters(),
                time_step,
                False,
                "orientation_dmp",
                canonical=pos.canonical,
            )
            norm = builder.AddNamedSystem("quaternion_normalizer", QuaternionNormalizer())
            builder.Connect(
                comp.system.get_position_output_port(), norm.get_quaternion_input_port()
            )
            builder.Connect(
                comp.system.get_velocity_output_port(), norm.get_quaternion_rate_input_port()
            )
            sign = builder.AddNamedSystem("goal_sign", QuaternionGoalSign(ori))
            self._goal_sign = sign
            builder.Connect(sign.GetOutputPort("goal"), comp.system.get_goal_input_port())
            builder.ExportInput(sign.GetInputPort("goal"), "goal_orientation")
            builder.ExportOutput(norm.get_orientation_output_port(), "orientation")
            builder.ExportOutput(norm.get_angular_velocity_output_port(), "angular_velocity")
            self._parts["orientation"] = comp
        else:
            man = builder.AddNamedSystem(
                "orientation_dmp",
                ManifoldQuaternionSystem(ori, time_step=time_step or 1e-3),
            )
            builder.Connect(pos.phase, man.get_phase_input_port())
            builder.ExportInput(man.get_goal_input_port(), "goal_orientation")
            builder.ExportOutput(man.get_orientation_output_port(), "orientation")
            builder.ExportOutput(man.get_angular_velocity_output_port(), "angular_velocity")
            self._parts["orientation"] = man
        if dmp.fingers is not None:
            fin = _VectorDmp(
                builder, dmp.fingers, time_step, False, "finger_dmp", canonical=pos.canonical
            )
            builder.ExportInput(fin.system.get_goal_input_port(), "goal_fingers")
            builder.ExportOutput(fin.system.get_position_output_port(), "fingers")
            builder.ExportOutput(fin.system.get_velocity_output_port(), "finger_velocity")
            self._parts["fingers"] = fin
        phase = builder.AddNamedSystem("phase", PassThrough(1))
        builder.Connect(pos.phase, phase.get_input_port())
        builder.ExportOutput(phase.get_output_port(), "phase")

    # ------------------------------------------------------------------ context helpers
    def _subsystems(self):
        if self._fused is not None:
            yield self._fused
            if self._manifold is not None:
                yield self._manifold
            return
        for part in self._parts.values():
            if isinstance(part, _VectorDmp):
                yield part.system
                if part.canonical is not None:
                    yield part.canonical
            else:
                yield part

    def set_start(
        self,
        context: Context,
        position: np.ndarray | None = None,
        velocity: np.ndarray | None = None,
        orientation: np.ndarray | None = None,
        fingers: np.ndarray | None = None,
    ) -> None:
        """Restart the whole DMP: phase 1, every part at its start (the equations' x0).

        A part given here starts there; a part not given restarts from the start it had
        (the learned one in a fresh context). Every part starts with its learned velocity
        unless ``velocity`` is given. So the discrete and continuous variants restart alike
        (before, the continuous ones kept the decayed phase, and parts not given ran on).

        Args:
            context: This diagram's context (``dmp_system.GetMyMutableContextFromRoot``).
            position: Start of the position part (or of the n-DOF DMP).
            velocity: Initial velocity of that part; default the learned one (``v0``;
                every part starts with its demonstration's velocity, the orientation with
                ``omega0``).
            orientation: Start quaternion (TaskSpaceDmp only).
            fingers: Start finger positions (TaskSpaceDmp only).
        """
        if self._fused is not None:
            self._set_start_fused(context, position, velocity, orientation, fingers)
            return
        given = {"position": position, "orientation": orientation, "fingers": fingers}
        for name, value in given.items():
            if value is not None and name not in self._parts:
                raise RepertoireError(f"this DMP has no {name} part")
        for name, part in self._parts.items():
            system = part.system if isinstance(part, _VectorDmp) else part
            sub = self.GetMutableSubsystemContext(system, context)
            start = given[name]
            if start is None:
                start = system.get_start(sub)
            if name == "position":
                system.set_start(sub, start, velocity)
            elif name == "fingers":
                system.set_start(sub, start)
            elif isinstance(part, _VectorDmp):  # component orientation
                q = self._component_start(context, check_finite_vector("orientation", start, 4))
                system.set_start(sub, q, quaternion_rate(self.dmp.orientation.omega0, q))
            else:
                system.set_start(sub, start)
            if isinstance(part, _VectorDmp) and part.canonical is not None:
                part.canonical.set_phase(self.GetMutableSubsystemContext(part.canonical, context))

    def _component_start(self, context: Context, q: np.ndarray) -> np.ndarray:
        """``q`` or ``-q`` (one orientation): the sign on the learned start's side.

        The component quaternion DMP runs in R^4 with the forcing term learned from the
        learned start, so it starts from the sign with ``q . q0_learned >= 0``, and its
        goal's sign is chosen from that start (as
        :meth:`repertoire.planning.dmp.QuaternionDmpParameters.rollout` does).
        """
        # unit, as the on-manifold part's start (an R^4 start off the sphere ran silently)
        check_unit_quaternions(q[None], name="start orientation")
        q = learned_side(q, self.dmp.orientation.q0) * q
        sign = self._goal_sign
        sign.set_start(self.GetMutableSubsystemContext(sign, context), q)
        return q

    def _set_start_fused(self, context, position, velocity, orientation, fingers) -> None:
        sysd = self._fused
        sub = self.GetMutableSubsystemContext(sysd, context)
        x0 = sysd.get_start(sub)
        xd0 = self._stacked_v0.copy()  # the learned start velocities
        given = {"position": position, "orientation": orientation, "fingers": fingers}
        if self._manifold is not None:  # restarted too, from its start if none is given
            sub_m = self.GetMutableSubsystemContext(self._manifold, context)
            q = self._manifold.get_start(sub_m) if orientation is None else orientation
            self._manifold.set_start(sub_m, check_finite_vector("orientation", q, 4))
        for name, value in given.items():
            if value is None or (name == "orientation" and self._manifold is not None):
                continue
            if name not in self._slices:
                raise RepertoireError(f"this DMP has no {name} part")
            sl = self._slices[name]
            x0[sl] = check_finite_vector(name, value, sl.stop - sl.start)
            if name == "orientation":
                x0[sl] = self._component_start(context, x0[sl])
        learned = np.ones(xd0.size, dtype=bool)  # scaled to the goal at the onset (old form)
        if velocity is not None:
            sl = self._slices["position"]
            xd0[sl] = check_finite_vector("velocity", velocity, sl.stop - sl.start)
            learned[sl] = False
        if "orientation" in self._slices:  # the learned turn rate at the start: omega0 q / 2
            sl = self._slices["orientation"]
            xd0[sl] = quaternion_rate(self.dmp.orientation.omega0, x0[sl])
            learned[sl] = False
        sysd.set_start(sub, x0, xd0, learned=learned)

    def set_start_time(self, context: Context, start_time: float) -> None:
        """Hold the whole DMP (phase 1, start state) until ``start_time``.

        Args:
            context: This diagram's context.
            start_time: Movement onset [s].
        """
        for sys in self._subsystems():
            sys.set_start_time(self.GetMutableSubsystemContext(sys, context), start_time)


def add_dmp(
    builder: DiagramBuilder,
    dmp: DmpParameters | TaskSpaceDmp,
    *,
    name: str = "dmp",
    time_step: float | None = 1e-3,
    obstacle_avoidance: bool = False,
    gamma: float = 1000.0,
    beta: float = 20.0 / np.pi,
) -> DmpSystem:
    """Add a learned DMP to ``builder`` as a named :class:`DmpSystem`.

    Args:
        builder: The DiagramBuilder.
        dmp: DmpParameters (n-D) or TaskSpaceDmp (the paper's 10-D setup).
        name: System name.
        time_step: Discrete update period [s] (exact discretisation); None = continuous.
        obstacle_avoidance: Add eq. 10 coupling on the position with an ``obstacle`` input.
        gamma: Coupling gain.
        beta: Coupling angular decay.

    Returns:
        The added DmpSystem; its ports are named as in its docstring.
    """
    if not (isinstance(name, str) and name):
        raise RepertoireError(f"name must be a non-empty string, got {name!r}")
    system = DmpSystem(
        dmp,
        time_step=time_step,
        obstacle_avoidance=obstacle_avoidance,
        gamma=gamma,
        beta=beta,
    )
    system.set_name(name)
    return builder.AddSystem(system)


__all__ = ["DmpSystem", "GoalMultiplexer", "add_dmp"]
