"""Agents as named parts: one contract, kinds registered once, one episode runner.

    from hier_agents.agents import Play, make_player, register, resolve
    kind, arg = resolve("random:10")                  # NAME[:ARG], as --agent takes it
    player = make_player(Play("mujoban/level1", agent="random:10"))
    row, counters = player.play(0)                    # episode 0 of seed 0

`base` holds the contract (`Agent`) and the kinds' base class
(`AgentKind`, `AgentSetup`); `registry` the kinds by name (`register`,
`resolve`, `forms`); `kinds`
the shipped kinds (``modular``, ``checkpoint:PATH``, ``sb3:PATH``, ``random[:HOLD]``;
``sb3`` in `sb3`);
`runner` the one episode runner (`Play`, `Player`, `play_episode`).
"""

from hier_agents.agents.base import Agent, AgentKind, AgentSetup
from hier_agents.agents.registry import KINDS, forms, kind_of, register, resolve
from hier_agents.agents.runner import Play, Player, make_player, play_episode

__all__ = [
    "KINDS",
    "Agent",
    "AgentKind",
    "AgentSetup",
    "Play",
    "Player",
    "forms",
    "kind_of",
    "make_player",
    "play_episode",
    "register",
    "resolve",
]
