"""simgate.gym: the Gymnasium environment over real `simgate run` processes (docs/python.md).

Gymnasium's own checker on three models (the demo robot, a dm_control-style cartpole written
for these tests, Debian's humanoid), bit-for-bit episodes from a seed, the action bounds,
the errors (a bad model, no executable, nowhere to attach), processes stopped and reaped by
close(), attaching to a running simgate, rendering, vector environments, and pymorse talking
to the same simgate through the socket transport. Every simgate listens on 127.0.0.1, ports
the kernel picks; every wait is bounded.
"""

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

import simgate  # noqa: E402
import simgate.gym  # noqa: E402
from simgate.gym import SimgateEnv, SimgateStartError  # noqa: E402

from conftest import SOURCE_DIR, Gateway, simgate_binary  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
CARTPOLE = os.path.join(HERE, "cartpole.xml")
DEMO = os.path.join(SOURCE_DIR, "config", "scenes", "demo.xml")
HUMANOID = "/usr/share/mujoco/model/humanoid/humanoid.xml"
PLUGINS = [os.environ["SIMGATE_PLUGIN_DIR"]] if os.environ.get("SIMGATE_PLUGIN_DIR") else []


def make(**kwargs):
    kwargs.setdefault("binary", simgate_binary())
    kwargs.setdefault("plugin_path", PLUGINS)
    return SimgateEnv(**kwargs)


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie (not reaped) counts as alive
        return f.read().split(") ", 1)[1][0] != "Z"


@pytest.fixture
def cartpole():
    env = make(model=CARTPOLE)
    yield env
    env.close()


def check(env):
    with warnings.catch_warnings():
        # unbounded joint and sensor values are the truth, as in Gymnasium's MuJoCo envs
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value")
        check_env(env)


# ---- Gymnasium's checker on three models
def test_check_env_cartpole(cartpole):
    check(cartpole)
    assert cartpole.action_names == ["cart.actuators/slide"]
    assert cartpole.action_space.low.tolist() == [-1.0] and cartpole.action_space.high.tolist() == [1.0]
    assert list(cartpole.observation_space.spaces) == ["joint_pos", "joint_vel", "sensors"]
    assert cartpole.observation_names == [
        "joint_pos:cart.armature_pose/slider", "joint_pos:cart.armature_pose/hinge_1",
        "joint_vel:cart.armature_pose/slider", "joint_vel:cart.armature_pose/hinge_1",
        "sensors:cart.sensors/cart_x", "sensors:cart.sensors/pole_w", "sensors:cart.sensors/tip_pos[0]",
        "sensors:cart.sensors/tip_pos[1]", "sensors:cart.sensors/tip_pos[2]"]


def test_check_env_demo_robot():
    env = make(model=DEMO, render_mode="rgb_array", render_width=64, render_height=48)
    try:
        check(env)
        assert env.action_names == ["robot.actuators/robot_left_motor", "robot.actuators/robot_right_motor"]
        assert env.action_space.high.tolist() == [30.0, 30.0]  # the velocity actuators' ctrlrange
        obs, _ = env.reset(seed=3)
        assert obs["base"][:3].tolist() == [0.0, 0.0, 0.1]  # the floating base where the MJCF puts it
        for _ in range(200):
            obs, *_ = env.step(np.array([10.0, 10.0]))
        assert obs["base"][0] > 0.05  # both wheels forward: the robot drove along +x
        assert obs["joint_vel"].min() > 0
    finally:
        env.close()


def test_check_env_humanoid():
    if not os.path.exists(HUMANOID):
        pytest.skip(f"{HUMANOID} is not installed (Debian's libmujoco-samples)")
    env = make(model=HUMANOID, frame_skip=5)
    try:
        check(env)
        assert env.action_space.shape == (21,)
        assert env.observation_space["joint_pos"].shape == (21,)
        assert env.observation_space["base"].shape == (13,)
        obs, _ = env.reset(seed=0)
        _, _, _, _, info = env.step(env.action_space.sample())
        assert info["sim_time"] == pytest.approx(5 * 0.005)  # frame_skip steps of the model's timestep
    finally:
        env.close()


def test_config_file_gives_the_robots_of_the_config(tmp_path):
    config = {"scene": {"mjcf": os.path.relpath(CARTPOLE, tmp_path), "realtime_factor": 1.0},
              "transports": {"socket": {"plugin": "socket", "options": {"port": 4000}}},
              "robots": [{"name": "cartpole", "type": "mjcf", "body": "cart"}],
              "services": {"default": ["socket"]}}
    path = tmp_path / "cartpole.json"
    path.write_text(json.dumps(config))
    env = make(config=str(path))  # relative scene path, port 4000 and services replaced
    try:
        check(env)
        assert env.action_names == ["cartpole.actuators/slide"]
    finally:
        env.close()


# ---- same seed, same episode
def trajectory(env, seed, steps=60):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    env.action_space.seed(seed)
    for _ in range(steps):
        obs, *_ = env.step(env.action_space.sample())
        out.append(obs)
    return out


def same_bits(a, b):
    return all(np.array_equal(x[k].view(np.uint64), y[k].view(np.uint64)) for x, y in zip(a, b) for k in x)


def test_same_seed_same_trajectory_bit_for_bit(cartpole):
    first = trajectory(cartpole, 7)
    trajectory(cartpole, 8)  # another episode in between
    again = trajectory(cartpole, 7)
    assert same_bits(first, again)
    other = make(model=CARTPOLE)  # another process, the same seed
    try:
        assert same_bits(first, trajectory(other, 7))
    finally:
        other.close()
    assert not same_bits(first, trajectory(cartpole, 8))  # another seed, other actions


def test_reset_restores_the_initial_state_exactly(cartpole):
    start, _ = cartpole.reset()
    for _ in range(30):
        cartpole.step(np.array([1.0]))
    again, info = cartpole.reset()
    assert info["sim_time"] == 0.0
    assert same_bits([start], [again])


# ---- actions
def test_actions_out_of_range_are_clipped_by_default(cartpole):
    cartpole.reset()
    high, *_ = cartpole.step(np.array([5.0]))
    cartpole.reset()
    one, *_ = cartpole.step(np.array([1.0]))
    assert same_bits([high], [one])
    assert cartpole.client.call("cart.actuators", "get_controls") == {"slide": 1.0}


def test_actions_out_of_range_refused_when_asked():
    env = make(model=CARTPOLE, out_of_range="refuse")
    try:
        env.reset()
        with pytest.raises(ValueError, match=r"action\[0\] \(cart.actuators/slide\) = 1.5 is out of range: "
                                             r"expected a number from -1.0 to 1.0"):
            env.step(np.array([1.5]))
        assert env.client.state()["sim_time"] == 0.0  # nothing was sent
    finally:
        env.close()


def test_bad_actions_are_refused(cartpole):
    cartpole.reset()
    with pytest.raises(ValueError, match="expected a finite number"):
        cartpole.step(np.array([np.nan]))
    with pytest.raises(ValueError, match=r"shape \(2,\), expected \(1,\)"):
        cartpole.step(np.array([0.1, 0.2]))


def test_step_before_reset_is_refused(cartpole):
    with pytest.raises(RuntimeError, match="reset"):
        cartpole.step(np.array([0.0]))


# ---- reward, termination, truncation, frame_skip, flat
def test_reward_termination_truncation_and_frame_skip():
    def reward(obs, action, next_obs):
        return float(next_obs["joint_pos"][0] - obs["joint_pos"][0])

    def fallen(obs, action, next_obs):
        return abs(next_obs["joint_pos"][1]) > 0.5

    env = make(model=CARTPOLE, frame_skip=4, reward_fn=reward, terminated_fn=fallen, max_episode_steps=200)
    try:
        obs, _ = env.reset(seed=1)
        terminated = truncated = False
        steps = 0
        while not (terminated or truncated):
            before = obs["joint_pos"][0]
            obs, r, terminated, truncated, info = env.step(np.array([1.0]))
            steps += 1
            assert r == obs["joint_pos"][0] - before
            assert info["sim_time"] == pytest.approx(steps * 4 * 0.01)
        assert terminated and abs(obs["joint_pos"][1]) > 0.5 and steps < 200
    finally:
        env.close()
    env = make(model=CARTPOLE, max_episode_steps=3)
    try:
        env.reset()
        assert [env.step(np.zeros(1))[3] for _ in range(3)] == [False, False, True]
    finally:
        env.close()


def test_flat_observation_is_the_dict_concatenated(cartpole):
    flat = make(model=CARTPOLE, flat=True)
    try:
        check(flat)
        a, _ = cartpole.reset()
        b, _ = flat.reset()
        for _ in range(5):
            a, *_ = cartpole.step(np.array([0.3]))
            b, *_ = flat.step(np.array([0.3]))
        assert b.shape == (len(flat.observation_names),)
        assert np.array_equal(b, np.concatenate([a["joint_pos"], a["joint_vel"], a["sensors"]]))
    finally:
        flat.close()


# ---- rendering
def test_render_rgb_array_through_a_camera():
    env = make(model=CARTPOLE, render_mode="rgb_array", render_camera="fixed", render_width=80, render_height=60)
    try:
        env.reset()
        image = env.render()
        assert image.shape == (60, 80, 3) and image.dtype == np.uint8 and image.std() > 0
    finally:
        env.close()


# ---- errors
def test_a_model_simgate_cannot_load_is_reported_with_its_message(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><geom type='nosuchtype'/></body></worldbody></mujoco>")
    with pytest.raises(SimgateStartError, match=r"exited with status 2 before listening:(.|\n)*--model"):
        make(model=str(bad))


def test_a_missing_model_file_is_named():
    with pytest.raises(FileNotFoundError, match="model='/nonexistent/robot.xml': no such file"):
        make(model="/nonexistent/robot.xml")


def test_a_missing_binary_is_named(monkeypatch):
    with pytest.raises(FileNotFoundError, match=r"binary= '/nonexistent/simgate': no such executable"):
        SimgateEnv(model=CARTPOLE, binary="/nonexistent/simgate")
    monkeypatch.delenv("SIMGATE_BIN", raising=False)
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(FileNotFoundError, match="no simgate executable: pass binary=PATH, set SIMGATE_BIN"):
        SimgateEnv(model=CARTPOLE)


def test_an_unknown_address_is_named():
    import socket
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(simgate.ConnectionClosed, match=f"cannot attach to jsonrpc://127.0.0.1:{port}"):
        SimgateEnv(address=f"127.0.0.1:{port}", timeout=5)


def test_exactly_one_source_is_required():
    with pytest.raises(ValueError, match="exactly one of model"):
        SimgateEnv()
    with pytest.raises(ValueError, match="exactly one of model"):
        SimgateEnv(model=CARTPOLE, address="127.0.0.1:1")


def test_a_model_without_actuators_is_refused(tmp_path):
    model = tmp_path / "passive.xml"
    model.write_text("<mujoco><worldbody><body name='arm'><joint type='hinge'/>"
                     "<geom size='0.1'/></body></worldbody></mujoco>")
    with pytest.raises(ValueError, match="no actuators component"):
        make(model=str(model))


# ---- processes
def test_close_stops_and_reaps_simgate():
    env = make(model=CARTPOLE)
    pid = env._server.process.pid
    assert alive(pid)
    env.close()
    assert not alive(pid)
    env.close()  # idempotent


def test_gymnasium_make_registers_and_wraps():
    env = gymnasium.make("simgate/Model-v0", model=CARTPOLE, binary=simgate_binary(),
                         plugin_path=PLUGINS, max_episode_steps=2)
    pid = env.unwrapped._server.process.pid
    try:
        env.reset(seed=0)
        assert env.step(np.zeros(1))[3] is False
        assert env.step(np.zeros(1))[3] is True  # gymnasium's TimeLimit
    finally:
        env.close()
    assert not alive(pid)


def test_attach_to_a_running_simgate(tmp_path):
    config = {"scene": {"mjcf": CARTPOLE},
              "transports": {"jsonrpc": {"plugin": "jsonrpc", "options": {"host": "127.0.0.1", "port": 0}},
                             "websocket": {"plugin": "websocket", "options": {"host": "127.0.0.1", "port": 0}}},
              "robots": [{"name": "cart", "type": "mjcf", "body": "cart"}], "log_level": "warning"}
    gw = Gateway(tmp_path, config)  # playing, not paused
    try:
        keeper = simgate.connect(gw.url("jsonrpc"))
        keeper.pause()
        handle = keeper.save_state()  # both environments attach to this same world
        trajectories = {}
        for scheme in ("jsonrpc", "ws"):  # JSON-RPC on TCP and on WebSocket alike
            keeper.restore_state(handle)
            url = gw.url(scheme)
            env = SimgateEnv(address=url)
            try:
                assert env.client.state()["state"] == "paused"
                start, _ = env.reset()
                trajectories[scheme] = [start] + [env.step(np.array([a]))[0] for a in (1.0, -0.5, 0.25)]
                with simgate.connect(url) as other:  # the env's lockstep: no one else steps
                    with pytest.raises(simgate.ServiceFailed, match="stepped in lockstep"):
                        other.step(1)
                again, _ = env.reset()
                assert same_bits([start], [again])
            finally:
                env.close()
            assert gw.process.poll() is None  # not ours to stop
            with simgate.connect(url) as other:
                assert other.step(1)["steps_done"] == 1  # the env left the lockstep
        # the same world, the same actions: the same observations, bit for bit, either way
        assert len(trajectories["ws"]) == len(trajectories["jsonrpc"]) == 4
        assert same_bits(trajectories["jsonrpc"], trajectories["ws"])
        keeper.close()
    finally:
        gw.kill()


def test_make_vec_runs_one_simgate_per_environment():
    envs = simgate.gym.make_vec(2, vectorization_mode="sync", model=CARTPOLE, binary=simgate_binary(),
                                plugin_path=PLUGINS)
    pids = [e.unwrapped._server.process.pid for e in envs.envs]
    try:
        obs, _ = envs.reset(seed=5)
        assert obs["joint_pos"].shape == (2, 2)
        obs, reward, terminated, truncated, _ = envs.step(np.array([[1.0], [-1.0]]))
        assert obs["joint_pos"][0, 0] > 0 > obs["joint_pos"][1, 0]
    finally:
        envs.close()
    assert len(set(pids)) == 2 and not any(alive(p) for p in pids)


def test_make_vec_async_workers():
    envs = simgate.gym.make_vec(2, model=CARTPOLE, binary=simgate_binary(), plugin_path=PLUGINS)
    try:
        envs.reset(seed=5)
        obs, *_ = envs.step(np.array([[1.0], [1.0]]))
        assert np.array_equal(obs["joint_pos"][0], obs["joint_pos"][1])  # same seed offsets, no noise
    finally:
        envs.close()
    assert not [line for line in subprocess.run(["pgrep", "-af", "simgate run --model " + CARTPOLE],
                                                capture_output=True, text=True).stdout.splitlines()]


# ---- pymorse beside the environment
PYMORSE = """
import json, sys, warnings
warnings.simplefilter("ignore", DeprecationWarning)
import pymorse
simu = pymorse.Morse(sys.argv[1], int(sys.argv[2]))
try:
    print(json.dumps([simu.rpc("simulation", "list_robots"), simu.rpc("cart.armature_pose", "get_state")]))
finally:
    simu.close(wait_publishers=False)  # with True, pymorse trips over its own proxies (known bug)
"""


def test_pymorse_keeps_working_beside_the_environment(cartpole):
    cartpole.reset()
    for _ in range(20):
        obs, *_ = cartpole.step(np.array([1.0]))
    host, port = cartpole.url_of("socket").split("://")[1].split(":")
    out = subprocess.run(["/usr/bin/python3", "-c", PYMORSE, host, port], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    robots, state = json.loads(out.stdout)
    assert robots == ["cart"]
    assert [state["slider"]["position"], state["hinge_1"]["position"]] == obs["joint_pos"].tolist()
    obs, *_ = cartpole.step(np.array([1.0]))  # and the environment goes on
    assert obs["joint_pos"][0] > state["slider"]["position"]


def test_a_robot_whose_own_services_are_not_served_has_its_name_as_base(tmp_path):
    """Only the robot's components and `simulation` mapped to the transport (not the robot's
    own services, such as get_configurations): the floating base is the body named after the
    robot."""
    config = {"scene": {"mjcf": CARTPOLE},
              "transports": {"jsonrpc": {"plugin": "jsonrpc", "options": {"host": "127.0.0.1", "port": 0}}},
              "robots": [{"name": "cart", "type": "mjcf", "body": "cart",
                          "components": [{"name": "pose", "type": "pose"}]}],
              "services": {"cart.*": ["jsonrpc"], "simulation": ["jsonrpc"]}, "log_level": "warning"}
    gw = Gateway(tmp_path, config)
    try:
        with simgate.connect(gw.url("jsonrpc")) as probe:
            with pytest.raises(simgate.MethodNotFound):
                probe.call("cart", "get_configurations")
        env = SimgateEnv(address=gw.url("jsonrpc"))
        try:
            obs, _ = env.reset()
            assert env.observation_names.count("base:cart/x") == 1
            assert obs["base"].shape == (13,)
            env.step(np.array([0.5]))
        finally:
            env.close()
    finally:
        gw.kill()
