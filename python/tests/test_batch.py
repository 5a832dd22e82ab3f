"""Batched closed loops (cartesian_impedance.sim.BatchRunner, run_many): C++ threads with the GIL
released, each pair bit for bit where sim.run(loop, seconds) takes it alone; errors name the pair
and run nothing."""

import _thread
import threading
import time

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_URDF, PANDA_XML, PANDA_READY, requires_sim

pytestmark = requires_sim


def arm(panda, engine="mujoco", timestep=0.001):
    """A started (Simulation, ControlLoop) pair of the Panda."""
    if engine == "dart":
        sim = ci.sim.Simulation.from_urdf_file(PANDA_URDF, engine="dart", start_q=PANDA_READY,
                                               joint_names=panda.joint_names, timestep=timestep)
    else:
        sim = ci.sim.Simulation.from_mjcf_file(PANDA_XML, timestep=timestep)
    loop = ci.ControlLoop(panda, {"stiffness.translation": 600})
    loop.start(sim.q, sim.dq)
    return sim, loop


def kinds():
    found = [("mujoco", 0.001), ("mujoco", 0.002), ("mujoco", 0.001)]
    if ci.sim.engine_available("dart")[0]:
        found.append(("dart", 0.001))
    return found


def command(loop, index, call):
    # Each pair and each call its own reference, so that a mix-up shows.
    pose = loop.state.controller.pose
    offset = [0.02 * (index + 1), -0.01 * call, 0.015 * (call % 2)]
    loop.set_reference_pose((pose.position + offset, pose.orientation))


def assert_same(alone, batched, where):
    (sim_a, loop_a), (sim_b, loop_b) = alone, batched
    assert sim_b.time == sim_a.time, where
    for name in ("q", "dq", "torque"):
        assert np.array_equal(getattr(sim_b, name), getattr(sim_a, name)), (where, name)
    assert np.array_equal(loop_b.state.controller.tau, loop_a.state.controller.tau), where
    assert loop_b.state.cycle == loop_a.state.cycle, where


def test_batch_ends_each_pair_bit_for_bit_where_sim_run_takes_it_alone(panda):
    alone = [arm(panda, *kind) for kind in kinds()]
    batched = [arm(panda, *kind) for kind in kinds()]
    # spin=0: the pool sleeps between runs (C++'s test measures it); the results are the same.
    batch = ci.sim.BatchRunner([s for s, _ in batched], [l for _, l in batched], threads=2,
                               spin=0)
    assert len(batch) == len(batched) and batch.threads == 2 and batch.spin == 0.0
    assert batch.sims[1] is batched[1][0] and batch.loops[2] is batched[2][1]
    for call, seconds in enumerate([0.3, 0.2, 0.25]):
        for i in range(len(alone)):
            command(alone[i][1], i, call)
            command(batched[i][1], i, call)
            alone[i][0].run(alone[i][1], seconds)
        steps = batch.run(seconds)
        assert steps.dtype == np.int64
        assert list(steps) == [round(seconds / s.timestep) for s, _ in batched]
        for i in range(len(alone)):
            assert_same(alone[i], batched[i], "pair %d, call %d" % (i, call))
    for sim, loop in batched:  # the runs moved the arms, without a fault
        assert loop.state.controller.status == ci.Status.ok
        assert np.linalg.norm(sim.dq) > 0


def test_run_many_is_the_same_in_one_call(panda):
    alone = [arm(panda) for _ in range(3)]
    batched = [arm(panda) for _ in range(3)]
    for i in range(3):
        command(alone[i][1], i, 0)
        command(batched[i][1], i, 0)
        alone[i][0].run(alone[i][1], 0.2)
    steps = ci.sim.run_many([s for s, _ in batched], [l for _, l in batched], 0.2)
    assert list(steps) == [200, 200, 200]
    for i in range(3):
        assert_same(alone[i], batched[i], "pair %d" % i)


def test_errors_name_the_pair_and_nothing_runs(panda):
    pairs = [arm(panda) for _ in range(3)]
    sims, loops = [s for s, _ in pairs], [l for _, l in pairs]
    unstarted = ci.ControlLoop(panda)
    with pytest.raises(ci.Error, match=r"^pair 2: the control loop has not been started"):
        ci.sim.run_many(sims, loops[:2] + [unstarted], 0.1)
    iiwa = ci.RobotModel.from_urdf_file(
        PANDA_URDF.parents[1] / "iiwa14" / "iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee")
    iiwa_loop = ci.ControlLoop(iiwa)
    with pytest.raises(ci.Error, match=r"^pair 1: the simulation exchanges joints"):
        ci.sim.BatchRunner(sims, [loops[0], iiwa_loop, loops[2]])
    with pytest.raises(ci.Error, match=r"^pair 2: its simulation is also pair 0's"):
        ci.sim.BatchRunner([sims[0], sims[1], sims[0]], loops)
    with pytest.raises(ci.Error, match=r"^sims has 3 entries but loops has 2"):
        ci.sim.BatchRunner(sims, loops[:2])
    with pytest.raises(TypeError, match=r"^sims\[1\] must be a cartesian_impedance.sim.Simulation"):
        ci.sim.BatchRunner([sims[0], "sim"], loops[:2])
    with pytest.raises(TypeError, match=r"^loops must be a list or tuple"):
        ci.sim.BatchRunner(sims, None)
    with pytest.raises(ci.Error, match=r"^threads = 65 is outside \[0, 64\]"):
        ci.sim.BatchRunner(sims, loops, threads=65)
    with pytest.raises(ci.Error, match=r"^spin = 2 s is outside \[0, 1\] s"):
        ci.sim.BatchRunner(sims, loops, spin=2.0)
    with pytest.raises(ci.Error, match=r"^spin = nan s"):
        ci.sim.BatchRunner(sims, loops, spin=float("nan"))
    batch = ci.sim.BatchRunner(sims, loops)
    assert batch.spin == 0.002
    with pytest.raises(ci.Error, match=r"^seconds = nan must be finite and >= 0"):
        batch.run(float("nan"))
    for sim, loop in pairs:  # nothing ran
        assert sim.time == 0.0 and loop.state.cycle == 0
    assert "3 pairs" in repr(batch)


def test_run_releases_the_gil_and_claims_every_pair(panda):
    pairs = [arm(panda) for _ in range(2)]
    batch = ci.sim.BatchRunner([s for s, _ in pairs], [l for _, l in pairs])
    seconds = 20.0
    thread = threading.Thread(target=batch.run, args=(seconds,))
    seen, refusals = [], []
    thread.start()
    while thread.is_alive():
        cycle = pairs[1][1].latest_state().cycle  # any thread may read the published state
        seen.append(cycle)
        if 0 < cycle and not refusals:
            for use in (lambda: pairs[0][0].q, lambda: pairs[1][1].state, lambda: batch.run(1.0),
                        lambda: pairs[0][0].run(pairs[0][1], 0.1)):
                try:
                    use()
                except RuntimeError as error:
                    refusals.append(str(error))
            pairs[0][1].set_stiffness([400, 400, 400, 40, 40, 40])  # commands from any thread
        time.sleep(0.001)
    thread.join()
    assert any(0 < cycle < 20000 for cycle in seen)  # Python ran here meanwhile
    assert len(refusals) == 4, refusals
    assert all("in use by Simulation.run() or BatchRunner.run() in another thread" in r
               for r in refusals)
    assert [loop.state.cycle for _, loop in pairs] == [20000, 20000]
    np.testing.assert_allclose(np.diag(pairs[0][1].state.controller.commanded.stiffness),
                               [400, 400, 400, 40, 40, 40])


def test_ctrl_c_stops_every_pair(panda):
    pairs = [arm(panda) for _ in range(3)]
    batch = ci.sim.BatchRunner([s for s, _ in pairs], [l for _, l in pairs], threads=2)
    # As Ctrl+C would, 0.2 s into a run of 1000 simulated seconds (over a minute of work).
    timer = threading.Timer(0.2, _thread.interrupt_main)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        batch.run(1000.0)
    timer.join()
    # Every pair stopped long before the end (without the check, the interrupt would come after
    # 1000 s each), after a whole step: the state is consistent.
    for sim, loop in pairs:
        assert sim.time < 500.0 and loop.state.cycle == round(sim.time / sim.timestep)
    assert list(batch.run(0.01)) == [10, 10, 10]  # usable again
