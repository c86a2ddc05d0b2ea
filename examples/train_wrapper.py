"""Train a tabular Q-learning agent on a tiny driving task, rewarded by stdlib/driving.ra.

The environment is defined here (numpy and gymnasium only): a one-lane road. The ego cruises
at 5 m/s towards a goal area that starts at GOAL_X metres (the road goes on through it). An
obstacle (a car pulling out, a crossing pedestrian) blocks the lane at OBSTACLE_X until a
random moment between 4 and 9 s; the ego sees the gap to it while it is there. Each step
the ego accelerates, keeps its speed or brakes hard. One environment step is one sample of
the automaton (0.1 s), and an episode lasts the automaton's horizon (300 samples = 30 s)
unless the ego hits the obstacle.

The environment's own reward is the paper's hand-written weighted sum (Gu, FMAS 2024, Eq. 9).
:class:`rac.learning.gym.RewardAutomatonWrapper` replaces it with the automaton's reward: the increase
of ``10*sa + 5*pr + co`` at each sample, so an episode's return is the objective's final
value (at most 980: 30 s in `Normal` and the goal bonus).

Run::

    python examples/train_wrapper.py                    # 600 episodes, seed 0, a few seconds
    python examples/train_wrapper.py --episodes 100 --seed 3
    python examples/train_wrapper.py --plot curve.png   # needs matplotlib; skipped without it
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import gymnasium
import numpy as np

import rac
from rac.lang.resources import stdlib_file
from rac.learning.gym import RewardAutomatonWrapper

# ---------------------------------------------------------------- the environment
GOAL_X = 80.0  # m: where the goal area starts
OBSTACLE_X = 30.0  # m: where the obstacle blocks the lane
CLEAR_AFTER = (4.0, 9.0)  # s: the obstacle leaves at a uniformly random time in this range
UNSAFE_GAP = 5.0  # m: closer than this to the obstacle is unsafe (the automaton's `isClose`)
GOAL_RADIUS = 2.0  # m: the automaton pays its end bonus when `dgoal < 2` at the end
V_MAX = 5.0  # m/s: the speed limit, and the speed at the start
ACCELERATIONS = (1.5, 0.0, -3.0)  # m/s^2 for the actions accelerate, keep, brake
COMFORT_LIMIT = 2.0  # m/s^2: braking at -3 is uncomfortable (the automaton's `comf`)
NO_OBSTACLE_GAP = 100.0  # the gap observed when no obstacle is ahead


class Road1D(gymnasium.Env):
    """One lane, one obstacle that leaves at a random time, one goal.

    Observation: ``[position, speed, gap]`` (m, m/s, m); ``gap`` is ``NO_OBSTACLE_GAP`` once the
    obstacle has left. Actions: 0 accelerate, 1 keep, 2 brake. The episode terminates on a
    collision and is truncated after ``max_steps``. ``info`` carries what the reward automaton
    needs: ``obstacle``, ``collision``, ``progress`` (metres driven in the step), ``accel`` and
    ``dgoal`` (distance to the goal area, 0 inside it), plus ``time``.
    """

    metadata = {"render_modes": []}

    def __init__(self, dt: float = 0.1, max_steps: int = 300) -> None:
        self.dt, self.max_steps = dt, max_steps
        self.action_space = gymnasium.spaces.Discrete(len(ACCELERATIONS))
        self.observation_space = gymnasium.spaces.Box(
            low=np.array([0.0, 0.0, -10.0], dtype=np.float32),
            high=np.array([np.inf, V_MAX, NO_OBSTACLE_GAP], dtype=np.float32))

    def _obs(self) -> np.ndarray:
        gap = OBSTACLE_X - self.x if self.blocked else NO_OBSTACLE_GAP
        return np.array([self.x, self.v, gap], dtype=np.float32)

    def _info(self, progress: float, accel: float) -> dict[str, Any]:
        return {"obstacle": self.blocked, "collision": self.collided, "progress": progress,
                "accel": accel, "dgoal": max(0.0, GOAL_X - self.x), "time": self.steps * self.dt}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.x, self.v, self.steps = 0.0, V_MAX, 0
        self.clear_at = float(self.np_random.uniform(*CLEAR_AFTER))
        self.blocked, self.collided = True, False
        return self._obs(), self._info(0.0, 0.0)

    def step(self, action: int):
        accel = ACCELERATIONS[int(action)]
        v = min(V_MAX, max(0.0, self.v + accel * self.dt))
        dx = 0.5 * (self.v + v) * self.dt
        self.x, self.v = self.x + dx, v
        self.steps += 1
        self.blocked = self.blocked and self.steps * self.dt < self.clear_at
        self.collided = self.blocked and self.x >= OBSTACLE_X
        in_goal = GOAL_X - self.x < GOAL_RADIUS  # the automaton's `dgoal < 2`
        obs, info = self._obs(), self._info(dx, accel)
        # The environment's own reward: the paper's weighted sum (Eq. 9), paid every step.
        safe = not (self.blocked and obs[2] < UNSAFE_GAP)
        reward = 10.0 * safe + (5.0 + 100.0 * in_goal) * (dx > 0) + 1.0 * (abs(accel) <= COMFORT_LIMIT)
        terminated = self.collided
        truncated = not terminated and self.steps >= self.max_steps
        return obs, reward, terminated, truncated, info


def automaton_inputs(obs: np.ndarray, info: dict[str, Any]) -> dict[str, bool | float]:
    """The automaton's inputs, read from one observation and its info."""
    gap = float(obs[2])
    return {
        "isClose": bool(info["obstacle"] and gap < UNSAFE_GAP),
        "prog": info["progress"] > 0.0,  # moved along the route (towards or through the goal area)
        "comf": abs(info["accel"]) <= COMFORT_LIMIT,
        "collide": bool(info["collision"]),  # implies isClose, as `assume` demands
        "dgoal": min(float(info["dgoal"]), 500.0),
    }


# ---------------------------------------------------------------- the agent
SPEED_EDGES = np.array([0.25, 1.5, 2.5, 3.5, 4.5])  # 6 speed bins
GAP_EDGES = np.array([UNSAFE_GAP, 6.0, 7.5, 10.0, 15.0, 30.0])  # 7 gap bins (the last: far, or no obstacle)
DECISION_EVERY = 5  # the agent picks an action every 5 samples (0.5 s) and holds it


def discretise(obs: np.ndarray) -> tuple[int, int]:
    """The agent's state: speed and gap bins (42 states); keeping moving is what reaches the goal."""
    _, v, gap = (float(value) for value in obs)
    return int(np.searchsorted(SPEED_EDGES, v)), int(np.searchsorted(GAP_EDGES, gap))


class QAgent:
    """Tabular Q-learning over the discretised state, one update per decision (SMDP style)."""

    def __init__(self, n_actions: int, rng: np.random.Generator, alpha: float = 0.2, gamma: float = 0.99) -> None:
        shape = (len(SPEED_EDGES) + 1, len(GAP_EDGES) + 1)
        # Optimistic start, above any return the automaton pays (at most 980): untried actions get tried.
        self.q = np.full(shape + (n_actions,), 1000.0)
        self.rng, self.alpha, self.gamma, self.n_actions = rng, alpha, gamma, n_actions

    def act(self, state: tuple[int, ...], epsilon: float) -> int:
        if epsilon and self.rng.random() < epsilon:
            return int(self.rng.integers(self.n_actions))
        return int(np.argmax(self.q[state]))

    def learn(self, state: tuple[int, ...], action: int, gain: float, following: tuple[int, ...],
              done: bool) -> None:
        # No bootstrapping past the end of an episode (a collision, or the horizon, where the
        # automaton's `at end` bonus is paid).
        target = gain if done else gain + self.gamma * float(np.max(self.q[following]))
        self.q[state + (action,)] += self.alpha * (target - self.q[state + (action,)])


def run_episode(env: RewardAutomatonWrapper, agent: QAgent, epsilon: float, learn: bool) -> dict[str, float]:
    """One episode; returns its outcome. ``learn=False`` only evaluates."""
    obs, info = env.reset()
    state, done = discretise(obs), False
    episode_return, unsafe = 0.0, False
    while not done:
        action = agent.act(state, epsilon)
        gain = 0.0
        for _ in range(DECISION_EVERY):  # hold the action for DECISION_EVERY samples
            obs, reward, terminated, truncated, info = env.step(action)
            gain += float(reward)
            unsafe |= info["rac"]["location"] == "Unsafe"
            done = terminated or truncated
            if done:
                break
        following = discretise(obs)
        if learn:
            agent.learn(state, action, gain, following, done)
        state = following
        episode_return += gain
    # The wrapper hands out the objective's increase, so the return is the objective's final value.
    assert abs(episode_return - info["rac"]["objective"]) <= 1e-6 * max(1.0, abs(episode_return))
    return {"return": episode_return, "unsafe": float(unsafe), "collision": float(info["collision"]),
            "goal": float(info["dgoal"] < GOAL_RADIUS), "time": float(info["time"])}


def summarise(label: str, window: list[dict[str, float]]) -> str:
    def total(key: str) -> int:
        return int(sum(h[key] for h in window))

    return (f"{label}  mean return {np.mean([h['return'] for h in window]):7.1f}  "
            f"unsafe {total('unsafe'):3d}  collisions {total('collision'):3d}  "
            f"goal reached {total('goal'):3d}/{len(window)}  "
            f"mean duration {np.mean([h['time'] for h in window]):4.1f} s")


def train(episodes: int, seed: int, report_every: int, evaluate: int) -> list[dict[str, float]]:
    automaton = rac.load(stdlib_file("driving.ra"))  # checked on load: P1, P2, determinism
    # One environment step is one sample of the automaton: same period, same horizon.
    env = RewardAutomatonWrapper(Road1D(dt=automaton.period, max_steps=automaton.steps), automaton,
                                 inputs=automaton_inputs)
    env.reset(seed=seed)  # seeds the environment's generator; later resets continue from it
    agent = QAgent(int(env.action_space.n), np.random.default_rng(seed))
    history: list[dict[str, float]] = []
    for episode in range(episodes):
        epsilon = max(0.02, 0.5 * (1.0 - episode / (0.7 * episodes)))
        history.append(run_episode(env, agent, epsilon, learn=True))
        if (episode + 1) % report_every == 0 or episode + 1 == episodes:
            first = (episode // report_every) * report_every + 1
            print(summarise(f"episodes {first:4d}-{episode + 1:<4d}", history[first - 1:]))
    if evaluate:
        greedy = [run_episode(env, agent, 0.0, learn=False) for _ in range(evaluate)]
        print(summarise(f"summary: greedy policy, {evaluate} new episodes:", greedy))
    return history


def plot(history: list[dict[str, float]], path: str, window: int) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: skipping the plot ({path})")
        return
    returns = np.array([h["return"] for h in history])
    kernel = np.ones(min(window, len(returns))) / min(window, len(returns))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(returns, alpha=0.3, label="episode return (final objective)")
    ax.plot(np.arange(len(kernel) - 1, len(returns)), np.convolve(returns, kernel, mode="valid"),
            label=f"mean over {len(kernel)} episodes")
    ax.set_xlabel("episode")
    ax.set_ylabel("10*sa + 5*pr + co")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path)
    print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=600, help="training episodes (default 600)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the environment and the agent (default 0)")
    parser.add_argument("--report-every", type=int, default=50, help="episodes per progress line (default 50)")
    parser.add_argument("--evaluate", type=int, default=100,
                        help="greedy episodes run after training for the summary (default 100; 0: none)")
    parser.add_argument("--plot", metavar="PNG", help="save a learning curve (needs matplotlib)")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.report_every < 1 or args.evaluate < 0:
        parser.error("--episodes and --report-every must be positive, --evaluate not negative")
    started = time.perf_counter()
    print(f"Q-learning on Road1D, rewarded by stdlib/driving.ra: {args.episodes} episodes, seed {args.seed}")
    history = train(args.episodes, args.seed, args.report_every, args.evaluate)
    if args.plot:
        plot(history, args.plot, args.report_every)
    print(f"done in {time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
