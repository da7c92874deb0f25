"""simgate.vector: the Gymnasium vector environment over the worlds of one simgate (docs/python.md).

Its spaces against the single environment's, batched; its observations, rewards and ends
against one `SimgateEnv` per world given the same actions, bit for bit, across autoresets
(next step and same step) that reset only the worlds that ended; a step sent as one
step_many request, its actions where MuJoCo's ctrl has them; masked resets; bad actions
refused before anything is sent; a diverging world reset and reported; attaching to a
simgate started with worlds; the simgate it started stopped and reaped by close(). Every
simgate listens on 127.0.0.1, ports the kernel picks; every wait is bounded.
"""

import json
import os

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.vector import AutoresetMode  # noqa: E402
from gymnasium.vector.utils import batch_space  # noqa: E402

import simgate  # noqa: E402
import simgate.gym  # noqa: E402
import simgate.vector  # noqa: E402
from simgate.vector import SimgateVectorEnv  # noqa: E402

from conftest import Gateway, simgate_binary  # noqa: E402
from test_gym import CARTPOLE, PLUGINS, alive, make  # noqa: E402

# a block pushed by a motor far too strong: any push makes it diverge (docs/world/divergence.md)
PUSHER = """<mujoco model="pusher">
  <option timestep="0.01"/>
  <worldbody>
    <body name="block">
      <joint name="slide" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="slide" gear="1e12"/></actuator>
</mujoco>
"""


def make_vector(num_envs, **kwargs):
    kwargs.setdefault("binary", simgate_binary())
    kwargs.setdefault("plugin_path", PLUGINS)
    return SimgateVectorEnv(num_envs, **kwargs)


def bits(obs):
    """The observation's numbers as integers: equal bits, equal values (NaN and -0.0 included)."""
    if isinstance(obs, dict):
        return {k: v.view(np.uint64).tolist() for k, v in obs.items()}
    return obs.view(np.uint64).tolist()


def world(obs, k):
    return {key: value[k] for key, value in obs.items()} if isinstance(obs, dict) else obs[k]


def pushed_right(obs, action, next_obs):
    return bool(next_obs["joint_pos"][0] > 0.004)


def progress(obs, action, next_obs):
    return float(next_obs["joint_pos"][0] - obs["joint_pos"][0])


# ---- spaces
@pytest.mark.parametrize("flat", [False, True])
def test_spaces_are_the_single_environments_batched(flat):
    single = make(model=CARTPOLE, flat=flat)
    envs = simgate.gym.make_vec(3, vectorization_mode="worlds", model=CARTPOLE, binary=simgate_binary(),
                                plugin_path=PLUGINS, flat=flat)
    try:
        assert isinstance(envs, SimgateVectorEnv) and envs.num_envs == 3
        assert envs.single_observation_space == single.observation_space
        assert envs.single_action_space == single.action_space
        assert envs.observation_space == batch_space(single.observation_space, 3)
        assert envs.action_space == batch_space(single.action_space, 3)
        assert envs.action_names == single.action_names
        assert envs.observation_names == single.observation_names
        assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        obs, infos = envs.reset(seed=0)
        assert envs.observation_space.contains(obs)
        assert infos["sim_time"].tolist() == [0.0] * 3 and infos["_sim_time"].all()
    finally:
        envs.close()
        single.close()


def test_gymnasium_make_vec_uses_the_worlds():
    envs = gymnasium.make_vec("simgate/Model-v0", num_envs=2, model=CARTPOLE, binary=simgate_binary(),
                              plugin_path=PLUGINS)  # the registered vector_entry_point
    try:
        assert isinstance(envs.unwrapped, SimgateVectorEnv)
        assert envs.unwrapped.client.call("w1/simulation", "get_simulation_state")["state"] == "paused"
    finally:
        envs.close()


# ---- the same episodes as one SimgateEnv per world
def test_observations_equal_one_single_environment_per_world_across_autoresets():
    """World 0 pushes right and ends its episodes (terminated_fn), world 1 pushes left and
    never does but is truncated (max_episode_steps), world 2 pushes gently: each world's
    steps, rewards, ends and resets are those of a SimgateEnv given the same actions."""
    options = dict(terminated_fn=pushed_right, reward_fn=progress, max_episode_steps=9, frame_skip=2)
    envs = make_vector(3, model=CARTPOLE, **options)
    singles = [make(model=CARTPOLE, **options) for _ in range(3)]
    try:
        obs, _ = envs.reset(seed=1)
        single_obs = [env.reset(seed=1)[0] for env in singles]
        ended = [False] * 3
        rng = np.random.default_rng(1)
        episodes = [0] * 3
        for _ in range(24):
            actions = np.abs(rng.uniform(0.2, 1.0, (3, 1))) * [[1.0], [-1.0], [0.3]]
            obs, rewards, terminated, truncated, infos = envs.step(actions)
            for k, env in enumerate(singles):
                if ended[k]:  # autoreset, the next step: the reset observation, nothing else
                    single_obs[k], _ = env.reset()
                    expected = (0.0, False, False)
                    episodes[k] += 1
                else:
                    single_obs[k], reward, term, trunc, info = env.step(actions[k])
                    expected = (reward, term, trunc)
                    assert infos["sim_time"][k] == info["sim_time"]
                assert bits(world(obs, k)) == bits(single_obs[k]), f"world {k}"
                assert (rewards[k], terminated[k], truncated[k]) == expected, f"world {k}"
                ended[k] = bool(terminated[k] or truncated[k])
        assert episodes[0] >= 3 and episodes[1] == 2  # world 0 terminated, world 1 truncated twice
    finally:
        envs.close()
        for env in singles:
            env.close()


def test_autoreset_resets_only_the_worlds_that_ended():
    envs = make_vector(3, model=CARTPOLE, terminated_fn=pushed_right)
    try:
        start, _ = envs.reset()
        push = np.array([[1.0], [-1.0], [0.0]])
        terminated = np.zeros(3, dtype=bool)
        steps = 0
        while not terminated[0]:
            _, _, terminated, truncated, infos = envs.step(push)
            steps += 1
            assert steps < 100
        assert terminated.tolist() == [True, False, False] and not truncated.any()
        obs, rewards, terminated, truncated, infos = envs.step(push)  # world 0 resets instead
        assert infos["sim_time"][0] == 0.0
        assert infos["sim_time"][1:].tolist() == pytest.approx([(steps + 1) * 0.01] * 2)
        assert bits(world(obs, 0)) == bits(world(start, 0))
        assert obs["joint_pos"][1, 0] < 0 and not terminated.any()
        states = envs.client.call_many([("simulation", "get_simulation_state", None),
                                        ("w1/simulation", "get_simulation_state", None)])
        assert [s["sim_time"] for s in states] == [0.0, pytest.approx((steps + 1) * 0.01)]
        obs, *_ = envs.step(push)  # and world 0 steps again
        assert obs["joint_pos"][0, 0] > 0
    finally:
        envs.close()


def test_same_step_autoreset_gives_the_final_observation_and_the_reset_one():
    envs = make_vector(2, model=CARTPOLE, max_episode_steps=3, autoreset_mode="SameStep")
    try:
        assert envs.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        start, _ = envs.reset()
        push = np.array([[1.0], [-1.0]])
        for _ in range(2):
            last, _, _, truncated, infos = envs.step(push)
            assert not truncated.any() and "final_obs" not in infos
        obs, _, _, truncated, infos = envs.step(push)
        assert truncated.tolist() == [True, True]
        assert bits(obs) == bits(start)  # reset in the same step
        assert infos["sim_time"].tolist() == [0.0, 0.0]
        assert infos["_final_obs"].tolist() == [True, True]
        assert infos["final_info"]["sim_time"].tolist() == [pytest.approx(0.03)] * 2
        final = infos["final_obs"][0]["joint_pos"]
        assert final[0] > last["joint_pos"][0, 0] > 0  # one step past the one before
    finally:
        envs.close()


def test_reset_mask_resets_only_the_worlds_it_names():
    envs = make_vector(3, model=CARTPOLE, autoreset_mode=AutoresetMode.DISABLED)
    try:
        start, _ = envs.reset()
        for _ in range(5):
            stepped, *_ = envs.step(np.ones((3, 1)))
        obs, infos = envs.reset(options={"reset_mask": np.array([False, True, False])})
        assert infos["_sim_time"].tolist() == [False, True, False] and infos["sim_time"][1] == 0.0
        assert bits(world(obs, 1)) == bits(world(start, 1))
        assert bits(world(obs, 0)) == bits(world(stepped, 0))
        with pytest.raises(ValueError, match="reset_mask"):
            envs.reset(options={"reset_mask": np.zeros(3, dtype=bool)})
    finally:
        envs.close()


def test_a_step_is_one_request_and_resets_are_batches_in_turn_past_the_limit(monkeypatch):
    """A step is one simulation.step_many request, not a batch; a step that resets worlds
    (NEXT_STEP) sends their restore_state and reads in a batch that ends with it; a reset
    past MAX_BATCH entries is sent as batches in turn. The same observations either way."""
    def ends_pushed(obs, action, next_obs):
        return bool(action[0] > 0.9)

    def trajectory(envs):
        out = [envs.reset()[0]]
        for action in (1.0, -0.5, 0.25):
            out.append(envs.step(np.array([[action], [-action], [0.0]]))[0])
        return [bits(obs) for obs in out]

    whole = make_vector(3, model=CARTPOLE, terminated_fn=ends_pushed)
    split = make_vector(3, model=CARTPOLE, terminated_fn=ends_pushed)
    try:
        expected = trajectory(whole)
        sent = []
        call_many, submit = split.client.call_many, split.client.submit
        monkeypatch.setattr(split.client, "call_many", lambda requests, **kw: sent.append(
            [f"{c}.{s}" for c, s, _ in requests]) or call_many(requests, **kw))
        monkeypatch.setattr(split.client, "submit", lambda c, s, *args: sent.append(f"{c}.{s}")
                            or submit(c, s, *args))
        monkeypatch.setattr(simgate.vector, "MAX_BATCH", 4)
        assert trajectory(split) == expected
        reads = ["cart.armature_pose.get_state", "cart.sensors.get_local_data"]
        assert sent == [
            ["simulation.restore_state", "w1/simulation.restore_state", "w2/simulation.restore_state",
             "cart.armature_pose.get_state"],  # reset(): 3 restores, 6 reads
            ["cart.sensors.get_local_data", "w1/cart.armature_pose.get_state",
             "w1/cart.sensors.get_local_data", "w2/cart.armature_pose.get_state"],
            ["w2/cart.sensors.get_local_data"],
            "simulation.step_many",  # world 0 ends its episode
            ["simulation.restore_state", *reads, "simulation.step_many"],  # world 0 reset, 1 and 2 step
            "simulation.step_many"]
    finally:
        whole.close()
        split.close()


# a cart driven by the second actuator of MuJoCo's ctrl: the first and the third act on a body
# no robot has
TWO_CARTS = """<mujoco model="two_carts">
  <option timestep="0.01"/>
  <worldbody>
    <body name="other" pos="0 2 0">
      <joint name="other_slide" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1" contype="0" conaffinity="0"/>
    </body>
    <body name="cart">
      <joint name="slide" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="push_other" joint="other_slide"/>
    <motor name="push" joint="slide" ctrllimited="true" ctrlrange="-1 1"/>
    <motor name="pull_other" joint="other_slide"/>
  </actuator>
</mujoco>
"""


def test_actions_go_where_mujocos_ctrl_has_them(tmp_path, monkeypatch):
    (tmp_path / "two_carts.xml").write_text(TWO_CARTS)
    config = tmp_path / "config.json"
    config.write_text(json.dumps({"scene": {"mjcf": "two_carts.xml"},
                                  "robots": [{"name": "cart", "type": "mjcf", "body": "cart"}]}))
    envs = make_vector(2, config=str(config))
    single = make(config=str(config))
    try:
        assert envs.action_names == ["cart.actuators/push"]
        sent = []
        submit = envs.client.submit
        monkeypatch.setattr(envs.client, "submit", lambda c, s, args, params: sent.append(params["actions"])
                            or submit(c, s, args, params))
        obs, _ = envs.reset()
        single_obs, _ = single.reset()
        for action in (0.5, -2.0):
            obs, *_ = envs.step(np.array([[action], [0.0]]))
            single_obs, *_ = single.step(np.array([action]))
            assert bits(world(obs, 0)) == bits(single_obs)
        # clipped, the others kept (the whole ctrl: simulation list_worlds' actuators)
        assert sent == [[[None, 0.5, None], [None, 0.0, None]], [[None, -1.0, None], [None, 0.0, None]]]
        assert obs["joint_pos"][:, 0].tolist() == [single_obs["joint_pos"][0], 0.0]
    finally:
        envs.close()
        single.close()


# ---- bad input, a diverging world
def test_bad_actions_are_refused_before_anything_is_sent():
    envs = make_vector(2, model=CARTPOLE, out_of_range="refuse")
    try:
        envs.reset()
        with pytest.raises(ValueError, match=r"shape \(2,\), expected \(2, 1\)"):
            envs.step(np.array([0.1, 0.2]))
        with pytest.raises(ValueError, match=r"shape \(3, 1\), expected \(2, 1\)"):
            envs.step(np.zeros((3, 1)))
        with pytest.raises(ValueError, match=r"actions\[1\]\[0\] \(cart.actuators/slide\) = nan: expected a finite"):
            envs.step(np.array([[0.0], [np.nan]]))
        with pytest.raises(ValueError, match=r"actions\[0\]\[0\] \(cart.actuators/slide\) = 1.5 is out of range"):
            envs.step(np.array([[1.5], [0.0]]))
        states = envs.client.call_many([("simulation", "get_simulation_state", None),
                                        ("w1/simulation", "get_simulation_state", None)])
        assert [s["steps"] for s in states] == [0, 0]  # nothing was sent
    finally:
        envs.close()


def test_step_before_reset_is_refused():
    envs = make_vector(2, model=CARTPOLE)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            envs.step(np.zeros((2, 1)))
    finally:
        envs.close()


def test_a_diverging_world_is_reported_truncated_and_reset(tmp_path):
    model = tmp_path / "pusher.xml"
    model.write_text(PUSHER)
    envs = make_vector(3, model=str(model))
    try:
        start, _ = envs.reset()
        obs, rewards, terminated, truncated, infos = envs.step(np.array([[0.0], [1e6], [0.0]]))
        assert truncated.tolist() == [False, True, False] and not terminated.any()
        assert infos["_diverged"].tolist() == [False, True, False]
        assert infos["diverged"]["quantity"][1] == "qacc[0]"
        assert infos["diverged"]["action"][1] == "pause"  # the scene's policy: the step undone
        assert infos["sim_time"].tolist() == [0.01, 0.0, 0.01]
        obs, _, _, truncated, infos = envs.step(np.zeros((3, 1)))  # world 1 reset instead
        assert infos["sim_time"].tolist() == [0.02, 0.0, 0.02] and not truncated.any()
        assert "diverged" not in infos and bits(world(obs, 1)) == bits(world(start, 1))
    finally:
        envs.close()


# ---- where the worlds come from
def test_attach_to_a_simgate_started_with_worlds(tmp_path):
    config = {"scene": {"mjcf": CARTPOLE}, "worlds": 3,
              "transports": {"jsonrpc": {"plugin": "jsonrpc", "options": {"host": "127.0.0.1", "port": 0}}},
              "robots": [{"name": "cart", "type": "mjcf", "body": "cart"}], "log_level": "warning"}
    gw = Gateway(tmp_path, config)  # playing, not paused
    try:
        with pytest.raises(ValueError, match="runs worlds 0, 1, 2: num_envs = 4 needs worlds 0 to 3"):
            SimgateVectorEnv(4, address=gw.url("jsonrpc"))
        envs = SimgateVectorEnv(2, address=gw.url("jsonrpc"))
        try:
            obs, infos = envs.reset()  # each world back to where it was paused
            times = infos["sim_time"]
            _, _, _, _, infos = envs.step(np.array([[1.0], [-1.0]]))
            assert infos["sim_time"].tolist() == pytest.approx((times + 0.01).tolist())
            controls = envs.client.call_many([("cart.actuators", "get_controls", None),
                                              ("w1/cart.actuators", "get_controls", None)])
            assert controls == [{"slide": 1.0}, {"slide": -1.0}]  # each world its action
        finally:
            envs.close()
        assert gw.process.poll() is None  # not ours to stop
        with simgate.connect(gw.url("jsonrpc")) as other:
            states = other.call_many([(w + "simulation", "get_simulation_state", None) for w in ("", "w1/", "w2/")])
        assert [s["state"] for s in states[:2]] == ["paused", "paused"]  # left paused
        assert states[0]["sim_time"] == pytest.approx(times[0] + 0.01)
        assert states[2]["state"] == "playing"  # not one of the environment's worlds
    finally:
        gw.kill()


def test_close_stops_and_reaps_simgate():
    envs = make_vector(1, model=CARTPOLE)  # one environment, one world
    pid = envs._server.process.pid
    assert alive(pid)
    envs.reset()
    obs, *_ = envs.step(np.ones((1, 1)))
    assert obs["joint_pos"].shape == (1, 2) and obs["joint_pos"][0, 0] > 0
    envs.close()
    assert not alive(pid)
    envs.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        envs.client


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="num_envs = 0"):
        SimgateVectorEnv(0, model=CARTPOLE)
    with pytest.raises(ValueError, match="exactly one of model"):
        SimgateVectorEnv(2)
    with pytest.raises(ValueError, match="autoreset_mode = 'later'"):
        SimgateVectorEnv(2, model=CARTPOLE, autoreset_mode="later")
    with pytest.raises(FileNotFoundError, match="no such file"):
        SimgateVectorEnv(2, model="/nonexistent/robot.xml")
