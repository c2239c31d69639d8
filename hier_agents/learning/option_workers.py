"""The vector environments of `hier_agents.learning.train_options` and the
CPU clocks that count their worker processes.

* `make_option_env`, `make_abstract_env`: thunks of one shaped environment
  copy (`OptionEnv` or `AbstractOptionEnv`, wrapped in `Shaped`);
* `make_vector`: a training phase's vector environment;
* `WorkerClock`, `CpuClock`: CPU seconds (user + system) of the workers
  (read from ``/proc``) and of this process.
"""

from __future__ import annotations

import os
import time

import torch

from hier_agents.learning import ppo
from hier_agents.learning.option_shaping import AbstractOptionEnv, Shaped

__all__ = ["make_option_env", "make_abstract_env", "make_vector", "WorkerClock", "CpuClock"]


def make_option_env(env_name: str, seed: int, args):
    """A thunk building `OptionEnv` (``args``: skill, estimator, gamma, t_abs)
    wrapped in `Shaped` (``args``: shape_box, shape_player, box_distance)."""

    def thunk():
        torch.set_num_threads(1)
        from hier_agents.learning.option_env import OptionEnv

        env = OptionEnv(
            env_name,
            skill=args.skill,
            estimator=args.estimator,
            seed=seed,
            gamma=args.gamma,
            t_abs=args.t_abs,
        )
        return Shaped(env, args.shape_box, args.shape_player, args.box_distance, args.gamma)

    return thunk


def make_abstract_env(env_name: str, seed: int, args):
    """A thunk building `AbstractOptionEnv` (``args.abstract_duration``,
    ``args.gamma``) wrapped in `Shaped` as `make_option_env`."""

    def thunk():
        env = AbstractOptionEnv(env_name, seed, args.abstract_duration, args.gamma)
        return Shaped(env, args.shape_box, args.shape_player, args.box_distance, args.gamma)

    return thunk


class WorkerClock:
    """CPU seconds (user + system) of live worker processes, from /proc."""

    def __init__(self, pids):
        self.pids = list(pids)
        self.tick = os.sysconf("SC_CLK_TCK")
        self.last = {pid: 0.0 for pid in self.pids}

    def seconds(self) -> float:
        for pid in self.pids:
            try:
                with open(f"/proc/{pid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                self.last[pid] = (int(fields[11]) + int(fields[12])) / self.tick
            except (OSError, IndexError, ValueError):
                pass  # exited: keep its last reading
        return sum(self.last.values())


def make_vector(phase: str, names, state, args):
    """The phase's vector env, its env names (dealt in turn) and its worker pids."""
    if phase == "abstract":
        n = args.abstract_envs
        phase_names = [names[k % len(names)] for k in range(n)]
        thunks = [
            make_abstract_env(phase_names[k], state["env_seed"] + 500 + k, args) for k in range(n)
        ]
        return ppo.make_vector_env(thunks), phase_names, []
    phase_names = [names[k % len(names)] for k in range(args.envs)]
    seed0 = state["env_seed"] + state["updates"]
    thunks = [make_option_env(phase_names[k], seed0 + k, args) for k in range(args.envs)]
    if args.sync:
        return ppo.make_vector_env(thunks), phase_names, []
    vec = ppo.make_vector_env(thunks, asynchronous=True, context="forkserver")
    pids = [p.pid for p in vec.processes]
    try:  # the forkserver that forks the workers (imports once) counts too
        from multiprocessing import forkserver

        # A private attribute, which typeshed's stubs leave out.
        pids.append(forkserver._forkserver._forkserver_pid)  # type: ignore[attr-defined]
    except Exception:  # noqa: BLE001 - private API: best effort
        pass
    return vec, phase_names, [p for p in pids if p]


class CpuClock:
    """CPU seconds of this process and its live vector-env workers, on top of
    ``base`` (earlier phases and runs)."""

    def __init__(self, base: float) -> None:
        self.base, self.main0 = float(base), time.process_time()
        self.workers: list[WorkerClock] = []

    def now(self) -> float:
        return self.base + time.process_time() - self.main0 + sum(w.seconds() for w in self.workers)

    def freeze(self) -> None:
        """Folds the workers' last readings into ``base`` (before they exit)."""
        self.base, self.main0, self.workers = self.now(), time.process_time(), []
