"""The learner: batches actors' unrolls, V-trace loss, RMSProp, checkpoints, logs.

`train(config)` is the whole loop:

1. start the actors (`LocalActors` processes or `RayActors`) with the
   learner's current weights;
2. take unrolls as they arrive until a batch is gathered (``batch_size``
   unrolls; the last update only the unrolls the budget has left), stack
   them ``[T + 1, B, ...]`` and replay them through the network from the
   actors' recorded core states;
3. one RMSProp step on `impala_loss` (V-trace; two value heads and the sum of
   both advantage terms for the planner conditions), gradient norm clipped;
4. publish the new weights; log scalars (`hier_agents.learning.rundir`: the
   run directory's ``scalars.jsonl`` and TensorBoard); save ``checkpoint.pt``
   every ``checkpoint_every_s`` seconds, at the end and on Ctrl-C (with
   ``keep_checkpoints``, also a copy ``checkpoints/frames-N.pt`` each time,
   for learning curves: `benchmarks/learning_curve.py`); with ``save_at``,
   a kept copy ``checkpoints/frames-B.pt`` exactly at each budget B (updates
   are cut so the frame count meets it: evaluation at equal budgets,
   `hier_agents.compare`).

Frames are environment control steps consumed by the learner. The budget
``steps`` is met exactly when it is a multiple of ``unroll_length`` (else
overshot by less than one unroll): every update takes ``batch_size`` unrolls
of ``unroll_length`` steps, except that the last one takes only the unrolls
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
from pathlib import Path

import numpy as np

from physics_planning.cli import UsageError, choice, plural
from hier_agents.baselines.impala.actors import ActorConfig, LocalActors, RayActors, stack_states
from hier_agents.learning.rundir import CHECKPOINT, KEPT, SCALARS, RunDir
from hier_agents.modular.options import T_ABS

#: Paper's batch sizes (unrolls per update): board games 64, MuJoBan 128.
PAPER_BATCH = {"mujoban": 128, "mujoxo": 64, "mujogo": 64}
KEPT_CHECKPOINTS = KEPT  # folder of `keep_checkpoints` copies, frames-N.pt
#: The trainer recorded in its run directories (`RunDir`'s ``trainer``).
TRAINER = "python -m hier_agents.train"


@dataclasses.dataclass
class TrainConfig:
    """Everything a training run depends on (saved in ``config.json`` and its checkpoint).

    Observations: proprioception always; ``cameras`` the paper's camera views
    (``image_size`` squared; ``env_overrides`` may turn views off, e.g.
    `main_camera_only`); ``state`` the current abstract state (privileged);
    the planner conditions add the planner's planes (see `AgentEnv`).
    ``steps`` is the frame budget (module docstring).
    """

    env: str
    condition: str = "vanilla"
    steps: int = 1_000_000
    actors: int = 2
    envs_per_actor: int = 32  # 2 x 32 beat 2 x 16 and 1 x 32 in benchmarks/learner_speed.py
    backend: str = "local"
    ray_address: str | None = None
    logdir: str = "runs/impala"
    unroll_length: int = 100
    batch_size: int | None = None  # None: the paper's (64 board games, 128 MuJoBan)
    learning_rate: float = 3e-4
    rmsprop_alpha: float = 0.99
    rmsprop_eps: float = 1e-5
    rmsprop_momentum: float = 0.0
    grad_clip: float = 40.0
    baseline_cost: float = 0.5
    entropy_cost: float = 1e-3
    cameras: bool = True
    image_size: int = 96
    state: bool = False  # observe the current abstract state (AgentEnv(state=True))
    t_abs: int = T_ABS
    abs_reward: float = 1.0
    seed: int = 0
    checkpoint_every_s: float = 300.0
    keep_checkpoints: bool = False
    save_at: tuple = ()  # frame counts at which a kept checkpoint frames-N.pt is saved
    log_every_s: float = 10.0
    progress: bool = True
    env_overrides: dict = dataclasses.field(default_factory=dict)

    def validate(self) -> None:
        """Checks the configuration without building anything.

        Raises:
          UsageError: an unknown environment, condition or backend (with the
            closest valid name), a count below 1, a seed below 0, or a budget
            (``steps``) below one unroll.
        """
        import envs
        from hier_agents.baselines.impala.agent_env import CONDITIONS

        choice("environment", self.env, envs.names())
        choice("condition", self.condition, CONDITIONS)
        choice("backend", self.backend, ("local", "ray"))
        for name in ("steps", "actors", "envs_per_actor", "unroll_length", "image_size",
                     "t_abs"):
            if int(getattr(self, name)) < 1:
                raise UsageError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.batch_size is not None and self.batch_size < 1:
            raise UsageError(f"batch_size must be >= 1, got {self.batch_size!r}")
        if int(self.seed) < 0:
            raise UsageError(f"seed must be >= 0, got {self.seed!r}")
        for budget in self.save_at:
            if int(budget) < 1 or int(budget) > self.steps or int(budget) % self.unroll_length:
                raise UsageError(f"save_at {budget!r}: each must be a multiple of the unroll "
                                 f"length ({self.unroll_length}) within the budget "
                                 f"({self.steps} frames)")
        if self.steps < self.unroll_length:
            raise UsageError(f"a budget of {plural(self.steps, 'frame')} is less than one unroll "
                             f"of {plural(self.unroll_length, 'frame')}: give --frames >= "
                             f"{self.unroll_length} or a shorter --unroll-length")

    def resolved_batch(self, family: str) -> int:
        return int(self.batch_size or PAPER_BATCH[family])


# -- batching ---------------------------------------------------------------------------------


def make_batch(unrolls: list[dict], net, value_states: dict | None = None):
    """Stacks unrolls into time-major tensors for one learner step.

    ``value_states`` maps a stream to the value core's (h, c) after its last
    unroll; those rows replace the actors' (zero) value-core rows. A stream's
    first unroll starts at an episode start, where zeros are exact.
    """
    import torch

    obs = {k: torch.from_numpy(np.stack([u["obs"][k] for u in unrolls], axis=1))
           for k in unrolls[0]["obs"]}
    batch = {"obs": obs,
             "first": torch.from_numpy(np.stack([u["first"] for u in unrolls], axis=1))}
    for key in ("actions", "log_probs", "rewards_env", "discounts_env", "rewards_abs",
                "discounts_abs"):
        batch[key] = torch.from_numpy(np.stack([u[key] for u in unrolls], axis=1))
    state = list(stack_states([u["state"] for u in unrolls], net.initial_state(1)))
    streams = [tuple(u.get("stream", ())) for u in unrolls]
    # A stream may have several (consecutive, in arrival order) unrolls in one
    # batch: the later ones start from the earlier one's value state.
    chain, last_column = [], {}
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


def learner_step(net, optimizer, batch, config: TrainConfig,
                 value_states: dict | None = None) -> dict:
    """One gradient step on ``batch``; returns float statistics.

    When ``value_states`` is given, the value core's state after each
    unroll's last step is stored there for the stream's next unroll.
    """
    import torch

    from hier_agents.baselines.impala.vtrace import impala_loss

    T = batch["actions"].shape[0]
    out, new_state = net(batch["obs"], batch["first"], batch["state"],
                         value_state_after=T - 1, value_chain=batch.get("value_chain"))
    if value_states is not None:
        hv, cv = new_state[0].detach(), new_state[1].detach()
        for j, stream in enumerate(batch["streams"]):  # the stream's last column wins
            if stream:
                value_states[stream] = (hv[j].clone(), cv[j].clone())
    steps = type(out)(*(None if x is None else x[:-1] for x in out))
    bootstrap = type(out)(*(None if x is None else x[-1] for x in out))
    loss, stats = impala_loss(steps, bootstrap, batch["actions"], batch["log_probs"],
                              batch["rewards_env"], batch["discounts_env"],
                              batch["rewards_abs"], batch["discounts_abs"],
                              baseline_cost=config.baseline_cost,
                              entropy_cost=config.entropy_cost)
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(net.parameters(), config.grad_clip)
    optimizer.step()
    stats = dict(stats)
    stats["loss"] = float(loss.detach())
    stats["grad_norm"] = float(grad_norm)
    return stats


# -- checkpoints ------------------------------------------------------------------------------


def load_checkpoint(path: str | Path) -> dict:
    """The checkpoint of a `train` run: ``path`` is its file or its run directory.

    Raises:
      FileNotFoundError: no checkpoint there.
      UsageError: the file is not a checkpoint of this trainer (unreadable, or
        another trainer's: no ``model``, ``input_spec``, ``config`` or
        ``counters``).
    """
    import torch

    path = Path(path)
    if path.is_dir():
        path = path / CHECKPOINT
    if not path.exists():
        raise FileNotFoundError(f"no checkpoint at {path}")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as exc:  # noqa: BLE001 - whatever is wrong with the file, it is the input
        raise UsageError(f"{path} is not a readable checkpoint ({type(exc).__name__})") from None
    missing = [k for k in ("model", "input_spec", "config", "counters")
               if not isinstance(ckpt, dict) or k not in ckpt]
    if missing:
        raise UsageError(f"{path} is not a checkpoint of {TRAINER} (it has no "
                         f"{', '.join(missing)})")
    return ckpt


def _spec_from_dict(d: dict):
    from hier_agents.baselines.impala.agent_env import InputSpec

    d = dict(d)
    d["images"] = tuple((name, tuple(shape)) for name, shape in d["images"])
    for key in ("planner_shape", "state_shape"):
        if d.get(key) is not None:
            d[key] = tuple(d[key])
    return InputSpec(**d)


def net_from_checkpoint(ckpt: dict):
    """The trained `ImpalaNet` (eval mode) and its `InputSpec` from a checkpoint."""
    from hier_agents.baselines.impala.network import ImpalaNet

    spec = _spec_from_dict(ckpt["input_spec"])
    net = ImpalaNet(spec, two_values=ckpt["config"]["condition"] != "vanilla")
    net.load_state_dict(ckpt["model"])
    net.eval()
    return net, spec


# -- the loop ---------------------------------------------------------------------------------

#: Configuration keys a resumed run must share with its run directory (the
#: first identifies a run of this trainer made before runs recorded it).
FIXED = ("condition", "env", "cameras", "image_size", "state", "env_overrides")


def observed(config: dict, spec) -> tuple[list[str], bool]:
    """What a run's agent observed: (input keys, privileged), from its
    ``config.json`` when it recorded them, else inferred from its `InputSpec`
    (runs made before config.json recorded them)."""
    keys = config.get("observations")
    privileged = config.get("privileged")
    return (list(spec.keys) if keys is None else list(keys),
            bool(spec.privileged if privileged is None else privileged))


def _build(config: TrainConfig, run: RunDir):
    """(net, optimiser, input spec, counters, recent episodes), resumed from
    ``run``'s checkpoint when there is one."""
    import torch

    from hier_agents.baselines.impala.agent_env import AgentEnv
    from hier_agents.baselines.impala.network import ImpalaNet

    # The input spec comes from one environment built here (closed at once).
    probe = AgentEnv(config.env, config.condition, seed=config.seed, cameras=config.cameras,
                     image_size=config.image_size, state=config.state, t_abs=config.t_abs,
                     abs_reward=config.abs_reward, **config.env_overrides)
    spec = probe.input_spec
    probe.close()
    run.record(observations=list(spec.keys), privileged=spec.privileged)
    net = ImpalaNet(spec, two_values=config.condition != "vanilla")
    optimizer = torch.optim.RMSprop(net.parameters(), lr=config.learning_rate,
                                    alpha=config.rmsprop_alpha, eps=config.rmsprop_eps,
                                    momentum=config.rmsprop_momentum)
    counters = {"frames": 0, "updates": 0, "episodes": 0, "wall_s": 0.0, "cpu_s": 0.0}
    recent: deque = deque(maxlen=100)
    ckpt = run.load()
    if ckpt is not None:
        net.load_state_dict(ckpt["model"])
        optimizer.load_state_dict(ckpt["optimizer"])
        counters.update(ckpt["counters"])
        recent.extend(ckpt["counters"].get("recent_episodes", []))
        print(f"resuming {run.checkpoint_path} at {plural(counters['frames'], 'frame')}, "
              f"{plural(counters['updates'], 'update')}", file=sys.stderr)
    counters.pop("recent_episodes", None)
    return net, optimizer, spec, counters, recent


def _gather(actors, pending: list, batch_size: int, counters: dict, recent: deque,
            run: RunDir, actor_cpu: dict) -> None:
    """Takes unrolls (and their finished episodes) until ``batch_size`` are
    pending or a stop; ``actor_cpu`` keeps each actor's latest CPU seconds."""
    while len(pending) < batch_size and not run.stop_requested:
        unrolls = actors.get(should_stop=lambda: run.stop_requested)
        for u in unrolls or ():
            actor_cpu[u["stream"][0]] = float(u.pop("cpu_s", 0.0))
            for ep in u.pop("episodes"):
                counters["episodes"] += 1
                recent.append({"return": float(ep.get("episode_return", 0.0)),
                               "success": float(bool(ep.get("success", False))),
                               "steps": int(ep.get("episode_steps", 0)),
                               "subgoals": int(ep.get("subgoals_reached", 0))})
            pending.append(u)


def _scalars(stats: dict, counters: dict, recent: deque, fps: float, lags: list) -> dict:
    scalars = {"frames": counters["frames"], **{f"loss/{k}": float(v) for k, v in stats.items()}}
    scalars.update({"perf/frames_per_s": fps, "perf/updates": counters["updates"],
                    "perf/policy_lag": float(np.mean(lags)) if lags else 0.0,
                    "episodes/count": counters["episodes"], "wall_s": counters["wall_s"],
                    "cpu_s": counters["cpu_s"]})
    if recent:
        for key, name in (("success", "success_rate"), ("return", "return"), ("steps", "steps"),
                          ("subgoals", "subgoals_reached")):
            scalars[f"episodes/{name}"] = float(np.mean([e.get(key, 0) for e in recent]))
    return scalars


def train(config: TrainConfig) -> dict:
    """Runs (or resumes) a training run; returns its final counters.

    Raises:
      UsageError: `TrainConfig.validate`'s, or the logdir is a file or holds
        a run this one cannot continue (`RunDir`), before anything is built.
    """
    import torch

    from hier_agents.modular.components import family as env_family

    config.validate()
    batch_size = config.resolved_batch(env_family(config.env))
    run = RunDir(config.logdir, dataclasses.asdict(config), resume=None, fixed=FIXED,
                 trainer=TRAINER)
    torch.manual_seed(config.seed)
    torch.set_num_threads(1)
    try:
        net, optimizer, spec, counters, recent = _build(config, run)
        if counters["frames"] >= config.steps:
            print(f"{run.checkpoint_path} already has {plural(counters['frames'], 'frame')}, "
                  f"the budget is {plural(config.steps, 'frame')}: nothing to train",
                  file=sys.stderr)
            return counters
        return _loop(config, run, net, optimizer, spec, counters, recent, batch_size)
    finally:
        run.close()


def _loop(config, run: RunDir, net, optimizer, spec, counters, recent, batch_size) -> dict:
    """Actors, learner steps, logs and checkpoints until the frame budget or a stop."""
    actor_config = ActorConfig(env=config.env, condition=config.condition,
                               unroll_length=config.unroll_length,
                               envs_per_actor=config.envs_per_actor, cameras=config.cameras,
                               image_size=config.image_size, state=config.state,
                               t_abs=config.t_abs, abs_reward=config.abs_reward,
                               seed=config.seed * 1000 + counters["updates"],
                               env_overrides=dict(config.env_overrides))
    if config.backend == "ray":
        actors = RayActors(actor_config, config.actors, net, address=config.ray_address)
    else:
        actors = LocalActors(actor_config, config.actors, net)
        actors.publish(net)
    published = 1  # weights versions published to the actors in this process

    save_at = sorted({int(b) for b in config.save_at})

    def save(keep: bool = config.keep_checkpoints):
        run.save({"format": 1, "model": net.state_dict(), "optimizer": optimizer.state_dict(),
                  "counters": dict(counters, recent_episodes=list(recent)),
                  "input_spec": dataclasses.asdict(spec)},
                 keep=f"frames-{int(counters['frames'])}" if keep else None)

    bar = run.progress(config.steps, counters["frames"], desc=f"{config.env} {config.condition}",
                       unit="frame", disable=not config.progress)
    start = last_ckpt = last_log = time.perf_counter()
    wall0, frames_at_log = counters["wall_s"], counters["frames"]
    # CPU seconds: earlier processes' (the checkpoint's), this one's since
    # here, and each of this run's actors' (reported with their unrolls).
    cpu0, process0, actor_cpu = counters.get("cpu_s", 0.0), time.process_time(), {}

    def count_cpu():
        counters["cpu_s"] = cpu0 + (time.process_time() - process0) + sum(actor_cpu.values())

    pending: list[dict] = []
    value_states: dict = {}  # stream -> value-core (h, c) after its last unroll
    stats: dict = {}
    lags: list[int] = []
    with run.interruptible():
        try:
            while counters["frames"] < config.steps and not run.stop_requested:
                # An update takes only the unrolls the budget, or the next
                # save_at point, still needs.
                target = min([b for b in save_at if b > counters["frames"]] + [config.steps])
                take = min(batch_size, math.ceil((target - counters["frames"])
                                                 / config.unroll_length))
                _gather(actors, pending, take, counters, recent, run, actor_cpu)
                if run.stop_requested:  # the partial batch is dropped
                    break
                batch_unrolls, pending = pending[:take], pending[take:]
                # Updates between the weights an unroll was acted with and now.
                lags.extend(published - int(u.get("policy_version", 0)) for u in batch_unrolls)
                batch = make_batch(batch_unrolls, net, value_states)
                stats = learner_step(net, optimizer, batch, config, value_states)
                actors.publish(net)
                published += 1
                counters["updates"] += 1
                new_frames = config.unroll_length * len(batch_unrolls)
                counters["frames"] += new_frames
                bar.update(new_frames)
                now = time.perf_counter()
                counters["wall_s"] = wall0 + (now - start)
                count_cpu()
                if recent:
                    bar.set_postfix(success=f"{np.mean([e['success'] for e in recent]):.2f}",
                                    ret=f"{np.mean([e['return'] for e in recent]):.2f}",
                                    refresh=False)
                if now - last_log >= config.log_every_s or counters["frames"] >= config.steps:
                    fps = (counters["frames"] - frames_at_log) / max(now - last_log, 1e-9)
                    run.log(counters["frames"], _scalars(stats, counters, recent, fps, lags))
                    last_log, frames_at_log, lags = now, counters["frames"], []
                if counters["frames"] in save_at and counters["frames"] < config.steps:
                    save(keep=True)
                    last_ckpt = now
                elif now - last_ckpt >= config.checkpoint_every_s:
                    save()
                    last_ckpt = now
        finally:
            bar.close()
            actors.close()
            counters["wall_s"] = wall0 + (time.perf_counter() - start)
            count_cpu()
            save(keep=config.keep_checkpoints or counters["frames"] in save_at)
    if run.stop_requested:
        print(f"interrupted: checkpoint saved at {plural(counters['frames'], 'frame')}; run "
              f"the same command to resume", file=sys.stderr)
    if recent:
        counters["success_rate_last_100"] = float(np.mean([e["success"] for e in recent]))
        counters["return_last_100"] = float(np.mean([e["return"] for e in recent]))
    counters["last_stats"] = stats
    return counters
