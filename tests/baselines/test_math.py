"""The baselines' arithmetic against values computed by hand on tiny examples."""
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from league.baselines.common.buffers import ReplayBuffer  # noqa: E402
from league.baselines.common.networks import adam, anneal_learning_rates, polyak_update  # noqa: E402
from league.baselines.common.plots import moving_average  # noqa: E402
from league.baselines.dsac import critic_loss, critic_targets  # noqa: E402
from league.baselines.ppo import compute_gae  # noqa: E402


def test_gae_by_hand():
    # One car, three steps, the episode ends with step 1 (a crash), a new one starts at step 2.
    gamma, lam = 0.9, 0.5
    rewards = torch.tensor([[1.0], [2.0], [3.0]])
    values = torch.tensor([[0.5], [1.0], [2.0]])
    dones = torch.tensor([[0.0], [1.0], [0.0]])
    next_value = torch.tensor([4.0])
    # δ2 = 3 + 0.9·4 − 2 = 4.6                 Â2 = 4.6
    # δ1 = 2 + 0 − 1 = 1.0 (episode ended)     Â1 = 1.0 (nothing flows back across the end)
    # δ0 = 1 + 0.9·1.0 − 0.5 = 1.4             Â0 = 1.4 + 0.9·0.5·1.0 = 1.85
    advantages, returns = compute_gae(rewards, values, dones, next_value, gamma, lam)
    assert advantages[:, 0].tolist() == pytest.approx([1.85, 1.0, 4.6])
    assert returns[:, 0].tolist() == pytest.approx([2.35, 2.0, 6.6])


def test_gae_with_lambda_one_is_the_discounted_return_minus_the_value():
    gamma = 0.99
    rewards = torch.tensor([[0.1, 0.2], [0.3, -3.0], [0.5, 0.1]])
    values = torch.tensor([[0.2, 0.1], [0.4, 0.3], [0.6, 0.5]])
    dones = torch.tensor([[0.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    next_value = torch.tensor([1.0, 2.0])
    advantages, returns = compute_gae(rewards, values, dones, next_value, gamma, 1.0)
    car0 = 0.1 + gamma * 0.3 + gamma**2 * 0.5 + gamma**3 * 1.0
    car1_first_episode = 0.2 + gamma * -3.0
    assert returns[0, 0].item() == pytest.approx(car0)
    assert returns[0, 1].item() == pytest.approx(car1_first_episode)
    assert returns[2, 1].item() == pytest.approx(0.1 + gamma * 2.0)
    assert torch.allclose(advantages, returns - values)


def test_dsac_critic_targets_by_hand():
    rewards = torch.tensor([0.01, -3.0])
    dones = torch.tensor([0.0, 1.0])
    next_q, next_z = torch.tensor([2.0, 5.0]), torch.tensor([2.5, 7.0])
    next_log_pi = torch.tensor([-1.0, 0.5])
    target_q, target_z = critic_targets(rewards, dones, next_q, next_z, next_log_pi, alpha=0.2, gamma=0.99)
    # r + γ (Q' − α log π) = 0.01 + 0.99 (2.0 + 0.2) = 2.188; a terminal transition keeps r only
    assert target_q.tolist() == pytest.approx([2.188, -3.0])
    assert target_z.tolist() == pytest.approx([0.01 + 0.99 * 2.7, -3.0])


def test_dsac_critic_loss_value_and_gradients_by_hand():
    q = torch.tensor([1.0], requires_grad=True)
    std = torch.tensor([2.0], requires_grad=True)
    target_q, target_z = torch.tensor([3.0]), torch.tensor([40.0])  # z is 39 above Q: clipped to Q + 10
    loss = critic_loss(q, std, target_q, target_z, td_bound=10.0)
    # (3 − 1)² / (2·4) + (11 − 1)² / (2·4) + log 2 = 0.5 + 12.5 + 0.6931
    assert loss.item() == pytest.approx(0.5 + 12.5 + math.log(2))
    loss.backward()
    # ∂/∂Q = −(target_q − Q)/σ² = −0.5 (the σ term holds Q fixed)
    assert q.grad.item() == pytest.approx(-0.5)
    # ∂/∂σ = −((z_clip − Q)²/σ³ − 1/σ) = −(100/8 − 0.5) = −12 (the mean term holds σ fixed)
    assert std.grad.item() == pytest.approx(-12.0)


def test_polyak_update_by_hand():
    params = [torch.tensor([1.0, 2.0]), torch.tensor([[4.0]])]
    targets = [torch.tensor([0.0, 0.0]), torch.tensor([[2.0]])]
    polyak_update(params, targets, 0.25)  # θ' ← τθ + (1 − τ)θ'
    assert targets[0].tolist() == [0.25, 0.5]
    assert targets[1].tolist() == [[2.5]]


def test_learning_rates_decay_linearly_to_their_final_fraction():
    """SB3's get_linear_fn: lr(t) = lr0 (1 − (1 − f) t / T), for each optimizer from its own lr0."""
    weight = torch.zeros(1, requires_grad=True)
    optimizers = [adam([weight], lr=1e-3), adam([torch.zeros(1, requires_grad=True)], lr=3e-4)]
    for step, fraction in [(0, 1.0), (500, 0.55), (1000, 0.1), (2000, 0.1)]:
        anneal_learning_rates(optimizers, step, 1000, final_fraction=0.1)
        assert [o.param_groups[0]["lr"] for o in optimizers] == pytest.approx([1e-3 * fraction, 3e-4 * fraction])
    constant = [adam([weight], lr=1e-3)]
    for step in (1, 700, 1000):  # 1: the thesis' constant rate, exactly
        anneal_learning_rates(constant, step, 1000, final_fraction=1.0)
        assert constant[0].param_groups[0]["lr"] == 1e-3


def test_replay_buffer_wraps_around_and_round_trips():
    rb = ReplayBuffer(3, obs_dim=2, act_dim=2, seed=0)
    for k in range(5):
        rb.add(np.full((1, 2), k, np.float32), np.zeros((1, 2), np.float32), np.array([k], np.float32),
               np.full((1, 2), k + 1, np.float32), np.array([k % 2 == 1]))
    assert rb.size == 3 and sorted(rb.rewards.tolist()) == [2.0, 3.0, 4.0]
    copy = ReplayBuffer(3, obs_dim=2, act_dim=2, seed=99)
    copy.load_state_dict(rb.state_dict())
    a, b = rb.sample(16), copy.sample(16)
    assert all(torch.equal(x, y) for x, y in zip(a, b))
    assert torch.equal(a.next_observations[:, 0], a.observations[:, 0] + 1)
    assert torch.equal(a.dones, (a.rewards % 2 == 1).float())


def test_moving_average():
    assert moving_average(np.array([1.0, 3.0, 5.0, 7.0]), window=2).tolist() == [1.0, 2.0, 4.0, 6.0]
