"""Players of a trained checkpoint, or of random actions, with the same rows as the modular agent.

`CheckpointPlayer` plays the checkpoint's policy (the Gaussian's mean by
default, or samples with ``stochastic=True``) in the environment it was
trained on, built the same way (same condition, cameras, abstract inputs;
``env_options`` may change other settings, such as MuJoBan's ``levels``).
Its ``play(episode)`` returns the episode's row, which `hier_agents.run`
(``--agent checkpoint:PATH``) turns into its table and JSON: ``return``,
``steps``, ``wall_s``, ``solved`` (MuJoBan) or ``outcome`` (board games),
and the auxiliary subgoal counts for planner conditions; its ``info`` says
what the agent observed (``observations``, ``privileged``).

`RandomPlayer` gives the same rows for uniformly random actions (each action
component drawn independently from its bounds, a new draw every ``hold``
control steps; ``--agent random:HOLD``): the floor every trained agent must
clear. In MuJoBan, holding a draw for a while rolls the ball further and
solves more levels than drawing at every step; compare against the better of
the two.
"""

from __future__ import annotations

import time

import numpy as np

from physics_planning.cli import UsageError, plural


def parse_agent(spec: str) -> str:
    """The checkpoint path of an ``--agent checkpoint:PATH`` value
    (`UsageError` for anything else)."""
    if not spec.startswith("checkpoint:") or not spec[len("checkpoint:"):]:
        raise UsageError(f"--agent must be 'modular' or 'checkpoint:PATH', got {spec!r}")
    return spec[len("checkpoint:"):]


def _outcome_row(row: dict, task, fam: str) -> dict:
    if fam == "mujoban":
        row["solved"] = bool(task.solved)
    else:
        # The task's outcome counts an opponent's resignation as a win; a
        # game still running counts as lost.
        row["outcome"] = task.outcome or "loss"
    return row


def parse_random(spec: str) -> int:
    """The hold (control steps per draw) of an ``--agent random[:HOLD]`` value
    (`UsageError` for anything else)."""
    name, _, hold = spec.partition(":")
    try:
        value = int(hold) if hold else 1
    except ValueError:
        value = 0
    if name != "random" or value < 1:
        raise UsageError(f"a random agent is 'random' or 'random:HOLD' with HOLD >= 1 control "
                         f"steps per draw, got {spec!r}")
    return value


class RandomPlayer:
    """Uniformly random actions in ``env_name`` (cameras off), a new draw every
    ``hold`` control steps. ``play(episode)`` plays episode ``episode`` of
    seed ``seed`` (`envs.episode_seed`: environment and action draws), so
    episodes give the same rows in any order or process; ``info`` describes
    the agent; ``close()`` frees the environment."""

    def __init__(self, env_name: str, seed: int = 0, hold: int = 1):
        import envs
        from hier_agents.modular.components import family

        self.fam, self.seed, self.hold = family(env_name), int(seed), int(hold)
        self.env = envs.load(env_name, seed=seed, **envs.no_cameras(env_name))
        spec = self.env.action_spec()
        self._low = np.broadcast_to(spec.minimum, spec.shape)
        self._high = np.broadcast_to(spec.maximum, spec.shape)
        self.info = {"condition": f"uniform random actions, held {plural(hold, 'step')}",
                     "trained_env": "-", "training_frames": 0, "training_updates": 0}

    def play(self, episode: int, frames=None) -> dict:
        from envs.core import episode_seed

        start = time.perf_counter()
        env = self.env
        env.seed(self.seed, episode=episode)
        rng = np.random.default_rng([episode_seed(self.seed, episode), _ACTIONS])
        timestep = env.reset()
        ret, steps = 0.0, 0
        while not timestep.last():
            if steps % self.hold == 0:
                action = rng.uniform(self._low, self._high)
            timestep = env.step(action)
            ret += float(timestep.reward)
            steps += 1
        return _outcome_row({"episode": episode, "return": ret, "steps": steps,
                             "subgoals_issued": 0, "subgoals_reached": 0,
                             "wall_s": time.perf_counter() - start}, env.task, self.fam)

    def close(self) -> None:
        self.env.close()


#: Mixed into the seed of a random agent's action draws (distinct from the environment's).
_ACTIONS = 0x61637473


class CheckpointPlayer:
    """A trained checkpoint's policy (its mean, or samples with ``stochastic``)
    in ``env_name``, built as it was trained.

    ``path`` is the checkpoint file or its run directory; ``env_options`` are
    `envs.load` overrides applied on top of the run's own (e.g.
    ``{"levels": PATH}`` for MuJoBan), which must leave the inputs the
    network expects unchanged. ``play(episode, frames=None)`` plays episode
    ``episode`` of seed ``seed`` (environment, planner and samples seeded
    from `envs.episode_seed`), appending the main camera's 256x256 frames to
    ``frames`` if given, and returns its row; ``info`` has ``condition``,
    ``trained_env``, ``training_frames``, ``training_updates``,
    ``observations`` (the input keys the agent observed) and ``privileged``
    (whether any came from the simulator's abstract state); ``close()``.

    Raises:
      FileNotFoundError: no checkpoint at ``path``.
      UsageError: not a checkpoint of ``python -m hier_agents.train``;
        another family's; an unknown or bad option; options that change the
        network's inputs.
    """

    def __init__(self, env_name: str, path: str, seed: int = 0, *, stochastic: bool = False,
                 env_options: dict | None = None):
        import torch

        import envs
        from hier_agents.modular.components import family
        from hier_agents.baselines.impala.agent_env import AgentEnv
        from hier_agents.baselines.impala.learner import (load_checkpoint, net_from_checkpoint,
                                                          observed)

        ckpt = load_checkpoint(path)
        config = ckpt["config"]
        self.fam, self.seed, self.stochastic = family(env_name), int(seed), bool(stochastic)
        if family(config["env"]) != self.fam:
            raise UsageError(f"checkpoint {path} was trained on {config['env']!r}, a "
                             f"{family(config['env'])} environment; cannot play {env_name!r}")
        overrides = {**config.get("env_overrides", {}), **(env_options or {})}
        try:
            envs.check(env_name, seed=seed, **overrides)
        except (TypeError, ValueError) as exc:
            raise UsageError(f"{env_name}: {exc}") from None
        self.net, spec = net_from_checkpoint(ckpt)
        torch.set_num_threads(1)
        self.env = AgentEnv(env_name, config["condition"], seed=seed, cameras=config["cameras"],
                            image_size=config["image_size"], state=config.get("state", False),
                            t_abs=config["t_abs"], abs_reward=config["abs_reward"], **overrides)
        if self.env.input_spec != spec:
            self.env.close()
            raise UsageError(f"{env_name!r} gives inputs {self.env.input_spec}, the checkpoint "
                             f"expects {spec}")
        observations, privileged = observed(config, spec)
        self.info = {"condition": config["condition"] + (" (sampled)" if stochastic else ""),
                     "trained_env": config["env"],
                     "training_frames": int(ckpt["counters"].get("frames", 0)),
                     "training_updates": int(ckpt["counters"].get("updates", 0)),
                     "observations": observations, "privileged": privileged}

    def play(self, episode: int, frames=None) -> dict:
        import torch

        from envs.core import episode_seed

        start = time.perf_counter()
        env, net = self.env, self.net
        generator = torch.Generator().manual_seed(episode_seed(self.seed, episode))
        obs = env.reset(episode=episode)
        state = net.initial_state(1)
        first = np.ones(1, dtype=bool)
        ret, steps, info = 0.0, 0, {}
        while True:
            if frames is not None:
                frames.append(env.env.render(env.env.task.main_camera, 256, 256))
            batch = {k: v[None] for k, v in obs.items()}
            action, _, state = net.act(batch, first, state,
                                       deterministic=not self.stochastic, generator=generator)
            result = env.step(action[0])
            ret += float(result.reward_env)
            steps += 1
            first[0] = False
            obs = result.obs
            if result.last:
                info = result.info
                break
        row = {"episode": episode, "return": ret, "steps": steps,
               "subgoals_issued": int(info.get("subgoals_issued", 0)),
               "subgoals_reached": int(info.get("subgoals_reached", 0)),
               "wall_s": time.perf_counter() - start}
        return _outcome_row(row, env.env.task, self.fam)

    def close(self) -> None:
        self.env.close()
