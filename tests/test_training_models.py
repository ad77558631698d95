"""The estimator, actors and algorithms of frbench.training: numbers by hand, gradients, checkpoints, a toy run."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from rsl_rl.algorithms import PPO
from rsl_rl.env import VecEnv
from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils import resolve_class

from frbench.policies.export import quiet_onnx_exporter
from frbench.training.algorithm import EstimatorPPO, RMAAdaptation
from frbench.networks.estimator import Estimator, EstimatorConfig, EstimatorOutput
from frbench.training.methods import METHODS, make_rma_adaptation_cfg, make_train_cfg

sys.path.insert(0, str(Path(__file__).resolve().parent))
from policy_factory import writing_torchscript  # noqa: E402

torch.set_num_threads(1)

D, A, H, LONG = 42, 12, 5, 50
MASS_SCALE = torch.tensor([15.0, 5.0, 5.0, 5.0])
GROUP_OF_JOINT = torch.arange(A) % 3 + 1  # hip, thigh, calf groups (1..3) of the 12 joints


class ToyEnv(VecEnv):
    """N envs whose hidden group masses show only in how the joints respond to actions.

    Joint j of env i sags in proportion to the scaled mass μ_k = m_k / s_k of its group
    k (hip, thigh, calf): q̇' = 0.5 q̇ + 0.5 (a − q) − μ_k + 0.2 ε; the base mass sags
    the angular velocity: ω' = 0.5 ω − 0.5 μ_base + 0.2 ε. Reward −mean_j (a_j − f_j)²,
    f_j = 2 (μ_k − 0.6): the best action depends on the hidden masses. Fixed-length
    episodes (timeouts). Groups follow the env contract; ``long_history`` (50 frames)
    only when asked for (it slows the mini-batches).
    """

    def __init__(self, num_envs: int = 64, episode_length: int = 32, seed: int = 0, long_history: bool = False) -> None:
        self.long_history = long_history
        self.num_envs, self.num_actions, self.device, self.cfg = num_envs, A, "cpu", {}
        self.max_episode_length = episode_length
        self.episode_length_buf = torch.zeros(num_envs, dtype=torch.long)
        self.gen = torch.Generator().manual_seed(seed)
        n = num_envs
        self.mass = torch.zeros(n, 4)
        self.q, self.qd, self.prev = torch.zeros(n, A), torch.zeros(n, A), torch.zeros(n, A)
        self.w = torch.zeros(n, 3)
        self.hist = torch.zeros(n, LONG, D)
        self.extra = torch.zeros(n, 2)
        self.rewards: list[float] = []
        self._reset(torch.ones(n, dtype=torch.bool))

    def _rand(self, *shape: int) -> torch.Tensor:
        return torch.rand(*shape, generator=self.gen)

    def _reset(self, ids: torch.Tensor) -> None:
        k = int(ids.sum())
        self.mass[ids] = torch.cat([6 + 8 * self._rand(k, 1), 1.5 + 3 * self._rand(k, 3)], dim=1)
        self.q[ids] = self._rand(k, A) - 0.5
        self.qd[ids], self.w[ids], self.prev[ids] = 0.0, 0.0, 0.0
        self.extra[ids] = self._rand(k, 2)
        self.hist[ids] = 0.0
        self.episode_length_buf[ids] = 0
        self.hist[ids, -1] = self._o()[ids]

    def _o(self) -> torch.Tensor:
        gravity = torch.tensor([0.0, 0.0, -1.0]).expand(self.num_envs, 3)
        return torch.cat([self.w, gravity, self.q, self.qd, self.prev], dim=1)

    def scaled_mass(self) -> torch.Tensor:
        return self.mass / MASS_SCALE

    def target_action(self) -> torch.Tensor:
        return 2.0 * (self.scaled_mass()[:, GROUP_OF_JOINT] - 0.6)

    def get_observations(self) -> TensorDict:
        n, o, m = self.num_envs, self._o(), self.scaled_mass()
        contact = torch.cat([(self.w.norm(dim=1, keepdim=True) > 1.0), self.q < 0], dim=1).float()
        privileged = torch.zeros(n, 277)
        privileged[:, :D], privileged[:, D:D + 4] = o, m
        groups = {
            "policy": o, "history": self.hist[:, -H:].reshape(n, H * D).clone(), "privileged": privileged,
            "mass": self.mass.clone(), "contact": contact, "velocity": self.qd[:, :3].clone(),
            "extrinsics": torch.cat([m, self.extra], dim=1),
        }
        if self.long_history:
            groups["long_history"] = self.hist.reshape(n, LONG * D).clone()
        return TensorDict(groups, batch_size=[n])

    def step(self, actions: torch.Tensor):
        a = actions.clamp(-3.0, 3.0)
        reward = -(a - self.target_action()).pow(2).mean(dim=1)
        mu = self.scaled_mass()
        noise = 0.2 * torch.randn(self.num_envs, A + 3, generator=self.gen)
        self.qd = 0.5 * self.qd + 0.5 * (a - self.q) - mu[:, GROUP_OF_JOINT] + noise[:, :A]
        self.q = (self.q + 0.1 * self.qd).clamp(-2.0, 2.0)
        self.w = 0.5 * self.w - 0.5 * mu[:, :1] + noise[:, A:]
        self.prev = a
        self.hist = torch.roll(self.hist, -1, dims=1)
        self.hist[:, -1] = self._o()
        self.episode_length_buf += 1
        dones = self.episode_length_buf >= self.max_episode_length
        if dones.any():
            self._reset(dones)
        self.rewards.append(float(reward.mean()))
        return self.get_observations(), reward, dones.long(), {"time_outs": dones.long()}


def toy_obs(n: int = 4) -> TensorDict:
    return ToyEnv(num_envs=n, long_history=True).get_observations()


# --- the loss by hand ---

def test_estimator_loss_matches_hand_computation():
    cfg = EstimatorConfig(history_frames=2, obs_dim=3, num_contacts=2, velocity=True, latent_dim=2,
                          encoder_hidden_dims=(8,), decoder_hidden_dims=(8,), mass_weight=2.0, contact_weight=3.0,
                          velocity_weight=0.5, recon_weight=0.25, kl_weight=0.1)
    est = Estimator(cfg)
    two = lambda rows: torch.tensor([rows, rows], dtype=torch.float32)  # noqa: E731 (two identical rows)
    out = EstimatorOutput(
        features=torch.zeros(2, cfg.feature_dim),
        mass=two([0.5, 0.2, 0.4, 0.6]),
        contact_logits=two([0.0, math.log(3.0)]),  # p = 0.5, 0.75
        velocity=two([0.5, 0.0, -1.0]),
        z_mean=two([1.0, 0.0]), z_logvar=two([0.0, math.log(4.0)]),
        recon=torch.tensor([[1.0, 2.0, 3.0], [100.0, 100.0, 100.0]]),
    )
    targets = {"mass": two([9.0, 2.0, 1.0, 3.0]), "contact": two([1.0, 0.0]), "velocity": two([0.0, 0.0, 0.0])}
    next_obs = torch.ones(2, 3)
    total, parts = est.loss(out, targets, next_obs, next_valid=torch.tensor([True, False]))

    mass = ((0.5 - 9 / 15) ** 2 + (0.2 - 2 / 5) ** 2 + (0.4 - 1 / 5) ** 2 + (0.6 - 3 / 5) ** 2) / 4  # 0.0225
    contact = -(math.log(0.5) + math.log(1 - 0.75)) / 2  # 1.5 ln 2
    velocity = (0.25 + 0 + 1) / 3
    recon = (0 + 1 + 4) / 3  # the second pair crosses an episode end
    kl = 0.5 * ((1 + 1 - 1 - 0) + (0 + 4 - 1 - math.log(4.0)))
    assert mass == pytest.approx(0.0225)
    for key, value in {"mass": mass, "contact": contact, "velocity": velocity, "recon": recon, "kl": kl}.items():
        assert float(parts[key]) == pytest.approx(value, rel=1e-6), key
    expected = 2 * mass + 3 * contact + 0.5 * velocity + 0.25 * recon + 0.1 * kl
    assert float(total) == pytest.approx(expected, rel=1e-6)


def test_estimator_forward_layout_and_sampling():
    torch.manual_seed(0)
    cfg = EstimatorConfig(encoder_hidden_dims=(16,), decoder_hidden_dims=(16,))
    est = Estimator(cfg)
    h = torch.randn(7, cfg.input_dim)
    est.eval()
    out = est(h)
    assert out.features.shape == (7, 4 + 13 + 16) and out.recon.shape == (7, 42)
    torch.testing.assert_close(out.z, out.z_mean)
    torch.testing.assert_close(out.contact, torch.sigmoid(out.contact_logits))
    torch.testing.assert_close(out.features, torch.cat([out.mass, out.contact, out.z_mean], dim=1))
    torch.testing.assert_close(est.policy_features(h), out.features)
    est.train()
    sampled = est(h)
    assert not torch.allclose(sampled.z, sampled.z_mean)  # reparameterised sample in training
    torch.testing.assert_close(sampled.features, out.features)  # the policy's features stay deterministic
    no_vae = Estimator(EstimatorConfig(latent_dim=0, encoder_hidden_dims=(16,)))
    assert no_vae.decoder is None and no_vae(h).recon is None and no_vae(h).features.shape == (7, 17)


# --- actor input sizes ---

@pytest.mark.parametrize("method, dim", [("frnet", 75), ("frnet-no-mass", 71), ("frnet-no-contact", 62),
                                         ("frnet-no-est", 59), ("dreamriser", 42 + 3 + 16), ("rma", 42 + 8),
                                         ("ppo", 42)])
def test_actor_latent_dims(method, dim):
    cfg = make_train_cfg(method)
    obs = toy_obs()
    actor_class, actor_cfg = resolve_class(cfg["actor"])
    actor = actor_class(obs, cfg["obs_groups"], "actor", A, **actor_cfg)
    assert actor._get_latent_dim() == dim
    assert actor.get_latent(obs).shape == (4, dim)
    assert actor(obs).shape == (4, A)
    critic_class, critic_cfg = resolve_class(cfg["critic"])
    assert critic_class(obs, cfg["obs_groups"], "critic", 1, **critic_cfg).obs_dim == 277


def test_every_method_is_configured():
    assert set(METHODS) == {"frnet", "frnet-no-mass", "frnet-no-contact", "frnet-no-est", "dreamriser", "rma", "ppo"}
    cfg = make_train_cfg("frnet", {"algorithm": {"learning_rate": 5e-4}, "num_steps_per_env": 12})
    assert cfg["algorithm"]["learning_rate"] == 5e-4 and cfg["algorithm"]["desired_kl"] == 0.01
    assert cfg["num_steps_per_env"] == 12 and METHODS["frnet"]["algorithm"]["learning_rate"] == 1e-3
    with pytest.raises(KeyError, match="did you mean 'frnet'"):
        make_train_cfg("frnte")


# --- runner helpers ---

def make_runner(method: str = "frnet", seed: int = 0, num_envs: int = 64, overrides: dict | None = None,
                long_history: bool = False):
    torch.manual_seed(seed)
    env = ToyEnv(num_envs=num_envs, seed=seed, long_history=long_history)
    runner = OnPolicyRunner(env, make_train_cfg(method, overrides), log_dir=None, device="cpu")
    return env, runner


def record_losses(runner) -> list[dict]:
    losses: list[dict] = []
    update = runner.alg.update
    runner.alg.update = lambda: losses.append(update()) or losses[-1]
    return losses


# --- gradients ---

def test_ppo_loss_does_not_reach_the_estimator_and_its_own_loss_does():
    env, runner = make_runner("frnet", num_envs=16)
    alg: EstimatorPPO = runner.alg
    actor, est = alg.actor, alg.estimator
    obs = env.get_observations()
    assert {id(p) for p in est.parameters()}.isdisjoint(id(p) for g in alg.optimizer.param_groups for p in g["params"])

    actions = actor(obs, stochastic_output=True)
    loss = -actor.get_output_log_prob(actions.detach()).mean() + alg.critic(obs).pow(2).mean()
    loss.backward()
    assert all(p.grad is None for p in est.parameters())
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in actor.mlp.parameters())

    actor.zero_grad(set_to_none=True)
    history = actor.normalize_history(obs["history"])
    out = est(history)
    total, _ = est.loss(out, {"mass": obs["mass"], "contact": obs["contact"]}, actor.normalize_obs(obs["policy"]))
    total.backward()
    assert all(p.grad is not None for p in est.encoder.parameters()) and est.decoder[0].weight.grad.abs().sum() > 0
    assert all(p.grad is None for p in actor.mlp.parameters())

    # one full iteration: PPO's half leaves the estimator alone, the estimator's half moves it
    runner.learn(1)
    before = {k: v.clone() for k, v in est.state_dict().items()}
    policy_before = {k: v.clone() for k, v in actor.mlp.state_dict().items()}
    with torch.inference_mode():
        o = env.get_observations()
        for _ in range(runner.cfg["num_steps_per_env"]):
            o, r, d, x = env.step(alg.act(o))
            alg.process_env_step(o, r, d, x)
        alg.compute_returns(o)
    PPO.update(alg)
    assert all(torch.equal(before[k], v) for k, v in est.state_dict().items())
    assert any(not torch.equal(policy_before[k], v) for k, v in actor.mlp.state_dict().items())


def test_the_estimator_trains_on_ppos_mini_batches_with_one_encoder_pass_each(monkeypatch):
    monkeypatch.setenv("FRBENCH_UPDATE_THREADS", "2")
    env, runner = make_runner("frnet", num_envs=16)
    alg: EstimatorPPO = runner.alg
    est = alg.estimator
    passes, threads = [], []

    def record(*_):
        passes.append(torch.is_grad_enabled())
        threads.append(torch.get_num_threads())

    est.encoder.register_forward_hook(record)
    torch.set_num_threads(1)
    with torch.inference_mode():
        o = env.get_observations()
        for _ in range(runner.cfg["num_steps_per_env"]):
            o, r, d, x = env.step(alg.act(o))
            alg.process_env_step(o, r, d, x)
        alg.compute_returns(o)
    rollout_passes = len(passes)
    before = {k: v.clone() for k, v in est.state_dict().items()}
    losses = alg.update()
    updates = alg.num_learning_epochs * alg.num_mini_batches
    assert passes[rollout_passes:] == [True] * updates  # the actor's pass of each mini-batch, nothing else
    assert threads[:rollout_passes] == [1] * rollout_passes and threads[rollout_passes:] == [2] * updates
    assert torch.get_num_threads() == 1  # restored for the next rollout
    assert set(losses) >= {"estimator", "estimator_mass", "estimator_contact", "estimator_recon", "estimator_kl"}
    assert any(not torch.equal(before[k], v) for k, v in est.state_dict().items())
    assert alg.storage.observations.get("estimator_next_obs", None) is None  # the update's groups are gone
    with pytest.raises(ValueError, match="estimator_epochs = 3"):
        make_runner("frnet", num_envs=16, overrides={"algorithm": {"estimator_epochs": 3}})


def test_fused_optimisers_step_as_plain_adam_and_resume_its_state():
    """Both optimisers use torch's fused Adam; a step equals plain (rsl-rl's) Adam's to float32 round-off, and a
    plain-Adam optimiser state (checkpoints written before) loads and continues."""
    env, runner = make_runner("frnet", num_envs=16)
    alg: EstimatorPPO = runner.alg
    assert alg.optimizer.defaults["fused"] and alg.estimator_optimizer.defaults["fused"]
    params = [p for g in alg.optimizer.param_groups for p in g["params"]]
    twins = [p.detach().clone().requires_grad_(True) for p in params]
    plain = torch.optim.Adam(twins, lr=1e-3)
    generator = torch.Generator().manual_seed(0)
    for _ in range(3):
        for p, twin in zip(params, twins):
            p.grad = torch.randn(p.shape, generator=generator)
            twin.grad = p.grad.clone()
        alg.optimizer.step()
        plain.step()
    worst = max(float((p - twin).detach().abs().max()) for p, twin in zip(params, twins))
    assert worst < 1e-6  # three steps of 1e-3 each: the kernels agree to round-off
    alg.optimizer.load_state_dict(plain.state_dict())
    assert float(alg.optimizer.state_dict()["state"][0]["step"]) == 3.0
    runner.learn(1)  # continues from the loaded state
    assert float(alg.optimizer.state_dict()["state"][0]["step"]) > 3.0


def test_estimator_batch_pairs_each_step_with_the_next_observation():
    env, runner = make_runner("frnet", num_envs=4, overrides={"num_steps_per_env": 12})
    env.max_episode_length = 5  # episode ends inside the rollout
    alg: EstimatorPPO = runner.alg
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(12):
            obs, r, d, x = env.step(alg.act(obs))
            alg.process_env_step(obs, r, d, x)
        alg.compute_returns(obs)
    next_o, valid = alg.estimator_targets()
    stored, dones = alg.storage.observations, alg.storage.dones.squeeze(-1)
    norm = alg.actor.normalize_obs
    assert next_o.shape == (12, 4, D) and valid.shape == (12, 4)
    # step t of env i holds o_{t+1} of env i
    torch.testing.assert_close(next_o[:11], norm(stored["policy"][1:]))
    torch.testing.assert_close(next_o[11], norm(obs["policy"]))  # the last step's successor: compute_returns' obs
    assert torch.equal(valid, (dones == 0).float()) and 0 < int((valid == 0).sum()) < 48


# --- checkpoints and export ---

def test_checkpoint_roundtrip_and_exports(tmp_path):
    onnx = pytest.importorskip("onnx")
    env, runner = make_runner("frnet", seed=1, num_envs=16)
    runner.learn(2)
    path = tmp_path / "model.pt"
    runner.save(str(path))
    saved = torch.load(path, weights_only=False)
    assert "estimator_optimizer_state_dict" in saved

    _, fresh = make_runner("frnet", seed=2, num_envs=16)
    obs = env.get_observations()
    policy, fresh_policy = runner.get_inference_policy(), fresh.get_inference_policy()
    assert not torch.allclose(policy(obs), fresh_policy(obs))
    fresh.load(str(path))
    fresh_policy = fresh.get_inference_policy()
    torch.testing.assert_close(fresh_policy(obs), policy(obs), rtol=0, atol=0)
    adam_steps = fresh.alg.estimator_optimizer.state_dict()["state"][0]["step"]
    assert adam_steps == saved["estimator_optimizer_state_dict"]["state"][0]["step"] > 0
    assert float(policy.obs_normalizer.count) > 0  # the statistics travelled too
    torch.testing.assert_close(fresh_policy.obs_normalizer._mean, policy.obs_normalizer._mean)

    expected = policy(obs).detach()
    # TorchScript, as rsl-rl's runner writes it for a user (torch.jit.script and save): raw o_t and history in,
    # actions out
    with writing_torchscript():
        runner.export_policy_to_jit(str(tmp_path), "policy.pt")
        jit = torch.jit.load(str(tmp_path / "policy.pt"))
    torch.testing.assert_close(jit(obs["policy"], obs["history"]), expected, rtol=0, atol=1e-5)

    # ONNX, opset 18 through the runner's torch.onnx.export call (torch's current exporter)
    with quiet_onnx_exporter():
        runner.export_policy_to_onnx(str(tmp_path), "policy.onnx")
    model = onnx.load(str(tmp_path / "policy.onnx"))
    onnx.checker.check_model(model)
    assert [i.name for i in model.graph.input] == ["obs", "history"]
    assert [o.name for o in model.graph.output] == ["actions"]
    # onnxruntime is not installed: onnx's own reference evaluator runs the graph (numpy, float32)
    from onnx.reference import ReferenceEvaluator

    single = {"obs": obs["policy"][:1].numpy(), "history": obs["history"][:1].numpy()}
    (actions,) = ReferenceEvaluator(model).run(None, single)
    torch.testing.assert_close(torch.from_numpy(actions), expected[:1], rtol=0, atol=1e-5)


# --- a toy run that must learn ---

def test_frnet_learns_on_the_toy_env():
    # The frnet config as is, but for discounting and the initial noise: the toy's reward is myopic (the
    # action at t only scores at t), so γ = λ = 0.5 keeps 20 steps of other actions' noise out of each
    # advantage; the toy's actions are O(1), so it starts from std 1 (the recovery task's 0.5 is in joint units).
    env, runner = make_runner("frnet", seed=0, num_envs=64, overrides={
        "algorithm": {"gamma": 0.5, "lam": 0.5}, "actor": {"distribution_cfg": {"init_std": 1.0}}})
    losses = record_losses(runner)
    runner.learn(25)
    steps = runner.cfg["num_steps_per_env"]
    reward = [sum(env.rewards[i * steps:(i + 1) * steps]) / steps for i in range(len(losses))]
    mass = [d["estimator_mass"] for d in losses]
    first, last = sum(reward[:3]) / 3, sum(reward[-3:]) / 3  # about −1.10 → −0.84 (seeds 0, 1, 2)
    assert last > first + 0.15, (first, last)
    assert sum(mass[-3:]) / 3 < 0.5 * sum(mass[:3]) / 3, mass  # about 0.05 → 0.009
    # the mass estimate tracks the hidden masses better than their mean would
    obs = env.get_observations()
    actor = runner.alg.actor
    est_out = runner.alg.estimator(actor.normalize_history(obs["history"]), sample=False)
    err = (est_out.mass - obs["mass"] / MASS_SCALE).pow(2).mean()
    spread = (obs["mass"] / MASS_SCALE).var(dim=0).mean()
    assert err < 0.5 * spread, (float(err), float(spread))  # about 0.01 vs 0.03


# --- RMA ---

def test_rma_phase_two_regresses_the_phase_one_latent(tmp_path):
    env, runner = make_runner("rma", seed=0, num_envs=32, long_history=True)
    runner.learn(2)
    path = tmp_path / "phase1.pt"
    runner.save(str(path))

    torch.manual_seed(0)
    phase2 = OnPolicyRunner(env, make_rma_adaptation_cfg({"num_steps_per_env": 16}), log_dir=None, device="cpu")
    alg: RMAAdaptation = phase2.alg
    assert alg.actor.use_adaptation and alg.actor.adaptation.out.out_features == 8
    phase2.load(str(path))
    obs = env.get_observations()
    torch.testing.assert_close(alg.actor.extrinsics_latent(obs), runner.alg.actor.extrinsics_latent(obs))
    frozen = {k: v.clone() for k, v in alg.actor.state_dict().items() if not k.startswith("adaptation.")}
    losses = record_losses(phase2)
    phase2.learn(16)
    # 16-step rollouts alternate between first and second episode halves (the first has a
    # zero-padded long history): compare two whole episodes at each end
    loss = [d["adaptation"] for d in losses]
    first, last = sum(loss[:4]) / 4, sum(loss[-4:]) / 4  # about 0.053 → 0.027
    z_var = float(alg.actor.extrinsics_latent(obs).detach().var(dim=0).mean())  # about 0.06: predicting the mean
    assert last < 0.7 * first and last < z_var, (loss, z_var)
    assert all(torch.equal(frozen[k], v) for k, v in alg.actor.state_dict().items() if k in frozen)
    jit = alg.actor.as_jit()
    torch.testing.assert_close(jit(obs["policy"], obs["long_history"]), alg.actor(obs).detach(), atol=1e-5, rtol=0)
