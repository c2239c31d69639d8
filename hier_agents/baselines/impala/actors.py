"""Actors: run the current policy in a few environments and return unrolls.

An `Actor` owns ``envs_per_actor`` `AgentEnv` copies and a local `ImpalaNet`.
``unroll(weights)`` loads the given weights (when not None), steps every
environment ``unroll_length`` times with one batched forward pass per step,
and returns one `Unroll` per environment:

* ``obs``: dict of arrays ``[T + 1, ...]`` (the last entry is the observation
  the learner bootstraps from; it is also the next unroll's first entry);
* ``first``: bool ``[T + 1]``: the observation begins an episode (the
  network zeroes its core state there);
* ``actions`` ``[T, A]`` (unclipped Gaussian samples), ``log_probs`` ``[T]``
  (the behaviour policy's), ``rewards_env``, ``discounts_env``,
  ``rewards_abs``, ``discounts_abs`` ``[T]``;
* ``state``: the policy core's state before ``obs[0]`` (one row per core
  tensor), so the learner replays the unroll from the actor's memory; the
  actors run the policy only (`ImpalaNet.act(policy_only=True)`), so the
  value-core rows are zeros and the learner carries the value core's state
  from one unroll of a ``stream`` (actor, environment) to the next;
* ``stream``: ``(actor_id, env_index)``; a stream's unrolls arrive in order;
* ``episodes``: stats of the episodes that ended during the unroll.

Backends: `LocalActors` runs each actor in its own process (``spawn``),
reading the learner's weights from shared memory whenever the learner
publishes a new version; `RayActors` runs the same `Actor` class as Ray
actors and sends weights through Ray's object store. Both offer ``get()``,
which blocks until some actor's unrolls are ready (or returns None as soon
as its ``should_stop`` callback says so: the learner was interrupted), and
``close()``. Actor processes ignore SIGINT: Ctrl-C in a terminal reaches the
whole process group, and the learner, not each actor, decides how to stop
(finish the update, save a checkpoint, then stop the actors).
"""

from __future__ import annotations

import dataclasses
import os
import queue
import signal
import time
import traceback
from typing import Callable

import numpy as np

from hier_agents.modular.options import T_ABS


@dataclasses.dataclass
class ActorConfig:
    """What an actor needs to build its environments and its network."""

    env: str
    condition: str
    unroll_length: int = 100
    envs_per_actor: int = 4
    cameras: bool = False
    image_size: int = 96
    state: bool = False
    t_abs: int = T_ABS
    abs_reward: float = 1.0
    seed: int = 0
    env_overrides: dict = dataclasses.field(default_factory=dict)


_BINARY_KEYS = frozenset({"planner", "planner_action", "state"})
_POLL_S = 0.5  # how often a waiting learner checks for a stop request or a dead actor


def _state_rows(state, index: int) -> list[np.ndarray]:
    """Column ``index`` of each core-state tensor (batch is dim 1 for 3-D, else 0)."""
    rows = []
    for s in state:
        s = s.detach().cpu().numpy()
        rows.append(s[:, index].copy() if s.ndim == 3 else s[index].copy())
    return rows


def stack_states(rows: list[list[np.ndarray]], like) -> tuple:
    """Stacks per-unroll state rows back into batched core-state tensors."""
    import torch

    out = []
    for k, template in enumerate(like):
        # np.stack copies, so the tensors own writable memory (Ray's arrays are read-only).
        out.append(torch.from_numpy(np.stack([r[k] for r in rows],
                                             axis=1 if template.dim() == 3 else 0)))
    return tuple(out)


class Actor:
    """Steps ``envs_per_actor`` environments with the current policy."""

    def __init__(self, config: ActorConfig, actor_id: int):
        import torch

        from hier_agents.baselines.impala.agent_env import AgentEnv
        from hier_agents.baselines.impala.network import ImpalaNet

        torch.set_num_threads(1)
        self.config, self.actor_id = config, actor_id
        base = config.seed * 10_007 + actor_id * 101
        self.envs = [AgentEnv(config.env, config.condition, seed=base + i,
                              cameras=config.cameras, image_size=config.image_size,
                              state=config.state,
                              t_abs=config.t_abs, abs_reward=config.abs_reward,
                              **config.env_overrides)
                     for i in range(config.envs_per_actor)]
        self.spec = self.envs[0].input_spec
        self.net = ImpalaNet(self.spec, two_values=config.condition != "vanilla")
        self.net.eval()
        self._generator = torch.Generator().manual_seed(base + 7)
        n = len(self.envs)
        self._obs = [env.reset() for env in self.envs]
        self._first = np.ones(n, dtype=bool)
        self._state = self.net.initial_state(n)
        self._returns = np.zeros(n)
        self.frames = 0

    def unroll(self, weights: dict | None = None) -> list[dict]:
        """Runs one unroll in every environment (see the module docstring)."""
        import torch

        if weights is not None:
            self.net.load_state_dict(weights)
        T, n = self.config.unroll_length, len(self.envs)
        keys = list(self._obs[0])
        # The planner inputs are 0/1 planes and one-hots: uint8 in transit
        # (4x less to pickle); the network casts them back to float.
        obs_buf = {k: np.empty((T + 1, n, *self._obs[0][k].shape),
                               np.uint8 if k in _BINARY_KEYS else self._obs[0][k].dtype)
                   for k in keys}
        first_buf = np.empty((T + 1, n), dtype=bool)
        actions = np.empty((T, n, self.spec.action_dim), dtype=np.float32)
        log_probs = np.empty((T, n), dtype=np.float32)
        r_env, d_env = np.empty((T, n), np.float32), np.empty((T, n), np.float32)
        r_abs, d_abs = np.empty((T, n), np.float32), np.empty((T, n), np.float32)
        start_state = [_state_rows(self._state, i) for i in range(n)]
        episodes: list[dict] = []
        for t in range(T + 1):
            for k in keys:
                for i in range(n):
                    obs_buf[k][t, i] = self._obs[i][k]
            first_buf[t] = self._first
            if t == T:
                break
            batch = {k: obs_buf[k][t] for k in keys}
            with torch.no_grad():
                a, logp, self._state = self.net.act(batch, self._first, self._state,
                                                    generator=self._generator,
                                                    policy_only=True)
            actions[t], log_probs[t] = a, logp
            for i, env in enumerate(self.envs):
                res = env.step(a[i])
                r_env[t, i], d_env[t, i] = res.reward_env, res.discount_env
                r_abs[t, i], d_abs[t, i] = res.reward_abs, res.discount_abs
                if res.last:
                    episodes.append(dict(res.info, actor=self.actor_id))
                    self._obs[i] = env.reset()
                    self._first[i] = True
                else:
                    self._obs[i] = res.obs
                    self._first[i] = False
        self.frames += T * n
        cpu_s = time.process_time()  # this actor process's CPU seconds so far
        out = []
        for i in range(n):
            out.append({
                "obs": {k: obs_buf[k][:, i] for k in keys},
                "first": first_buf[:, i],
                "actions": actions[:, i], "log_probs": log_probs[:, i],
                "rewards_env": r_env[:, i], "discounts_env": d_env[:, i],
                "rewards_abs": r_abs[:, i], "discounts_abs": d_abs[:, i],
                "state": start_state[i],
                "stream": (self.actor_id, i),
                "episodes": episodes if i == 0 else [],
                "cpu_s": cpu_s,
            })
        return out

    def close(self) -> None:
        for env in self.envs:
            env.close()


# -- local processes ------------------------------------------------------------------------


def _local_worker(config: ActorConfig, actor_id: int, shared_net, version, out_queue,
                  stop_event) -> None:
    """Process body: copy the shared weights when they change, unroll, queue;
    stops when ``stop_event`` is set or the learner's process is gone (killed
    without closing its actors, e.g. out of memory)."""
    # Ctrl-C signals the whole process group; the learner stops us through stop_event.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("MUJOCO_GL", "egl")
    learner = os.getppid()
    actor = None
    try:
        actor = Actor(config, actor_id)
        seen = -1
        while not stop_event.is_set() and os.getppid() == learner:
            weights = None
            if version.value != seen:
                seen = version.value
                weights = {k: v.clone() for k, v in shared_net.state_dict().items()}
            unrolls = actor.unroll(weights)
            for u in unrolls:
                u["policy_version"] = seen
            while not stop_event.is_set() and os.getppid() == learner:
                try:
                    out_queue.put(("unrolls", actor_id, unrolls), timeout=0.5)
                    break
                except queue.Full:
                    continue
    except Exception:  # report, do not die silently
        out_queue.put(("error", actor_id, traceback.format_exc()))
    finally:
        if actor is not None:
            actor.close()


class LocalActors:
    """``num_actors`` actor processes fed from a shared-memory copy of the net."""

    def __init__(self, config: ActorConfig, num_actors: int, net, *, max_queued: int = 4):
        import torch.multiprocessing as mp

        ctx = mp.get_context("spawn")
        self._shared = net
        self._shared.share_memory()
        self._version = ctx.Value("l", 0)
        self._queue = ctx.Queue(maxsize=max(1, max_queued))
        self._stop = ctx.Event()
        self._procs = [ctx.Process(target=_local_worker, daemon=True,
                                   args=(config, i, self._shared, self._version, self._queue,
                                         self._stop), name=f"impala-actor-{i}")
                       for i in range(num_actors)]
        for p in self._procs:
            p.start()

    def publish(self, net) -> None:
        """Makes ``net``'s weights the actors' policy (in place, shared memory)."""
        if net is not self._shared:
            self._shared.load_state_dict(net.state_dict())
        with self._version.get_lock():
            self._version.value += 1

    def get(self, timeout: float = 600.0,
            should_stop: Callable[[], bool] | None = None) -> list[dict] | None:
        """The next actor's unrolls, or None once ``should_stop()`` is true.

        Raises RuntimeError with the actor's traceback if one failed, at once
        if an actor process died without a word (killed, out of memory), and
        after ``timeout`` seconds without any unroll.
        """
        deadline = time.monotonic() + timeout
        while True:
            if should_stop is not None and should_stop():
                return None
            self._check_alive()
            try:
                kind, actor_id, payload = self._queue.get(timeout=_POLL_S)
                break
            except queue.Empty:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"no unroll from any actor within {timeout:.0f} s "
                                   f"(actors alive: {[p.is_alive() for p in self._procs]})")
        if kind == "error":
            raise RuntimeError(f"actor {actor_id} failed:\n{payload}")
        return payload

    def _check_alive(self) -> None:
        """Raises if an actor process has exited (the learner would starve or skew)."""
        dead = [(i, p.exitcode) for i, p in enumerate(self._procs) if not p.is_alive()]
        if not dead:
            return
        # A failing actor queues its traceback before it exits: report that first.
        for _ in range(4 * len(self._procs) + 8):  # what the queue holds, not a live stream
            try:
                kind, actor_id, payload = self._queue.get(timeout=_POLL_S)
            except queue.Empty:
                break
            if kind == "error":
                raise RuntimeError(f"actor {actor_id} failed:\n{payload}")
        raise RuntimeError("actor process(es) exited without reporting an error "
                           "(actor id, exit code): " + repr(dead))

    def close(self) -> None:
        self._stop.set()
        # Drain so blocked puts return, then join.
        for _ in range(64):
            try:
                self._queue.get_nowait()
            except (queue.Empty, OSError, ValueError):
                break
        for p in self._procs:
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()
                p.join(timeout=5)


# -- Ray ----------------------------------------------------------------------------------


class RayActors:
    """The same `Actor` class, run as Ray actors (one CPU each).

    Uses a running Ray cluster when ``address`` is given (``"auto"`` for the
    one ``ray start`` made), else starts a local one. Weights go through the
    object store once per `publish`.
    """

    def __init__(self, config: ActorConfig, num_actors: int, net, *, address: str | None = None):
        try:
            import ray
        except ImportError as exc:  # pragma: no cover - ray is a dependency
            raise RuntimeError("--backend ray needs the `ray` package: pip install ray") from exc
        from hier_agents.cluster import connect, remote

        self._ray = ray
        connect(address, num_cpus=None if address else max(num_actors, 1) + 1,
                log_to_driver=True)
        remote_cls = remote(_RayActor, num_cpus=1)
        self._actors = [remote_cls.remote(config, i) for i in range(num_actors)]
        self._weights_ref = None
        self._version = 0
        self.publish(net)
        # The weights ref travels inside a list so Ray does not fetch it for
        # actors whose weights are already current.
        self._pending = {a.unroll.remote([self._weights_ref], self._version): a
                         for a in self._actors}

    def publish(self, net) -> None:
        weights = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
        self._weights_ref = self._ray.put(weights)
        self._version += 1

    def get(self, timeout: float = 600.0,
            should_stop: Callable[[], bool] | None = None) -> list[dict] | None:
        """As `LocalActors.get`; an actor's exception is re-raised with its traceback."""
        ray = self._ray
        deadline = time.monotonic() + timeout
        while True:
            if should_stop is not None and should_stop():
                return None
            ready, _ = ray.wait(list(self._pending), num_returns=1, timeout=_POLL_S)
            if ready:
                break
            if time.monotonic() > deadline:
                raise RuntimeError(f"no unroll from any Ray actor within {timeout:.0f} s")
        ref = ready[0]
        actor = self._pending.pop(ref)
        unrolls = ray.get(ref)  # re-raises the actor's exception with its traceback
        self._pending[actor.unroll.remote([self._weights_ref], self._version)] = actor
        return unrolls

    def close(self) -> None:
        ray = self._ray
        for a in self._actors:
            try:
                ray.kill(a)
            except Exception:
                pass
        self._pending.clear()


class _RayActor:
    """Ray wrapper: the actor's last weights version, so unchanged weights are not reloaded."""

    def __init__(self, config: ActorConfig, actor_id: int):
        self._actor = Actor(config, actor_id)
        self._version = -1

    def unroll(self, weights_ref: list, version: int) -> list[dict]:
        import ray

        load = ray.get(weights_ref[0]) if version != self._version else None
        self._version = version
        unrolls = self._actor.unroll(load)
        for u in unrolls:
            u["policy_version"] = version
        return unrolls
