"""The observation boundary: agents get timesteps and the public description only."""

from __future__ import annotations

import dataclasses
import itertools
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

import envs
from fast_cover import cover
from hier_agents.boundary import BoundaryEnv, BoundaryViolation, PRIVILEGED_OBSERVATIONS
from hier_agents.modular.components import (
    ESTIMATORS,
    PLANNERS,
    SKILLS,
    env_overrides,
    is_privileged,
    make_agent,
    reads_record,
)

ROOT = Path(__file__).resolve().parents[1]
#: One short environment per family (a shortened time limit keeps every
#: combination's episode short; on the boards it still holds the arm's first
#: touch and the opponent's reply).
FAMILY_ENVS = {
    "mujoban": ("mujoban/level1-pegs", 8.0),
    "mujoxo": ("mujoxo/mixture", 8.0),
    "mujogo": ("mujogo/7x7", 4.0),
    "mujoboard": ("mujoboard/breakthrough-6x6", 8.0),
}


def _combinations():
    for fam, (name, limit) in FAMILY_ENVS.items():
        for est, plan, skill in itertools.product(ESTIMATORS[fam], PLANNERS[fam], SKILLS[fam]):
            yield pytest.param(name, limit, est, plan, skill, id=f"{fam}-{est}-{plan}-{skill}")


def _choices(name, limit, estimator, planner, skill):
    fam = name.split("/")[0]
    return [("estimator", fam, estimator), ("planner", fam, planner), ("skill", fam, skill)]


@pytest.mark.parametrize(
    "name, limit, estimator, planner, skill", cover(list(_combinations()), _choices)
)
def test_every_listed_combination_plays_through_the_boundary(
    name, limit, estimator, planner, skill, request
):
    """Each estimator/planner/skill offered by ``--list`` plays an episode
    through a wrapper exposing only reset, step, the specs and the public
    description; a privileged estimator handed that wrapper as its
    "simulator" is stopped at its first read."""
    if name.startswith("mujogo"):  # the opponent (and the gnugo planner) need GNU Go
        request.getfixturevalue("gnugo")
    fam = name.split("/")[0]
    env = envs.load(name, seed=1, time_limit=limit, **env_overrides(name, estimator))
    # Only the board estimator, which reads the game record, keeps it.
    view = BoundaryEnv(
        env,
        strip=PRIVILEGED_OBSERVATIONS
        if reads_record(fam, estimator)
        else env.privileged_observations,
    )
    privileged = is_privileged(fam, estimator)
    agent = make_agent(
        name,
        view.description(),
        planner=planner,
        skill=skill,
        estimator=estimator,
        seed=1,
        simulator=view if privileged else None,
    )
    assert agent.privileged == privileged
    try:
        timestep = view.reset()
        assert not PRIVILEGED_OBSERVATIONS & set(timestep.observation)
        if not reads_record(fam, estimator):
            assert not env.privileged_observations & set(timestep.observation)
        if privileged:
            with pytest.raises(BoundaryViolation):
                agent.reset(view.description(), timestep, seed=1)
                agent.act(timestep)
            return
        agent.reset(view.description(), timestep, seed=1)
        steps = 0
        while not timestep.last():
            action = agent.act(timestep)
            assert np.shape(action) == view.action_spec().shape
            if agent.gave_up is not None:
                break
            timestep = view.step(action)
            steps += 1
        assert steps > 0
    finally:
        agent.planner.close()
        env.close()


def test_the_wrapper_refuses_the_simulator_and_strips_ground_truth():
    env = envs.load("mujoban/level1", seed=0, top_camera=None, egocentric_camera=None)
    view = BoundaryEnv(env)
    for name in ("physics", "task", "render", "_env_private"):
        with pytest.raises(BoundaryViolation, match=name):
            getattr(view, name)
    with pytest.raises(BoundaryViolation):
        view.task = None
    timestep = view.reset()
    assert "full_entity_layer" not in timestep.observation
    assert "full_entity_layer" not in view.observation_spec()
    assert "walker/orientation" in timestep.observation
    # What is stripped is what the environment declares privileged.
    stripped = set(env.observation_spec()) - set(view.observation_spec())
    assert stripped == env.privileged_observations == PRIVILEGED_OBSERVATIONS
    assert set(timestep.observation) == set(view.observation_spec())
    env.close()


def _values(obj, depth=0):
    if depth > 6:
        return
    yield obj
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _values(getattr(obj, f.name), depth + 1)
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from _values(v, depth + 1)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _values(v, depth + 1)


@pytest.mark.parametrize("name", ["mujoban/level5-pegs", "mujoxo/mixture", "mujogo/7x7"])
def test_descriptions_are_static_values_without_simulator_handles(name):
    env = envs.load(name, seed=0)
    description = env.description()
    assert dataclasses.is_dataclass(description)
    with pytest.raises(dataclasses.FrozenInstanceError):
        description.control_timestep = 1.0
    live = (mujoco.MjData, mujoco.MjModel, type(env.physics), type(env.task))
    assert not any(isinstance(v, live) for v in _values(description))
    env.reset()
    assert env.description() == description  # the same facts every episode
    env.close()


#: Agent-side code (what runs at run time behind the boundary). The
#: privileged estimators (hier_agents/estimators/mujoban.py) are the exception
#: by design.
AGENT_SOURCES = sorted(
    [
        *ROOT.glob("skills/**/*.py"),
        *ROOT.glob("abstract_planners/*.py"),
        ROOT / "hier_agents/modular/agent.py",
        *[p for p in ROOT.glob("hier_agents/estimators/*.py") if p.name != "mujoban.py"],
    ]
)
FORBIDDEN = re.compile(
    r"\.physics\b|\benv\.task\b|\.ptr\b|full_entity_layer|pixel_layer|"
    r"\btask\._"
)


@pytest.mark.parametrize("path", AGENT_SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_agent_code_never_reaches_for_the_simulator(path):
    code = "\n".join(line.split("#", 1)[0] for line in path.read_text().splitlines())
    code = re.sub(r'"""[\s\S]*?"""', "", code)  # docstrings may explain the boundary
    hits = FORBIDDEN.findall(code)
    assert not hits, f"{path.relative_to(ROOT)} reads the simulator: {sorted(set(hits))}"
