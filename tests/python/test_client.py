"""The Python client (python/simgate, docs/python.md) against real simgate processes, over
JSON-RPC on TCP (jsonrpc://), JSON-RPC on WebSocket (ws://) and MORSE's socket protocol
(socket://). Every wait is bounded."""

import asyncio
import inspect
import math
import threading
import time

import numpy
import pytest

import simgate
from conftest import TOKEN

WAIT = 20  # seconds: the bound of every wait below
FAR = {"x": 40.0, "y": 0.0, "z": 0.0}  # a goto that takes long enough to be cancelled


def wait_until(predicate, what):
    deadline = time.monotonic() + WAIT
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


# ---- connecting, discovery, attributes


def test_a_call_on_each_scheme_and_the_context_manager_closes(gateway, scheme):
    with simgate.connect(gateway.url(scheme), token=TOKEN, timeout=WAIT) as sim:
        assert sim.pause() == "Simulation is paused"
        assert sim.call("rover.motion", "set_speed", 0.5, 0.2) is None
    assert sim.closed
    with pytest.raises(simgate.ConnectionClosed, match="closed by the client"):
        sim.call("simulation", "pause")


def test_services_are_attributes_with_signatures_and_docstrings(sim):
    set_speed = sim.rover.motion.set_speed
    assert str(inspect.signature(set_speed)) == "(v: float, w: float)"
    assert "Linear speed v" in inspect.getdoc(set_speed)
    reset = inspect.signature(sim.simulation.reset)
    assert reset.parameters["scope"].default == "all" and reset.parameters["robot"].default == ""
    assert inspect.signature(sim.simulation.step).parameters["n"].default == 1
    assert {"motion", "pose", "camera", "waypoint"} <= set(dir(sim.rover))
    assert sim.component("rover.motion").set_speed.info.method == "rover.motion.set_speed"
    assert sim.services["simulation.step"].is_async and not sim.services["simulation.pause"].is_async


def test_an_unknown_service_is_an_attribute_error_with_did_you_mean(sim):
    with pytest.raises(AttributeError, match=r"'set_sped'.*did you mean 'set_speed'"):
        sim.rover.motion.set_sped
    with pytest.raises(AttributeError, match=r"'mtion'.*did you mean 'motion'"):
        sim.rover.mtion
    with pytest.raises(AttributeError, match="'nothing_like_it'"):
        sim.rover.nothing_like_it


def test_wrong_arguments_raise_the_servers_message(sim):
    with pytest.raises(simgate.InvalidArguments) as wrong_type:
        sim.rover.motion.set_speed(v="fast", w=0)
    assert "parameter 'v' expects number" in wrong_type.value.message
    assert wrong_type.value.status == "FAILED"
    with pytest.raises(simgate.InvalidArguments, match="set_speed") as too_few:
        sim.rover.motion.set_speed(0.5)
    assert too_few.value.message  # the server's sentence, not a local TypeError
    if sim.scheme != "socket":
        assert wrong_type.value.data["parameter"] == "v" and wrong_type.value.code == -32602


def test_an_unknown_method_through_call_is_method_not_found(sim):
    with pytest.raises(simgate.MethodNotFound, match="set_sped"):
        sim.call("rover.motion", "set_sped", 1, 2)


def test_a_service_failure_carries_status_and_message(sim):
    sim.play()
    with pytest.raises(simgate.ServiceFailed, match="pause it first") as failed:
        sim.step(1)
    sim.pause()
    assert failed.value.status == "FAILED"
    # JSON-RPC says the parameter was bad (-32602); MORSE's lines only say FAILED
    refused = simgate.ServiceFailed if sim.scheme == "socket" else simgate.InvalidArguments
    with pytest.raises(refused, match="no saved state 987654") as bad:
        sim.restore_state(987654)
    assert bad.value.status == "FAILED"
    if sim.scheme != "socket":
        assert bad.value.data["parameter"] == "handle" and bad.value.data["failure"] == "bad_arguments"


# ---- world control


def test_step_n_advances_time_by_exactly_n_timesteps(sim):
    before = sim.state()
    assert before["state"] == "paused"
    done = sim.step(7)
    after = sim.state()
    assert done["steps_done"] == 7 and after["steps"] - before["steps"] == 7
    assert math.isclose(after["sim_time"] - before["sim_time"], 7 * before["timestep"], abs_tol=1e-12)
    assert after["sim_time"] == done["sim_time"]


def test_restoring_a_saved_state_replays_identically(sim):
    def drive():
        sim.rover.motion.set_speed(v=0.4, w=0.3)
        sim.step(150)
        return sim.rover.pose.get_local_data()

    handle = sim.save_state()
    start = sim.state()["sim_time"]
    first = drive()
    restored = sim.restore_state(handle)
    assert restored["exact"] and restored["sim_time"] == start
    second = drive()
    assert first == second and first["x"] != 0.0  # the same bits, and the rover moved
    sim.drop_state(handle)


def test_play_pause_reset_spawn_and_delete(sim):
    assert sim.play() == "Simulation is playing"
    wait_until(lambda: sim.state()["sim_time"] > 0.05, "time to advance while playing")
    sim.pause()
    sim.reset()
    assert sim.state()["sim_time"] == 0.0
    name = f"ball_{sim.scheme}"
    spawned = sim.spawn(name, '<body><freejoint/><geom type="sphere" size="0.05"/></body>', [1.0, 1.0, 0.5])
    assert spawned["name"] == name
    assert name in sim.simulation.list_entities(filter=name)
    assert sim.delete(name)["model_generation"] > spawned["model_generation"]


def test_a_batch_is_one_round_trip_of_action_step_and_observation(sim):
    before = sim.state()["sim_time"]
    with sim.batch() as b:
        action = b.rover.motion.set_speed(v=0.3, w=0.0)
        step = b.step(2)
        state = b.state()
    assert action.result(WAIT) is None
    assert step.result(WAIT)["steps_done"] == 2
    if sim.scheme != "socket":  # one JSON-RPC batch: the entries after the step see it
        assert math.isclose(state.result(WAIT)["sim_time"], before + 2 * 0.002, abs_tol=1e-12)
    else:
        assert state.result(WAIT)["state"] == "paused"


# ---- asynchronous services: progress, cancel, deadline


def test_an_async_call_reports_progress_and_is_cancelled(sim):
    sim.reset()
    reports = []
    goto = sim.rover.waypoint.goto.options(progress=reports.append)(**FAR)
    assert isinstance(goto, simgate.Call) and not goto.done()
    sim.play()
    wait_until(lambda: len(reports) >= 2, "two progress reports")
    assert reports[0]["distance_left"] >= reports[-1]["distance_left"]
    assert goto.progress == reports[-1]
    assert goto.cancel()
    with pytest.raises(simgate.Cancelled) as cancelled:
        goto.result(WAIT)
    assert cancelled.value.status == "PREEMPTED"
    assert not goto.cancel()  # ended already
    sim.pause()


def test_a_deadline_ends_an_async_call(sim):
    sim.reset()
    sim.play()
    goto = sim.rover.waypoint.goto.options(deadline=0.2)
    if sim.scheme == "socket":
        with pytest.raises(ValueError, match="socket:// cannot give a call a deadline"):
            goto(40.0, 0.0, 0.0).result(WAIT)
        return
    call = goto(40.0, 0.0, 0.0)  # positional arguments named from discovery
    with pytest.raises(simgate.DeadlineExceeded, match="no reply within 200 ms") as late:
        call.result(WAIT)
    assert late.value.data["timeout_ms"] == 200
    sim.pause()


def test_a_newer_call_preempts_an_interruptible_one(sim):
    first = sim.simulation.step(1000000)
    second = sim.simulation.step(1)
    with pytest.raises(simgate.Preempted):
        first.result(WAIT)
    assert second.result(WAIT)["steps_done"] == 1


# ---- streams


def test_a_subscription_iterates_keeps_the_latest_and_closes(sim):
    sub = sim.subscribe("rover.pose", buffer=4)
    first = sub.get(WAIT)  # a paused simulation sends the current state at once
    assert first.component == "rover.pose" and "x" in first.data
    sim.step(200)  # 60 Hz over 0.4 s: about 24 samples, 4 kept
    wait_until(lambda: sub.latest().time and sub.latest().time > first.time + 0.3, "the newest sample")
    assert sub.dropped > 0
    got = [next(sub) for _ in range(2)]
    assert got[0].seq < got[1].seq
    sub.close()
    assert sub.closed
    assert len(list(sub)) <= 2  # what was buffered, then the iteration ends
    assert list(sub) == []


def test_publish_drives_the_robot(sim):
    sim.reset()
    x0 = sim.rover.pose.get_local_data()["x"]
    applied = sim.publish("rover.motion", {"v": 0.5, "w": 0.0})
    assert applied is (None if sim.scheme == "socket" else True)  # MORSE's ports answer nothing
    # socket://: the command applies when the server reads its port, unacknowledged
    wait_until(lambda: sim.step(25) and sim.rover.pose.get_local_data()["x"] > x0 + 0.05,
               "the published speed to move the rover")
    if sim.scheme != "socket":
        with pytest.raises(simgate.InvalidArguments, match="unknown key 'speed'"):
            sim.publish("rover.motion", {"speed": 1})


# ---- images


def test_images_are_numpy_arrays_rgb_and_depth_in_metres(gateway):
    with simgate.connect(gateway.url("jsonrpc"), token=TOKEN, timeout=WAIT) as sim:
        rgb = sim.get_image("rover.camera")
        assert rgb.shape == (240, 320, 3) and rgb.dtype == numpy.uint8 and rgb.std() > 0
        record = sim.rover.depth.get_image().result(WAIT)
        depth = simgate.decode_image(record)
        assert depth.shape == (120, 160) and depth.dtype == numpy.float32
        hits = depth[depth > 0]
        assert math.isclose(hits.min(), record["min_depth"], abs_tol=1e-3)
        assert math.isclose(hits.max(), record["max_depth"], abs_tol=1e-3)
        raw = simgate.decode_image(record, numpy_arrays=False)
        assert raw.shape == (120, 160) and raw.dtype == "float32"
        assert numpy.array_equal(numpy.frombuffer(raw.data, dtype=numpy.float32).reshape(raw.shape), depth)
        shot = sim.snapshot(width=64, height=48)
        assert shot.shape == (48, 64, 3)


# ---- the connection's end, the token, asyncio


def test_closing_fails_every_pending_call(gateway, scheme):
    sim = simgate.connect(gateway.url(scheme), token=TOKEN, timeout=WAIT)
    sim.pause()
    sleeps = [sim.time.sleep(1000.0) for _ in range(3)]  # simulated seconds: never while paused
    assert not any(s.done() for s in sleeps)
    sim.close()
    for s in sleeps:
        with pytest.raises(simgate.ConnectionClosed, match="closed by the client"):
            s.result(WAIT)


def test_a_server_that_dies_fails_every_pending_call(fresh_gateway):
    sim = simgate.connect(fresh_gateway.url("jsonrpc"), timeout=WAIT)
    sub = sim.subscribe("rover.pose")
    pending = [sim.time.sleep(1000.0), sim.rover.waypoint.goto(**FAR)]
    fresh_gateway.kill()
    for call in pending:
        with pytest.raises(simgate.ConnectionClosed, match="server closed the connection|connection was lost"):
            call.result(WAIT)
    with pytest.raises(simgate.ConnectionClosed):
        while True:
            sub.get(WAIT)
    with pytest.raises(simgate.ConnectionClosed):
        sim.pause()
    sim.close()


def test_a_missing_or_wrong_token_is_refused(gateway, scheme):
    if scheme == "ws":
        with pytest.raises(simgate.NotAuthorized, match="401"):
            simgate.connect(gateway.url(scheme), token="wrong-token-0123456789", timeout=WAIT)
    else:
        with pytest.raises(simgate.NotAuthorized):
            simgate.connect(gateway.url(scheme), token="wrong-token-0123456789", timeout=WAIT).pause()
    with simgate.connect(gateway.url(scheme), timeout=WAIT) as anonymous:
        with pytest.raises(simgate.SimgateError):
            anonymous.pause()


def test_the_asyncio_api(gateway, scheme):
    async def main():
        async with await simgate.connect_async(gateway.url(scheme), token=TOKEN, timeout=WAIT) as sim:
            await sim.services()
            assert await sim.pause() == "Simulation is paused"
            await sim.rover.motion.set_speed(v=0.0, w=0.0)
            before = (await sim.state())["steps"]
            await sim.step(3)
            assert (await sim.state())["steps"] == before + 3
            sub = await sim.subscribe("rover.pose")
            first = await asyncio.wait_for(sub.__anext__(), WAIT)
            assert "x" in first.data
            sub.close()
            reports = asyncio.Queue()
            goto = sim.rover.waypoint.goto.options(progress=reports.put_nowait)(**FAR)
            await sim.play()
            assert "distance_left" in await asyncio.wait_for(reports.get(), WAIT)
            goto.cancel()  # the asyncio future's cancel sends the cancel to the server
            with pytest.raises(asyncio.CancelledError):
                await goto
            with pytest.raises(simgate.InvalidArguments):
                await sim.rover.motion.set_speed(v="x", w=0)
            await sim.pause()
            assert threading.current_thread() is threading.main_thread()
    asyncio.run(asyncio.wait_for(main(), 3 * WAIT))
