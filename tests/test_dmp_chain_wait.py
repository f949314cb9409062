"""DmpSequencer's waits: a segment that starts only once its predecessor has converged."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.planning.dmp import DmpParameters
from repertoire.planning.dmp_math import basis_centres, basis_widths
from repertoire.systems.dmp_sequencer import DmpSequencer

from repertoire.errors import RepertoireError

K, D, TAU = 100.0, 20.0, 0.5
GOALS = [np.array([1.0]), np.array([2.0]), np.array([3.0])]
TIMES = [0.0, 0.6, 1.2]


def _flat_dmp() -> DmpParameters:
    """A 1-D DMP with zero weights (f = 0): with a constant coupling p it rests at g + p / K."""
    c = basis_centres(5, 3.0)
    return DmpParameters(
        np.zeros((1, 5)), c, basis_widths(c, 3.0), np.full(1, K), np.full(1, D), 3.0, TAU,
        np.zeros(1), np.ones(1),
    )  # fmt: skip


def _sequencer(coupling: float, times=TIMES, **waits) -> tuple[DmpSequencer, Simulator]:
    seq = DmpSequencer(
        [_flat_dmp()] * 3, times, goals=GOALS, time_step=None, coupling_dofs=1, **waits
    )
    context = seq.CreateDefaultContext()
    seq.GetInputPort("coupling").FixValue(context, [coupling])
    simulator = Simulator(seq, context)
    simulator.get_mutable_integrator().set_target_accuracy(1e-9)
    return seq, simulator


def _segment_at(seq: DmpSequencer, simulator: Simulator, t: float) -> int:
    simulator.AdvanceTo(t)
    return int(seq.GetOutputPort("segment").Eval(simulator.get_context())[0])


def test_a_segment_held_off_its_goal_delays_its_successor_by_max_wait_and_shifts_the_rest():
    """A coupling of -5 holds segment 0 at 1 - 5 / K = 0.95, 5 cm short of its goal."""
    # before: segment 1 starts on time, from 5 cm short
    seq, simulator = _sequencer(-5.0)
    assert _segment_at(seq, simulator, 0.61) == 1
    # after: it waits for 1 cm, at most 0.3 s, then starts anyway; segment 2 starts 0.3 s late
    seq, simulator = _sequencer(-5.0, wait_tolerances=[None, 0.01, None], max_wait=0.3)
    assert _segment_at(seq, simulator, 0.89) == 0
    x = seq.GetOutputPort("position").Eval(simulator.get_context())[0]
    assert 1.0 - x > 0.05  # p / K short, and the phase term not yet gone
    assert _segment_at(seq, simulator, 0.905) == 1
    delay = seq.GetOutputPort("start_delay").Eval(simulator.get_context())[0]
    assert delay == pytest.approx(0.3, abs=1e-12)
    assert _segment_at(seq, simulator, 1.49) == 1
    assert _segment_at(seq, simulator, 1.505) == 2


def test_a_segment_starts_at_the_first_check_where_its_predecessor_is_within_tolerance():
    """No coupling: segment 0 converges; segment 1 (due at 0.6 s) starts when it is 1 mm off."""
    seq, simulator = _sequencer(0.0, wait_tolerances=[None, 0.001, None], max_wait=1.0)
    gaps = []
    while _segment_at(seq, simulator, simulator.get_context().get_time() + 1e-3) == 0:
        gaps.append(1.0 - seq.GetOutputPort("position").Eval(simulator.get_context())[0])
    switched = simulator.get_context().get_time()
    assert switched > 0.6 + 1e-3  # it waited
    assert gaps[-2] > 0.001 >= gaps[-1]  # ... exactly until the first check within 1 mm
    delay = seq.GetOutputPort("start_delay").Eval(simulator.get_context())[0]
    assert delay == pytest.approx(switched - 1e-3 - 0.6, abs=1e-9)


def test_a_converged_predecessor_starts_its_successor_on_time_as_without_waits():
    outputs = []
    for waits in ({}, {"wait_tolerances": [None, 0.5, 0.5], "max_wait": 1.0}):
        seq, simulator = _sequencer(0.0, **waits)
        simulator.AdvanceTo(1.7)
        context = simulator.get_context()
        assert seq.GetOutputPort("start_delay").Eval(context)[0] == 0.0
        outputs.append(seq.GetOutputPort("position").Eval(context).copy())
    np.testing.assert_array_equal(outputs[0], outputs[1])


def test_a_start_time_between_two_checks_is_no_wait():
    """Segment 1 is due at 0.6005 s, between the 1 ms checks: it starts at 0.601 s, as without
    waits, and segment 2 still starts at 1.2 s (the half step was counted as a delay once)."""
    seq, simulator = _sequencer(
        0.0, times=[0.0, 0.6005, 1.2], wait_tolerances=[None, 0.5, None], max_wait=1.0
    )
    assert _segment_at(seq, simulator, 0.6005) == 0
    assert _segment_at(seq, simulator, 0.6015) == 1
    assert seq.GetOutputPort("start_delay").Eval(simulator.get_context())[0] == 0.0
    assert _segment_at(seq, simulator, 1.1995) == 1
    assert _segment_at(seq, simulator, 1.2005) == 2


def test_bad_waits_are_refused_naming_them():
    segments = [_flat_dmp()] * 3
    with pytest.raises(RepertoireError, match=r"one entry per segment \(3\), got 2"):
        DmpSequencer(segments, TIMES, time_step=None, wait_tolerances=[None, 0.1])
    with pytest.raises(RepertoireError, match=r"wait_tolerances\[1\] must be None or a number"):
        DmpSequencer(segments, TIMES, time_step=None, wait_tolerances=[None, -0.1, None])
    with pytest.raises(RepertoireError, match="max_wait must be finite and >= 0"):
        DmpSequencer(segments, TIMES, time_step=None, max_wait=float("nan"))
    with pytest.raises(RepertoireError, match="wait_dofs must be a slice"):
        DmpSequencer(segments, TIMES, time_step=None, wait_dofs=slice(3, 5))
    with pytest.raises(RepertoireError, match="need the continuous mode"):
        DmpSequencer(segments, TIMES, time_step=1e-3, wait_tolerances=[None, 0.1, None])


def _gated(gate: float, max_wait: float = 0.3) -> tuple[DmpSequencer, Simulator]:
    seq, simulator = _sequencer(0.0, start_gates=[False, True, False], max_wait=max_wait)
    seq.GetInputPort("start_gate").FixValue(simulator.get_mutable_context(), [gate])
    return seq, simulator


def test_a_gated_segment_starts_when_its_gate_opens_and_shifts_the_rest():
    """Segment 1 (due at 0.6 s) waits for the start_gate input, whatever its predecessor's
    state (converged here); opened at 0.75 s it starts at that check, segment 2 0.15 s late."""
    seq, simulator = _gated(0.0)
    assert _segment_at(seq, simulator, 0.7495) == 0
    seq.GetInputPort("start_gate").FixValue(simulator.get_mutable_context(), [1.0])
    assert _segment_at(seq, simulator, 0.7505) == 1
    delay = seq.GetOutputPort("start_delay").Eval(simulator.get_context())[0]
    assert delay == pytest.approx(0.15, abs=1e-9)
    assert _segment_at(seq, simulator, 1.3495) == 1
    assert _segment_at(seq, simulator, 1.3505) == 2


def test_a_gate_that_never_opens_starts_its_segment_after_max_wait():
    seq, simulator = _gated(0.0, max_wait=0.3)
    assert _segment_at(seq, simulator, 0.8995) == 0
    assert _segment_at(seq, simulator, 0.9005) == 1
    assert seq.GetOutputPort("start_delay").Eval(simulator.get_context())[0] == pytest.approx(
        0.3, abs=1e-9
    )


def test_an_open_gate_starts_on_time_as_without_gates():
    outputs = []
    for gated in (False, True):
        seq, simulator = _gated(1.0) if gated else _sequencer(0.0)
        simulator.AdvanceTo(1.7)
        context = simulator.get_context()
        assert seq.GetOutputPort("start_delay").Eval(context)[0] == 0.0
        outputs.append(seq.GetOutputPort("position").Eval(context).copy())
    np.testing.assert_array_equal(outputs[0], outputs[1])


def test_bad_gates_are_refused_naming_them():
    segments = [_flat_dmp()] * 3
    with pytest.raises(RepertoireError, match=r"start_gates needs one entry per segment \(3\)"):
        DmpSequencer(segments, TIMES, time_step=None, start_gates=[False, True])
    with pytest.raises(RepertoireError, match=r"start_gates\[1\] must be True or False, got 1"):
        DmpSequencer(segments, TIMES, time_step=None, start_gates=[False, 1, False])
    with pytest.raises(RepertoireError, match=r"start_gates\[0\] must be False"):
        DmpSequencer(segments, TIMES, time_step=None, start_gates=[True, False, False])
    with pytest.raises(RepertoireError, match="start_gates need the continuous mode"):
        DmpSequencer(segments, TIMES, time_step=1e-3, start_gates=[False, True, False])
    seq = DmpSequencer(
        segments, TIMES, time_step=None, start_gates=[False, True, False], max_wait=1.0
    )
    simulator = Simulator(seq)
    with pytest.raises(RepertoireError, match="start_gate input is not connected"):
        simulator.AdvanceTo(0.65)
    seq, simulator = _gated(float("nan"))
    with pytest.raises(RepertoireError, match="start_gate input contains NaN"):
        simulator.AdvanceTo(0.65)
