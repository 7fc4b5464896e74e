"""DrQ: the random shift on hand-made frames, the DrQ targets and losses read from SB3's own
train(), and that acting never sees a shifted frame."""

from types import SimpleNamespace

import numpy as np
import pytest
import stable_baselines3.dqn.dqn
import stable_baselines3.sac.sac
import torch
from stable_baselines3.common.logger import Logger

from senbench.errors import SuiteError
from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.suite import load_suite
from senbench_agents.augment import random_shift, scaled_pad

# --- the shift ---------------------------------------------------------------------------


def test_a_shift_reads_the_frame_at_the_offset_with_its_edges_repeated():
    frame = torch.arange(16, dtype=torch.uint8).reshape(1, 1, 4, 4)
    generator = torch.Generator().manual_seed(0)
    offsets = torch.randint(-1, 2, (2, 1), generator=torch.Generator().manual_seed(0))
    dy, dx = int(offsets[0, 0]), int(offsets[1, 0])
    out = random_shift(frame, 1, generator)
    # pad by 1 with the edge repeated, crop back at (1 + dy, 1 + dx): by hand with numpy
    padded = np.pad(frame[0, 0].numpy(), 1, mode="edge")
    assert np.array_equal(out[0, 0].numpy(), padded[1 + dy:5 + dy, 1 + dx:5 + dx])
    assert out.dtype == torch.uint8


def test_one_shift_by_hand():
    frame = torch.tensor([[[[1, 2, 3], [4, 5, 6], [7, 8, 9]]]], dtype=torch.uint8)
    seen = set()
    for seed in range(40):
        out = random_shift(frame, 1, torch.Generator().manual_seed(seed))[0, 0].tolist()
        seen.add(str(out))
        if out[0][0] == 1 and out[2][2] == 5:  # moved down-right by one: (dy, dx) = (-1, -1)
            assert out == [[1, 1, 2], [1, 1, 2], [4, 4, 5]]
    assert len(seen) == 9  # all 3x3 shifts of pad 1, and nothing else (a 3x3 frame)


def test_the_stack_shifts_together_and_each_stack_of_the_batch_on_its_own():
    generator = torch.Generator().manual_seed(1)
    first = torch.randint(0, 200, (64, 1, 12, 12), generator=generator)
    stack = torch.cat([first, first + 50], dim=1)  # frame 2 = frame 1 + 50, pixel by pixel
    out = random_shift(stack, 3, generator)
    assert torch.equal(out[:, 1], out[:, 0] + 50)
    same = torch.cat([first[:1]] * 64)
    shifted = random_shift(same, 3, generator)
    assert len({shifted[i].numpy().tobytes() for i in range(64)}) > 20


def test_every_offset_within_the_pad_and_none_beyond():
    frame = torch.zeros(2000, 1, 9, 9)
    frame[:, 0, 4, 4] = 1  # one lit pixel at the centre: where it lands is the shift
    out = random_shift(frame, 2, torch.Generator().manual_seed(3))
    where = out[:, 0].flatten(1).argmax(1)
    rows, cols = where // 9 - 4, where % 9 - 4
    assert out.sum() == 2000
    assert set(zip(rows.tolist(), cols.tolist(), strict=True)) == {
        (r, c) for r in range(-2, 3) for c in range(-2, 3)}


def test_the_pad_scales_with_the_frame_and_may_not_exceed_half_of_it():
    assert scaled_pad(84, 84) == 4 and scaled_pad(64, 64) == 3 and scaled_pad(36, 48) == 2
    with pytest.raises(ValueError, match=r"pad must be in \[0, 4\]"):
        random_shift(torch.zeros(1, 1, 8, 8), 5)
    assert random_shift(frame := torch.ones(1, 1, 4, 4), 0) is frame


# --- discrete DrQ on SB3's DQN ----------------------------------------------------------

FRAMES = PixelSpec(36, 36, 2)


def pixel_learner(name: str, **hyperparams):
    regs = registries()
    spec = regs.envs.get("mountaincar" if name == "drq" else "pendulum")
    agent = regs.agents.get(name)
    cfg = agent.config(**{"learning_starts": 0, "buffer_size": 64, "features_dim": 16,
                          **hyperparams})

    def make():
        return make_env(spec, "pixels", 200, {}, FRAMES)

    learner = agent.make(AgentContext(cfg, spec, make, 0, 1))
    learner.model.set_logger(Logger(folder=None, output_formats=[]))
    return learner


def frames(count: int, seed: int) -> torch.Tensor:
    return torch.randint(0, 256, (count, 2, 36, 36), dtype=torch.uint8,
                         generator=torch.Generator().manual_seed(seed))


def filled(learner, count: int = 20):
    model = learner.model
    for i in range(count):
        model.replay_buffer.add(frames(1, i).numpy(), frames(1, i + 100).numpy(),
                                np.array([[0.5]]), np.array([float(i)]), np.array([False]), [{}])
    return model


def recorded_target(model, batch, monkeypatch, module, loss_name):
    targets = []
    loss = getattr(module.F, loss_name)

    def recording(current, target):
        targets.append(target)
        return loss(current, target)

    monkeypatch.setattr(module.F, loss_name, recording)
    monkeypatch.setattr(model.replay_buffer, "sample", lambda *args, **kwargs: batch)
    model.train(gradient_steps=1, batch_size=len(batch.rewards))
    return targets


def test_drq_target_averages_k_shifts_of_the_double_dqn_value(monkeypatch):
    model = pixel_learner("drq", k=2, gamma=0.9).model
    calls = iter([lambda x: x.roll(1, dims=-1), lambda x: x.flip(-2)] * 3)
    model.q_net_target.shift = lambda x: next(calls)(x)
    model.q_net.shift = lambda x: x
    nxt = frames(4, 0)
    batch = SimpleNamespace(observations=frames(4, 1), actions=torch.tensor([[0], [1], [2], [0]]),
                            next_observations=nxt, rewards=torch.full((4, 1), -1.0),
                            dones=torch.tensor([[0.0], [0.0], [0.0], [1.0]]), discounts=None)
    with torch.no_grad():
        online, target = model.policy.q_net, model.policy.q_net_target
        values = [target(x).gather(1, online(x).argmax(1, keepdim=True))
                  for x in (nxt.roll(1, dims=-1), nxt.flip(-2))]
    [y] = recorded_target(model, batch, monkeypatch, stable_baselines3.dqn.dqn, "smooth_l1_loss")
    not_done = torch.tensor([[0.9], [0.9], [0.9], [0.0]])
    assert torch.allclose(y, -1 + not_done * (values[0] + values[1]) / 2)


def test_drq_with_m_copies_shifts_each_copy_and_shares_their_target():
    learner = pixel_learner("drq", m=3)
    model = learner.model
    for _ in range(20):
        model.replay_buffer.add(frames(1, 2).numpy(), frames(1, 3).numpy(), np.array([1]),
                                np.array([-1.0]), np.array([False]), [{}])
    batch = model.replay_buffer.sample(5)
    assert batch.observations.shape[0] == 15
    assert torch.equal(batch.observations[:5], batch.observations[10:])  # copies, unshifted
    with torch.no_grad():
        out = model.q_net_target(batch.next_observations)
    value = out.max(dim=1).values
    assert torch.equal(value[:5], value[5:10]) and torch.equal(value[:5], value[10:])
    shifted = model.q_net.shift(batch.observations)
    assert not torch.equal(shifted[:5], shifted[5:10])


def test_acting_never_shifts(monkeypatch):
    def refuse(frames):
        raise AssertionError("acting saw a shifted frame")

    class Budget:
        def step(self, frames):
            return frames < 40

        def episode(self, *args):
            pass

    observation = frames(1, 5)[0].numpy()
    learner = pixel_learner("drq", k=2, m=2, learning_starts=10, batch_size=4)
    learner.learn(40, Budget())  # updates shift; then acting must not
    learner.model.q_net.shift = learner.model.q_net_target.shift = refuse
    assert learner.act(observation) in (0, 1, 2)
    assert type(learner.model.policy.q_net).__name__ == "QNetwork"
    sac = pixel_learner("drq-sac", learning_starts=10, batch_size=4)
    sac.learn(40, Budget())
    monkeypatch.setattr(type(sac.model.replay_buffer), "sample", refuse)
    assert sac.act(observation).shape == (1,)


# --- DrQ's SAC ---------------------------------------------------------------------------


def test_drq_sac_samples_m_times_k_rows_and_trains_on_them(monkeypatch):
    model = filled(pixel_learner("drq-sac", k=2, m=3, batch_size=4))
    batch = model.replay_buffer.sample(4)
    assert batch.observations.shape == (24, 2, 36, 36) and batch.rewards.shape == (24, 1)
    obs = batch.observations.reshape(3, 2, 4, 2, 36, 36)
    nxt = batch.next_observations.reshape(3, 2, 4, 2, 36, 36)
    assert torch.equal(obs[:, 0], obs[:, 1])  # the k copies share shift_m(s)
    assert torch.equal(nxt[0], nxt[1]) and torch.equal(nxt[0], nxt[2])  # the m share shift_k
    assert not torch.equal(obs[0, 0], obs[1, 0]) and not torch.equal(nxt[0, 0], nxt[0, 1])
    rewards = batch.rewards.reshape(6, 4)
    assert (rewards == rewards[0]).all()
    before = [p.clone() for p in model.critic.parameters()]
    model.train(gradient_steps=1, batch_size=4)
    assert any(not torch.equal(a, b) for a, b in zip(before, model.critic.parameters(),
                                                     strict=True))


@pytest.mark.parametrize("interval", [1, 2, 3])
def test_sac_moves_its_targets_every_interval_updates_over_the_run(interval):
    # SB3 counts the interval within one train() call: at one update a call, every one
    learner = pixel_learner("drq-sac", target_update_interval=interval, batch_size=4)
    model = learner.model
    for i in range(20):
        model.replay_buffer.add(frames(1, i).numpy(), frames(1, i + 100).numpy(),
                                np.array([[0.5]]), np.array([float(i)]), np.array([False]), [{}])
    moved = []
    for _ in range(6):
        before = [p.clone() for p in model.critic_target.parameters()]
        model.train(gradient_steps=1, batch_size=4)
        moved.append(any(not torch.equal(a, b) for a, b in
                         zip(before, model.critic_target.parameters(), strict=True)))
    assert moved == [i % interval == 0 for i in range(6)]
    assert model.tau == 0.01  # restored after the updates that leave the targets


# --- validation -------------------------------------------------------------------------


def suite_with(write_suite, method: str, pixels: str = "{height: 64, width: 64}"):
    return write_suite(f"""\
        name: drq-checks
        envs:
          mountaincar: {{}}
          pendulum: {{}}
        methods:
          {method}
        pixels: {pixels}
        seeds: 1
        budget: 100
        eval: {{every: 100, episodes: 1}}
        """)


def test_drq_on_the_state_is_refused_naming_pixels(write_suite):
    path = suite_with(write_suite, "drq-state: {agent: drq, envs: [mountaincar]}")
    with pytest.raises(SuiteError, match="drq.*pixels"):
        load_suite(path, registries())


def test_a_pad_over_half_the_frame_and_k_below_one_are_errors_at_their_lines(write_suite):
    path = suite_with(write_suite, "drq-pixels: {agent: drq, observation: pixels, envs: "
                      "[mountaincar], hyperparams: {pad: 40}}\n"
                      "          drq-sac-pixels: {agent: drq-sac, observation: pixels, envs: "
                      "[pendulum], hyperparams: {k: 0}}")
    with pytest.raises(SuiteError) as error:
        load_suite(path, registries())
    text = str(error.value)
    assert "drq' with these hyperparams needs frames of at least 80x80" in text
    assert "k" in text and "greater than or equal to 1" in text


def test_drq_target_update_copies_the_online_network_into_the_target():
    model = pixel_learner("drq").model  # DrQ's target: a copy at every update
    online, target = model.policy.q_net, model.policy.q_net_target
    with torch.no_grad():
        for p in online.parameters():
            p.add_(1.0)
    model._on_step()
    for now, copied in zip(online.parameters(), target.parameters(), strict=True):
        assert torch.equal(now, copied)
    assert list(model.q_net.parameters()) == list(online.parameters())


def test_drq_sac_defaults_are_the_sized_set_the_docs_state():
    from senbench_agents.sac import DRQ_SIZED, DrQSACConfig

    config = DrQSACConfig()
    assert {key: getattr(config, key) for key in DRQ_SIZED} == DRQ_SIZED
    assert (config.k, config.m, config.pad) == (1, 1, None)


def test_drq_sac_networks_end_in_drq_s_head_and_sac_s_keep_nature_cnn_s():
    from gymnasium.spaces import Box
    from stable_baselines3.common.torch_layers import NatureCNN

    from senbench_agents.sb3 import features_extractor_class

    drq = pixel_learner("drq-sac", learning_starts=10, batch_size=4)
    for net in (drq.model.actor, drq.model.critic, drq.model.critic_target):
        head = [type(layer).__name__ for layer in net.features_extractor.linear]
        assert head == ["Linear", "LayerNorm", "Tanh"]
    assert type(pixel_learner("sac", features_head="relu").model.actor.features_extractor) \
        is NatureCNN
    # the head's Linear is NatureCNN's own: from one seed they start with the same weights
    space = Box(0, 255, (2, 36, 36), np.uint8)
    torch.manual_seed(3)
    nature = NatureCNN(space, features_dim=8)
    torch.manual_seed(3)
    ours = features_extractor_class("layernorm-tanh")(space, features_dim=8)
    assert torch.equal(nature.linear[0].weight, ours.linear[0].weight)
    # bounded and spread over frames, where a ReLU head may output 0 everywhere
    features = ours(frames(16, 2).float())
    assert features.abs().max() < 1 and features.std(0).min() > 0


def test_the_dqn_learners_keep_nature_cnn_s_head_unless_drq_s_is_asked_for():
    from stable_baselines3.common.torch_layers import NatureCNN

    from senbench_agents.dqn import DQNConfig

    assert type(pixel_learner("drq").model.policy.q_net.features_extractor) is NatureCNN
    assert "features_head" in DQNConfig.LATE_FIELDS  # so the cells before it keep their ids
    drq = pixel_learner("drq", features_head="layernorm-tanh")
    for net in (drq.model.policy.q_net, drq.model.policy.q_net_target):
        head = [type(layer).__name__ for layer in net.features_extractor.linear]
        assert head == ["Linear", "LayerNorm", "Tanh"]


def test_a_features_head_drq_does_not_have_is_an_error_naming_the_heads(write_suite):
    with pytest.raises(SuiteError, match="relu.*layernorm-tanh"):
        load_suite(suite_with(write_suite, "drq-sac-pixels: {agent: drq-sac, observation: "
                              "pixels, envs: [pendulum], hyperparams: {features_head: gelu}}"),
                   registries())


# --- DrQ's tie: the actor reads the critic's convolutions, which only the critic trains ---

def test_drq_sac_s_actor_reads_the_critic_s_convolutions_and_owns_only_its_head():
    model = filled(pixel_learner("drq-sac", batch_size=4))
    actor, critic = model.actor.features_extractor, model.critic.features_extractor
    assert actor.cnn.convs is critic.cnn
    owned = {id(p) for p in model.actor.parameters()}
    optimised = {id(p) for group in model.actor.optimizer.param_groups for p in group["params"]}
    assert owned == optimised
    assert not owned & {id(p) for p in critic.cnn.parameters()}
    assert {id(p) for p in actor.linear.parameters()} <= owned
    # the target critic keeps convolutions of its own, a copy of the critic's
    assert model.critic_target.features_extractor.cnn is not critic.cnn


def test_the_actor_s_loss_leaves_the_convolutions_to_the_critic(monkeypatch):
    model = filled(pixel_learner("drq-sac", batch_size=4))
    convs = model.critic.features_extractor.cnn
    critic_step = model.critic.optimizer.step
    after_critic = {}

    def recording_step(*args, **kwargs):  # the convolutions as the critic's update left them
        out = critic_step(*args, **kwargs)
        after_critic["convs"] = [p.detach().clone() for p in convs.parameters()]
        return out

    monkeypatch.setattr(model.critic.optimizer, "step", recording_step)
    before = [p.detach().clone() for p in convs.parameters()]
    head = [p.detach().clone() for p in model.actor.features_extractor.linear.parameters()]
    model.train(gradient_steps=1, batch_size=4)
    now = [p.detach() for p in convs.parameters()]
    assert any(not torch.equal(a, b) for a, b in zip(before, now, strict=True))  # critic's
    assert all(torch.equal(a, b) for a, b in zip(after_critic["convs"], now, strict=True))
    assert any(not torch.equal(a, b) for a, b in zip(
        head, model.actor.features_extractor.linear.parameters(), strict=True))


def test_with_its_own_convolutions_the_actor_trains_them():
    model = filled(pixel_learner("drq-sac", batch_size=4, actor_convs="own"))
    actor_convs = model.actor.features_extractor.cnn
    assert actor_convs is not model.critic.features_extractor.cnn
    before = [p.detach().clone() for p in actor_convs.parameters()]
    model.train(gradient_steps=1, batch_size=4)
    assert any(not torch.equal(a, b) for a, b in zip(before, actor_convs.parameters(),
                                                     strict=True))


def test_sac_takes_drq_s_tie_on_pixels_by_default_and_keeps_old_ids_elsewhere():
    from senbench_agents.sac import DrQSACConfig, SACConfig

    assert SACConfig().actor_convs == "own" and "actor_convs" in SACConfig.LATE_FIELDS
    assert DrQSACConfig().actor_convs == "critic"
    sac = pixel_learner("sac", **{"actor_convs": "critic"})
    assert sac.model.actor.features_extractor.cnn.convs is sac.model.critic.features_extractor.cnn


def test_an_actor_convs_sac_does_not_have_is_an_error_naming_both(write_suite):
    with pytest.raises(SuiteError, match="own.*critic"):
        load_suite(suite_with(write_suite, "drq-sac-pixels: {agent: drq-sac, observation: "
                              "pixels, envs: [pendulum], hyperparams: {actor_convs: both}}"),
                   registries())
