#!/usr/bin/python3
"""A small PyTorch policy learns Reach-v0 with PPO on make_vector: the impedance controller runs
at 1 kHz in C++ underneath, the policy acts at 20 Hz through the same action a robot takes.

The policy is a Gaussian over the normalised action (a pose increment and the stiffness per axis),
its mean a two-layer MLP of the observation (normalised by running statistics), its standard
deviation learned per element; a separate MLP estimates the value. PPO (clipped surrogate, GAE)
on `--envs` environments stepped together in C++ threads. Before and after training the mean
action is evaluated on held-out seeds. Debian: python3-torch.

Usage (from the repository root, after building the module):

    PYTHONPATH=build/python /usr/bin/python3 examples/python/reach_ppo.py
        [--iterations 150] [--envs 8] [--steps 128] [--seed 0] [--plot reach_ppo.png]
        [--json results.json]

Measured (python/README.md): 150 iterations of 8 x 128 steps (154k environment steps, 94 s on the
two-core VM) take the held-out success from 5 % to 100 %.
"""

import argparse
import json
import time

import numpy as np
import torch
from torch import nn

import cartesian_impedance.envs as envs

ENV = "CartesianImpedance/Reach-v0"
OPTIONS = {"max_episode_steps": 50}


def features(obs, num_joints):
    """The observation and, as most reaching policies get it, the goal relative to the flange
    (goal: the last 3 values; flange position: after q and dq)."""
    obs = np.atleast_2d(obs)
    relative = obs[:, -3:] - obs[:, 2 * num_joints:2 * num_joints + 3]
    return np.concatenate([obs, relative], axis=1)


class RunningNorm:
    """The policy's input: features() normalised by their mean and variance so far (Welford over
    batches)."""

    def __init__(self, num_joints, obs_size):
        self.num_joints = num_joints
        self.size = obs_size + 3
        self.mean, self.var, self.count = np.zeros(self.size), np.ones(self.size), 1e-4

    def update(self, obs):
        batch = features(obs, self.num_joints)
        mean, var, count = batch.mean(axis=0), batch.var(axis=0), batch.shape[0]
        delta, total = mean - self.mean, self.count + count
        self.mean = self.mean + delta * count / total
        self.var = (self.var * self.count + var * count +
                    delta ** 2 * self.count * count / total) / total
        self.count = total

    def __call__(self, obs):
        normed = np.clip((features(obs, self.num_joints) - self.mean) / np.sqrt(self.var + 1e-8),
                         -10.0, 10.0)
        return normed if np.ndim(obs) == 2 else normed[0]


class Policy(nn.Module):
    def __init__(self, obs_size, action_size, hidden=64):
        super().__init__()
        self.mean = nn.Sequential(nn.Linear(obs_size, hidden), nn.Tanh(),
                                  nn.Linear(hidden, hidden), nn.Tanh(),
                                  nn.Linear(hidden, action_size))
        self.log_std = nn.Parameter(torch.full((action_size,), -1.0))
        self.value = nn.Sequential(nn.Linear(obs_size, hidden), nn.Tanh(),
                                   nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, 1))
        with torch.no_grad():  # a small first action: the arm starts still
            self.mean[-1].weight.mul_(0.01)
            self.mean[-1].bias.zero_()

    def distribution(self, obs):
        return torch.distributions.Normal(self.mean(obs), self.log_std.exp())


def evaluate(policy, norm, seeds):
    """Success rate, mean final distance [m] and the mean cosine between the first action's
    translation and the direction to the goal, of the mean action over episodes from `seeds`."""
    env = envs.make(ENV, **OPTIONS)
    n = env.model.num_joints
    successes, distances, cosines = [], [], []
    for seed in seeds:
        obs, info = env.reset(seed=int(seed))
        done = False
        while not done:
            with torch.no_grad():
                action = policy.mean(torch.as_tensor(norm(obs), dtype=torch.float32)).numpy()
            if env.steps == 0:  # the episode's first action
                toward = obs[-3:] - obs[2 * n:2 * n + 3]
                cosines.append(float(action[:3] @ toward /
                                     (np.linalg.norm(action[:3]) * np.linalg.norm(toward) + 1e-12)))
            obs, _, terminated, truncated, info = env.step(np.clip(action, -1, 1))
            done = terminated or truncated
        successes.append(float(info["is_success"]))
        distances.append(info["distance"])
    env.close()
    return float(np.mean(successes)), float(np.mean(distances)), float(np.mean(cosines))


def train(iterations, n_envs, steps, seed, held_out):
    torch.manual_seed(seed)
    torch.set_num_threads(1)  # the environments' C++ threads use the cores
    vector = envs.make_vector(ENV, n_envs, **OPTIONS)
    action_size = vector.single_action_space.shape[0]
    norm = RunningNorm(vector.envs[0].model.num_joints, vector.single_observation_space.shape[0])
    obs_size = norm.size
    policy = Policy(obs_size, action_size)
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-3)
    gamma, lam, clip, epochs, minibatch = 0.99, 0.95, 0.2, 10, 256

    before = evaluate(policy, norm, held_out)
    obs, _ = vector.reset(seed=seed)
    norm.update(obs)
    curve, episode_returns, running = [], [], np.zeros(n_envs)
    resetting = np.zeros(n_envs, dtype=bool)
    began = time.perf_counter()
    for iteration in range(iterations):
        o_buf = np.zeros((steps, n_envs, obs_size), dtype=np.float32)
        a_buf = np.zeros((steps, n_envs, action_size), dtype=np.float32)
        logp_buf, r_buf, v_buf = (np.zeros((steps, n_envs), dtype=np.float32) for _ in range(3))
        done_buf = np.zeros((steps, n_envs), dtype=np.float32)  # the episode ended at this step
        # Next-step autoreset: the step after an ending only resets (its action is ignored, its
        # reward 0); such steps are left out of the losses.
        reset_buf = np.zeros((steps, n_envs), dtype=bool)
        for t in range(steps):
            reset_buf[t] = resetting
            normed = torch.as_tensor(norm(obs), dtype=torch.float32)
            with torch.no_grad():
                distribution = policy.distribution(normed)
                action = distribution.sample()
                logp_buf[t] = distribution.log_prob(action).sum(-1).numpy()
                v_buf[t] = policy.value(normed).squeeze(-1).numpy()
            o_buf[t], a_buf[t] = normed.numpy(), action.numpy()
            obs, reward, terminated, truncated, _ = vector.step(np.clip(action.numpy(), -1, 1))
            r_buf[t] = reward
            done_buf[t] = terminated | truncated
            resetting = done_buf[t] > 0
            running += reward
            for i in np.flatnonzero(done_buf[t]):
                episode_returns.append(running[i])
                running[i] = 0.0
            norm.update(obs)
        # Generalised advantage estimation; an ending cuts the bootstrap (a truncation after 50
        # steps is treated as an end: the reward is per step and the horizon short).
        with torch.no_grad():
            last = policy.value(torch.as_tensor(norm(obs), dtype=torch.float32)).squeeze(-1)
        advantages = np.zeros((steps, n_envs), dtype=np.float32)
        gae = np.zeros(n_envs, dtype=np.float32)
        next_value = last.numpy()
        for t in reversed(range(steps)):
            alive = 1.0 - done_buf[t]
            delta = r_buf[t] + gamma * next_value * alive - v_buf[t]
            gae = np.where(reset_buf[t], 0.0, delta + gamma * lam * alive * gae)
            advantages[t] = gae
            next_value = v_buf[t]
        returns = advantages + v_buf
        flat = lambda x: torch.as_tensor(x.reshape(steps * n_envs, *x.shape[2:]))  # noqa: E731
        keep = torch.as_tensor(~reset_buf.reshape(-1))
        o, a, logp, adv, ret = (flat(x)[keep] for x in (o_buf, a_buf, logp_buf, advantages,
                                                         returns))
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        for _ in range(epochs):
            for batch in torch.randperm(len(adv)).split(minibatch):
                distribution = policy.distribution(o[batch])
                ratio = (distribution.log_prob(a[batch]).sum(-1) - logp[batch]).exp()
                surrogate = torch.min(ratio * adv[batch],
                                      ratio.clamp(1 - clip, 1 + clip) * adv[batch])
                value_loss = (policy.value(o[batch]).squeeze(-1) - ret[batch]).pow(2).mean()
                loss = -surrogate.mean() + 0.5 * value_loss - 0.001 * distribution.entropy().mean()
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
                optimizer.step()
        recent = float(np.mean(episode_returns[-20:])) if episode_returns else float("nan")
        curve.append({"iteration": iteration + 1, "env_steps": (iteration + 1) * steps * n_envs,
                      "mean_return_last_20": recent})
        print("iteration %3d: %6d env steps, mean return of the last 20 episodes %.3f" %
              (iteration + 1, (iteration + 1) * steps * n_envs, recent), flush=True)
    elapsed = time.perf_counter() - began
    vector.close()
    after = evaluate(policy, norm, held_out)
    return {"before": {"success": before[0], "final_distance": before[1],
                       "direction_cosine": before[2]},
            "after": {"success": after[0], "final_distance": after[1],
                      "direction_cosine": after[2]},
            "curve": curve, "train_seconds": elapsed, "held_out_seeds": len(held_out)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=150)
    parser.add_argument("--envs", type=int, default=8)
    parser.add_argument("--steps", type=int, default=128, help="steps per environment per "
                        "iteration")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--held-out", type=int, default=20, help="evaluation episodes")
    parser.add_argument("--plot", help="write the learning curve to this PNG")
    parser.add_argument("--json", help="write the figures to this file")
    args = parser.parse_args()
    held_out = 2**31 + np.arange(args.held_out)  # seeds training never uses
    result = train(args.iterations, args.envs, args.steps, args.seed, held_out)
    for name in ("before", "after"):
        print("%s training: success %.2f on %d held-out seeds, mean final distance %.3f m, "
              "first action toward the goal: cosine %.2f" %
              (name, result[name]["success"], args.held_out, result[name]["final_distance"],
               result[name]["direction_cosine"]))
    print("training: %.1f s" % result["train_seconds"])
    if args.json:
        with open(args.json, "w") as out:
            json.dump(result, out, indent=1)
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        steps = [c["env_steps"] for c in result["curve"]]
        figure, axes = plt.subplots(figsize=(6, 3.5))
        axes.plot(steps, [c["mean_return_last_20"] for c in result["curve"]], marker=".")
        axes.set_xlabel("environment steps (20 Hz policy, 1 kHz controller)")
        axes.set_ylabel("mean return, last 20 episodes")
        axes.set_title("PPO on Reach-v0: success %.0f%% -> %.0f%% on held-out seeds" %
                       (100 * result["before"]["success"], 100 * result["after"]["success"]))
        axes.grid(True, alpha=0.3)
        figure.tight_layout()
        figure.savefig(args.plot, dpi=100)
        print("wrote %s" % args.plot)


if __name__ == "__main__":
    main()
