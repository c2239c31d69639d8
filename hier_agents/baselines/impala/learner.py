"""The learner: batches actors' unrolls, V-trace loss, optimiser, checkpoints, logs.

`train(config)` is the whole loop:

1. start the actors (`LocalActors` processes or `RayActors`) with the
   learner's current weights;
2. take unrolls as they arrive until a batch is gathered (``batch_size``
   unrolls; the last update only the unrolls the budget has left), stack
   them ``[T + 1, B, ...]`` and replay them through the network from the
   actors' recorded core states;
3. ``passes`` optimiser steps (`make_optimizer`: RMSProp, the paper's, or
   Adam) on `impala_loss` (V-trace; two value heads and the sum of both
   advantage terms for the planner conditions), gradient norm clipped;
4. publish the new weights; log scalars (`hier_agents.learning.rundir`: the
   run directory's ``scalars.jsonl`` and TensorBoard); save ``checkpoint.pt``
   every ``checkpoint_every_s`` seconds, at the end and on Ctrl-C (with
   ``keep_checkpoints``, also a copy ``checkpoints/frames-N.pt`` each time,
   for learning curves: `benchmarks/learning_curve.py`); with ``save_at``,
   a kept copy ``checkpoints/frames-B.pt`` exactly at each budget B (updates
   are cut so the frame count meets it: evaluation at equal budgets,
   `hier_agents.compare`). Kept copies hold what evaluation reads (weights,
   input spec, config, counters; weights as float16), not the optimiser
   state or the random states (`checkpoints.kept_copy`): a run resumes from
   ``checkpoint.pt`` only.

Frames are environment control steps consumed by the learner: an unroll of
``unroll_length`` agent steps counts ``frames_per_unroll`` (times
``action_repeat``). The budget ``steps`` is met exactly when it is a
multiple of ``frames_per_unroll`` (else overshot by less than one unroll):
every update takes ``batch_size`` unrolls, except that the last one takes only the unrolls
the budget still needs (so a budget below one batch trains one smaller
batch); a budget below one unroll is refused.

A run whose logdir holds a checkpoint of the same environment, condition and
observations resumes from it: weights, optimiser, frame and update counts,
episode statistics, random states, and the counters ``wall_s`` (seconds the
run's processes were alive, a paused machine included) and ``cpu_s`` (CPU
seconds of the learner and its actors, over every resumed part: the cost a
comparison reports). ``config.json`` records the
configuration, the trainer and, once the first environment is built, what
the agent observes: ``observations`` (the input keys, `InputSpec.keys`) and
``privileged`` (`InputSpec.privileged`).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections import deque

import numpy as np

from physics_planning.cli import plural
from hier_agents.baselines.impala.actors import LocalActors, RayActors, stack_states
from hier_agents.baselines.impala.config import TrainConfig  # noqa: F401
from hier_agents.baselines.impala.checkpoints import TRAINER, kept_copy
from hier_agents.learning.rundir import RunDir

# -- batching ---------------------------------------------------------------------------------


def make_batch(unrolls: list[dict], net, value_states: dict | None = None):
    """Stacks unrolls into time-major tensors for one learner step.

    ``value_states`` maps a stream to the value core's (h, c) after its last
    unroll; those rows replace the actors' (zero) value-core rows. A stream's
    first unroll starts at an episode start, where zeros are exact.
    """
    import torch

    obs = {
        k: torch.from_numpy(np.stack([u["obs"][k] for u in unrolls], axis=1))
        for k in unrolls[0]["obs"]
    }
    batch = {"obs": obs, "first": torch.from_numpy(np.stack([u["first"] for u in unrolls], axis=1))}
    for key in (
        "actions",
        "log_probs",
        "rewards_env",
        "discounts_env",
        "rewards_abs",
        "discounts_abs",
    ):
        batch[key] = torch.from_numpy(np.stack([u[key] for u in unrolls], axis=1))
    state = list(stack_states([u["state"] for u in unrolls], net.initial_state(1)))
    streams = [tuple(u.get("stream", ())) for u in unrolls]
    # A stream may have several (consecutive, in arrival order) unrolls in one
    # batch: the later ones start from the earlier one's value state.
    chain: list[int] = []
    last_column: dict[tuple, int] = {}  # stream -> its latest unroll's column
    for j, stream in enumerate(streams):
        chain.append(last_column.get(stream, -1) if stream else -1)
        if stream:
            last_column[stream] = j
        carried = (value_states or {}).get(stream) if chain[j] < 0 else None
        if carried is not None:
            state[0][j], state[1][j] = carried
    batch["state"] = tuple(state)
    batch["streams"] = streams
    batch["value_chain"] = chain
    return batch


def learner_step(
    net, optimizer, batch, config: TrainConfig, value_states: dict | None = None
) -> dict:
    """One gradient step on ``batch``; returns float statistics.

    When ``value_states`` is given, the value core's state after each
    unroll's last step is stored there for the stream's next unroll.
    """
    import torch

    from hier_agents.baselines.impala.vtrace import impala_loss

    T = batch["actions"].shape[0]
    out, new_state = net(
        batch["obs"],
        batch["first"],
        batch["state"],
        value_state_after=T - 1,
        value_chain=batch.get("value_chain"),
    )
    if value_states is not None:
        hv, cv = new_state[0].detach(), new_state[1].detach()
        for j, stream in enumerate(batch["streams"]):  # the stream's last column wins
            if stream:
                value_states[stream] = (hv[j].clone(), cv[j].clone())
    steps = type(out)(*(None if x is None else x[:-1] for x in out))
    bootstrap = type(out)(*(None if x is None else x[-1] for x in out))
    loss, stats = impala_loss(
        steps,
        bootstrap,
        batch["actions"],
        batch["log_probs"],
        batch["rewards_env"],
        batch["discounts_env"],
        batch["rewards_abs"],
        batch["discounts_abs"],
        baseline_cost=config.baseline_cost,
        entropy_cost=config.entropy_cost,
        normalize_advantages=config.normalize_advantages,
        clip_ratio=config.clip_ratio,
    )
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(net.parameters(), config.grad_clip)
    optimizer.step()
    stats = dict(stats)
    stats["loss"] = float(loss.detach())
    stats["grad_norm"] = float(grad_norm)
    return stats


# -- the loop ---------------------------------------------------------------------------------

#: Configuration keys a resumed run must share with its run directory (the
#: first identifies a run of this trainer made before runs recorded it).
FIXED = (
    "condition",
    "env",
    "cameras",
    "image_size",
    "state",
    "state_channels",
    "action_repeat",
    "env_overrides",
    "optimizer",
)


def make_optimizer(net, config: TrainConfig):
    """``config.optimizer`` over ``net``'s parameters: RMSProp (``rmsprop_alpha``,
    ``rmsprop_eps``, ``rmsprop_momentum``) or Adam (``adam_eps``), both at
    ``learning_rate``."""
    import torch

    if config.optimizer == "adam":
        return torch.optim.Adam(net.parameters(), lr=config.learning_rate, eps=config.adam_eps)
    return torch.optim.RMSprop(
        net.parameters(),
        lr=config.learning_rate,
        alpha=config.rmsprop_alpha,
        eps=config.rmsprop_eps,
        momentum=config.rmsprop_momentum,
    )


def _build(config: TrainConfig, run: RunDir):
    """(net, optimiser, input spec, counters, recent episodes), resumed from
    ``run``'s checkpoint when there is one."""

    from hier_agents.baselines.impala.agent_env import AgentEnv
    from hier_agents.baselines.impala.network import net_for

    # The input spec comes from one environment built here (closed at once).
    probe = AgentEnv(
        config.env,
        config.condition,
        seed=config.seed,
        cameras=config.cameras,
        image_size=config.image_size,
        state=config.state,
        t_abs=config.t_abs,
        abs_reward=config.abs_reward,
        **config.env_overrides,
    )
    spec = probe.input_spec
    probe.close()
    run.record(observations=list(spec.keys), privileged=spec.privileged)
    net = net_for(spec, config)
    optimizer = make_optimizer(net, config)
    counters = {"frames": 0, "updates": 0, "episodes": 0, "wall_s": 0.0, "cpu_s": 0.0}
    recent: deque = deque(maxlen=100)
    ckpt = run.load()
    if ckpt is not None:
        net.load_state_dict(ckpt["model"])
        optimizer.load_state_dict(ckpt["optimizer"])
        counters.update(ckpt["counters"])
        recent.extend(ckpt["counters"].get("recent_episodes", []))
        print(
            f"resuming {run.checkpoint_path} at {plural(counters['frames'], 'frame')}, "
            f"{plural(counters['updates'], 'update')}",
            file=sys.stderr,
        )
    counters.pop("recent_episodes", None)
    return net, optimizer, spec, counters, recent


def _gather(
    actors,
    pending: list,
    batch_size: int,
    counters: dict,
    recent: deque,
    run: RunDir,
    actor_cpu: dict,
) -> None:
    """Takes unrolls (and their finished episodes) until ``batch_size`` are
    pending or a stop; ``actor_cpu`` keeps each actor's CPU seconds (`_note_cpu`)."""
    while len(pending) < batch_size and not run.stop_requested:
        unrolls = actors.get(should_stop=lambda: run.stop_requested)
        for u in unrolls or ():
            _note_cpu(actor_cpu, u["stream"][0], float(u.pop("cpu_s", 0.0)))
            for ep in u.pop("episodes"):
                counters["episodes"] += 1
                recent.append(
                    {
                        "return": float(ep.get("episode_return", 0.0)),
                        "success": float(bool(ep.get("success", False))),
                        "steps": int(ep.get("episode_steps", 0)),
                        "subgoals": int(ep.get("subgoals_reached", 0)),
                    }
                )
            pending.append(u)


def _note_cpu(actor_cpu: dict, actor: int, seconds: float) -> None:
    """Notes an actor's process CPU seconds so far; ``actor_cpu[actor]`` is
    (seconds of its earlier, dead processes, seconds of the current one): a
    replaced actor's process counts from 0 again."""
    before, last = actor_cpu.get(actor, (0.0, 0.0))
    actor_cpu[actor] = (before + last if seconds < last else before, seconds)


def _scalars(stats: dict, counters: dict, recent: deque, fps: float, lags: list) -> dict:
    scalars = {"frames": counters["frames"], **{f"loss/{k}": float(v) for k, v in stats.items()}}
    scalars.update(
        {
            "perf/frames_per_s": fps,
            "perf/updates": counters["updates"],
            "perf/policy_lag": float(np.mean(lags)) if lags else 0.0,
            "episodes/count": counters["episodes"],
            "wall_s": counters["wall_s"],
            "cpu_s": counters["cpu_s"],
        }
    )
    if recent:
        for key, name in (
            ("success", "success_rate"),
            ("return", "return"),
            ("steps", "steps"),
            ("subgoals", "subgoals_reached"),
        ):
            scalars[f"episodes/{name}"] = float(np.mean([e.get(key, 0) for e in recent]))
    return scalars


def train(config: TrainConfig) -> dict:
    """Runs (or resumes) a training run; returns its final counters.

    Raises:
      UsageError: `TrainConfig.validate`'s, or the logdir is a file or holds
        a run this one cannot continue (`RunDir`), before anything is built.
    """
    import torch

    import envs

    config.validate()
    config.env_overrides = envs.explicit_options(config.env, config.env_overrides)
    batch_size = config.resolved_batch()
    run = RunDir(
        config.logdir,
        dataclasses.asdict(config),
        resume=None,
        fixed=FIXED,
        env_key="env_overrides",
        trainer=TRAINER,
    )

    torch.manual_seed(config.seed)
    torch.set_num_threads(1)
    try:
        net, optimizer, spec, counters, recent = _build(config, run)
        if counters["frames"] >= config.steps:
            print(
                f"{run.checkpoint_path} already has {plural(counters['frames'], 'frame')}, "
                f"the budget is {plural(config.steps, 'frame')}: nothing to train",
                file=sys.stderr,
            )
            return counters
        return _loop(config, run, net, optimizer, spec, counters, recent, batch_size)
    finally:
        run.close()


def _start_actors(config: TrainConfig, net, counters: dict):
    """The actors of ``config.backend``, acting with ``net``'s weights; their
    config is `TrainConfig.actor_config` (a seed of their own per resumption)."""
    actor_config = config.actor_config(counters["updates"])
    if config.backend == "ray":
        return RayActors(actor_config, config.actors, net, address=config.ray_address)
    actors = LocalActors(actor_config, config.actors, net)
    actors.publish(net)
    return actors


class _Training:
    """One `_loop`'s state: the pending unrolls, the value cores' states, the
    clocks (``wall_s``, ``cpu_s``: earlier processes' from the checkpoint,
    this one's, and each actor's, reported with its unrolls), when it last
    logged and saved."""

    def __init__(self, config: TrainConfig, run: RunDir, net, optimizer, spec, counters, recent):
        self.config, self.run, self.net, self.optimizer = config, run, net, optimizer
        self.spec, self.counters, self.recent = spec, counters, recent
        self.save_at = sorted({int(b) for b in config.save_at})
        self.start = self.last_ckpt = self.last_log = time.perf_counter()
        self.wall0, self.frames_at_log = counters["wall_s"], counters["frames"]
        self.cpu0, self.process0 = counters.get("cpu_s", 0.0), time.process_time()
        self.actor_cpu: dict[int, tuple[float, float]] = {}  # actor -> CPU seconds (`_note_cpu`)
        self.pending: list[dict] = []
        self.value_states: dict = {}  # stream -> value-core (h, c) after its last unroll
        self.stats: dict = {}
        self.lags: list[int] = []
        self.published = 1  # weights versions published to the actors in this process

    def take(self, batch_size: int) -> int:
        """Unrolls the next update takes: a batch, or only those the budget,
        or the next ``save_at`` point, still needs."""
        frames = self.counters["frames"]
        target = min([b for b in self.save_at if b > frames] + [self.config.steps])
        return min(batch_size, math.ceil((target - frames) / self.config.frames_per_unroll))

    def update(self, take: int) -> int:
        """One learner step on the first ``take`` pending unrolls; returns the frames."""
        batch_unrolls, self.pending = self.pending[:take], self.pending[take:]
        # Updates between the weights an unroll was acted with and now.
        self.lags.extend(self.published - int(u.get("policy_version", 0)) for u in batch_unrolls)
        batch = make_batch(batch_unrolls, self.net, self.value_states)
        for k in range(self.config.passes):  # the value states of the last pass carry on
            last = k == self.config.passes - 1
            states = self.value_states if last else None
            self.stats = learner_step(self.net, self.optimizer, batch, self.config, states)
        self.published += 1
        self.counters["updates"] += 1
        new_frames = self.config.frames_per_unroll * len(batch_unrolls)
        self.counters["frames"] += new_frames
        self.clock()
        return new_frames

    def clock(self) -> None:
        """Brings ``wall_s`` and ``cpu_s`` up to now."""
        counters = self.counters
        counters["wall_s"] = self.wall0 + (time.perf_counter() - self.start)
        counters["cpu_s"] = (
            self.cpu0
            + (time.process_time() - self.process0)
            + sum(a + b for a, b in self.actor_cpu.values())
        )

    def log_and_save(self) -> None:
        """A scalars row every ``log_every_s`` and at the end; a kept
        checkpoint at a ``save_at`` point, else one every ``checkpoint_every_s``."""
        now, counters, config = time.perf_counter(), self.counters, self.config
        if now - self.last_log >= config.log_every_s or counters["frames"] >= config.steps:
            fps = (counters["frames"] - self.frames_at_log) / max(now - self.last_log, 1e-9)
            self.run.log(
                counters["frames"], _scalars(self.stats, counters, self.recent, fps, self.lags)
            )
            self.last_log, self.frames_at_log, self.lags = now, counters["frames"], []
        if counters["frames"] in self.save_at and counters["frames"] < config.steps:
            self.save(keep=True)
            self.last_ckpt = now
        elif now - self.last_ckpt >= config.checkpoint_every_s:
            self.save(keep=config.keep_checkpoints)
            self.last_ckpt = now

    def save(self, keep: bool) -> None:
        """Saves the checkpoint (``keep``: also as ``frames-N.pt``)."""
        counters = self.counters
        self.run.save(
            {
                "format": 1,
                "model": self.net.state_dict(),
                "optimizer": self.optimizer.state_dict(),
                "counters": dict(counters, recent_episodes=list(self.recent)),
                "input_spec": dataclasses.asdict(self.spec),
            },
            keep=f"frames-{int(counters['frames'])}" if keep else None,
            lean=kept_copy,
        )


def _loop(config, run: RunDir, net, optimizer, spec, counters, recent, batch_size) -> dict:
    """Actors, learner steps, logs and checkpoints until the frame budget or a
    stop; the checkpoint is saved however the loop ends."""
    actors = _start_actors(config, net, counters)
    state = _Training(config, run, net, optimizer, spec, counters, recent)
    bar = run.progress(
        config.steps,
        counters["frames"],
        desc=f"{config.env} {config.condition}",
        unit="frame",
        disable=not config.progress,
    )
    with run.interruptible():
        try:
            while counters["frames"] < config.steps and not run.stop_requested:
                take = state.take(batch_size)
                _gather(actors, state.pending, take, counters, recent, run, state.actor_cpu)
                if run.stop_requested:  # the partial batch is dropped
                    break
                bar.update(state.update(take))
                actors.publish(net)
                if recent:
                    bar.set_postfix(
                        success=f"{np.mean([e['success'] for e in recent]):.2f}",
                        ret=f"{np.mean([e['return'] for e in recent]):.2f}",
                        refresh=False,
                    )
                state.log_and_save()
        finally:
            bar.close()
            actors.close()
            state.clock()
            state.save(keep=config.keep_checkpoints or counters["frames"] in state.save_at)
    if run.stop_requested:
        print(
            f"interrupted: checkpoint saved at {plural(counters['frames'], 'frame')}; run "
            f"the same command to resume",
            file=sys.stderr,
        )
    if recent:
        counters["success_rate_last_100"] = float(np.mean([e["success"] for e in recent]))
        counters["return_last_100"] = float(np.mean([e["return"] for e in recent]))
    counters["last_stats"] = state.stats
    return counters
