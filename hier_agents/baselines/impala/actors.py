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

Backends, both an `hier_agents.executor.Pool` of ``num_actors`` workers that
each hold one `Actor` and keep two unroll calls in flight (so an actor starts
its next unroll while the learner steps): `LocalActors` runs them in spawned
processes, which read the learner's weights from shared memory whenever the
learner publishes a new version; `RayActors` runs them as Ray actors and
sends weights through Ray's object store. Both offer ``publish(net)``,
``get()``, which blocks until some actor's unrolls are ready (or returns None
as soon as its ``should_stop`` callback says so: the learner was
interrupted), and ``close()``. An actor whose process dies is replaced and its
unrolls run again (the executor's one retry policy: a line on stderr, then
`WorkerDied`); one that raises stops the learner with its traceback. Actor
processes ignore SIGINT: Ctrl-C in a terminal reaches the whole process group,
and the learner, not each actor, decides how to stop (finish the update, save
a checkpoint, then stop the actors).
"""

from __future__ import annotations

import time
from functools import partial
from typing import TYPE_CHECKING, Callable

import numpy as np

from hier_agents.baselines.impala.config import TrainConfig
from hier_agents.executor import CallFailed, Pool

if TYPE_CHECKING:
    from ray import ObjectRef


_BINARY_KEYS = frozenset({"planner", "planner_action", "state"})
IN_FLIGHT = 2  # unroll calls queued per actor: it starts the next while the learner steps


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
        out.append(
            torch.from_numpy(np.stack([r[k] for r in rows], axis=1 if template.dim() == 3 else 0))
        )
    return tuple(out)


class Actor:
    """Steps ``envs_per_actor`` environments with the current policy; its
    environments are seeded from ``config.seed`` and ``actor_id``."""

    def __init__(self, config: TrainConfig, actor_id: int):
        import torch

        from envs.vector import PhysicsPool
        from hier_agents.baselines.impala.agent_env import AgentEnv
        from hier_agents.baselines.impala.network import net_for

        torch.set_num_threads(1)
        self.config, self.actor_id = config, actor_id
        base = config.seed * 10_007 + actor_id * 101
        self.envs = [
            AgentEnv(
                config.env,
                config.condition,
                seed=base + i,
                cameras=config.cameras,
                image_size=config.image_size,
                state=config.state,
                t_abs=config.t_abs,
                abs_reward=config.abs_reward,
                action_repeat=config.action_repeat,
                **config.env_overrides,
            )
            for i in range(config.envs_per_actor)
        ]
        self._pool = PhysicsPool(config.env_threads)
        self.spec = self.envs[0].input_spec
        self.net = net_for(self.spec, config)
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

        from hier_agents.baselines.impala.agent_env import step_all

        if weights is not None:
            self.net.load_state_dict(weights)
        T, n = self.config.unroll_length, len(self.envs)
        keys = list(self._obs[0])
        # The planner inputs are 0/1 planes and one-hots: uint8 in transit
        # (4x less to pickle); the network casts them back to float.
        obs_buf = {
            k: np.empty(
                (T + 1, n, *self._obs[0][k].shape),
                np.uint8 if k in _BINARY_KEYS else self._obs[0][k].dtype,
            )
            for k in keys
        }
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
                a, logp, self._state = self.net.act(
                    batch, self._first, self._state, generator=self._generator, policy_only=True
                )
            actions[t], log_probs[t] = a, logp
            for i, (env, res) in enumerate(zip(self.envs, step_all(self.envs, a, self._pool))):
                r_env[t, i], d_env[t, i] = res.reward_env, res.discount_env
                r_abs[t, i], d_abs[t, i] = res.reward_abs, res.discount_abs
                if res.last:
                    episodes.append(dict(res.info, actor=self.actor_id))
                    self._obs[i] = env.reset()
                    self._first[i] = True
                else:
                    self._obs[i] = res.obs
                    self._first[i] = False
        self.frames += self.config.frames_per_unroll * n
        cpu_s = time.process_time()  # this actor process's CPU seconds so far
        out = []
        for i in range(n):
            out.append(
                {
                    "obs": {k: obs_buf[k][:, i] for k in keys},
                    "first": first_buf[:, i],
                    "actions": actions[:, i],
                    "log_probs": log_probs[:, i],
                    "rewards_env": r_env[:, i],
                    "discounts_env": d_env[:, i],
                    "rewards_abs": r_abs[:, i],
                    "discounts_abs": d_abs[:, i],
                    "state": start_state[i],
                    "stream": (self.actor_id, i),
                    "episodes": episodes if i == 0 else [],
                    "cpu_s": cpu_s,
                }
            )
        return out

    def close(self) -> None:
        self._pool.close()
        for env in self.envs:
            env.close()


# -- the two backends -----------------------------------------------------------------------


class _Actors:
    """What both backends share: a `Pool` of actors, ``IN_FLIGHT`` unroll
    calls each, ``get`` and ``close``."""

    pool: Pool

    def _start(self, num_actors: int) -> None:
        for actor_id in range(num_actors):
            for _ in range(IN_FLIGHT):
                self._submit(actor_id)

    def _submit(self, actor_id: int) -> None:
        self.pool.submit(
            "unroll", *self._unroll_args(), worker=actor_id, label=f"actor {actor_id}'s unroll"
        )

    def _unroll_args(self) -> tuple:
        return ()

    @property
    def restarts(self) -> int:
        """Actors replaced after their process died."""
        return self.pool.restarts

    def get(
        self, timeout: float = 600.0, should_stop: Callable[[], bool] | None = None
    ) -> list[dict] | None:
        """The next actor's unrolls (that actor's next unroll is queued), or
        None once ``should_stop()`` is true.

        Raises:
          RuntimeError: an actor raised (``actor N failed:`` and its
            traceback), or no unroll came within ``timeout`` seconds.
          WorkerDied: an actor's process died more than `WORKER_RETRIES`
            times running one unroll.
        """
        try:
            call = self.pool.next(timeout, should_stop)
        except CallFailed as exc:
            raise RuntimeError(f"actor {exc.call.worker} failed:\n{exc.details}") from None
        except TimeoutError:
            raise RuntimeError(f"no unroll from any actor within {timeout:.0f} s") from None
        if call is None:
            return None
        self._submit(call.worker)
        return call.result

    def close(self) -> None:
        self.pool.close()


class _SharedWeightsActor:
    """A local actor's worker: an `Actor` that copies the shared net's
    weights before an unroll when their version changed."""

    def __init__(self, config: TrainConfig, shared_net, version, actor_id: int):
        self.actor, self.shared, self.version, self.seen = (
            Actor(config, actor_id),
            shared_net,
            version,
            -1,
        )

    def unroll(self) -> list[dict]:
        weights = None
        if self.version.value != self.seen:
            self.seen = self.version.value
            weights = {k: v.clone() for k, v in self.shared.state_dict().items()}
        unrolls = self.actor.unroll(weights)
        for u in unrolls:
            u["policy_version"] = self.seen
        return unrolls

    def close(self) -> None:
        self.actor.close()


class LocalActors(_Actors):
    """``num_actors`` actor processes fed from a shared-memory copy of the net."""

    def __init__(self, config: TrainConfig, num_actors: int, net):
        import torch.multiprocessing as mp

        ctx = mp.get_context("spawn")  # torch's: the shared net travels as shared memory
        self._shared = net
        self._shared.share_memory()
        self._version = ctx.Value("l", 0)
        factory = partial(_SharedWeightsActor, config, self._shared, self._version)
        self.pool = Pool(factory, num_actors, name="impala-actor", context=ctx)
        self._start(num_actors)

    def publish(self, net) -> None:
        """Makes ``net``'s weights the actors' policy (in place, shared memory)."""
        if net is not self._shared:
            self._shared.load_state_dict(net.state_dict())
        with self._version.get_lock():
            self._version.value += 1


class RayActors(_Actors):
    """The same `Actor` class, run as Ray actors (one CPU each).

    Uses a running Ray cluster when ``address`` is given (``"auto"`` for the
    one ``ray start`` made), else starts a local one. Weights go through the
    object store once per `publish`.

    Raises:
      UsageError: no Ray cluster answers at ``address``.
    """

    def __init__(self, config: TrainConfig, num_actors: int, net, *, address: str | None = None):
        self._weights_ref: ObjectRef[dict] | None = None
        self._version = 0
        self.pool = Pool(
            partial(_RayActor, config), num_actors, address=address or "local", name="impala-actor"
        )
        import ray

        self._ray = ray
        self.publish(net)
        self._start(self.pool.size)

    def publish(self, net) -> None:
        weights = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
        self._weights_ref = self._ray.put(weights)
        self._version += 1

    def _unroll_args(self) -> tuple:
        # The weights ref travels inside a list so Ray does not fetch it for
        # actors whose weights are already current.
        return [self._weights_ref], self._version


class _RayActor:
    """A Ray actor's worker: the actor's last weights version, so unchanged
    weights are not reloaded."""

    def __init__(self, config: TrainConfig, actor_id: int):
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

    def close(self) -> None:
        self._actor.close()
