"""Which planners, skills and estimators fit which environment, by name.

    agent = make_agent("mujoban/level5-pegs", env.description())             # defaults
    agent = make_agent("mujoban/level5-pegs", env.description(), planner="random")
    agent = make_agent("mujoxo/mixture", env.description(), planner="mcts:3000")
    agent = make_agent("mujoban/level5-pegs", env.description(), estimator="oracle",
                       simulator=env)           # privileged: reads the simulator on purpose

Agents are built from the task's public description only; the privileged
estimators (``oracle``, ``entity-layer``) also need the simulator, given
explicitly as ``simulator``. The first name in each table is the default.

**Names.** A component is named ``NAME`` or, for the components that take a
parameter, ``NAME:ARG`` (one syntax everywhere a name is accepted:
`make_agent`, ``python -m hier_agents.run --planner/--skill/--estimator``,
``--list``, the tables below):

* ``learned:PATH`` (MuJoBan planner): a policy over options trained with
  ``python -m hier_agents.learning.train_options`` (a checkpoint file or a
  run directory), played by
  `abstract_planners.learned_options.OptionPolicyPlanner`; bare ``learned``
  is the shipped ``abstract_planners/learned/options.pt``;
* ``learned-ball:PATH``, ``learned-arm:PATH`` (skills): a checkpoint of
  ``python -m hier_agents.learning.train_skill``; bare: the shipped one
  (``skills/learned/ball_policy.pt``, ``skills/learned/arm_policy.pt``);
* ``mcts:N`` (board-game planner): N tree simulations per move (>= 1; bare:
  1000);
* ``gnugo:LEVEL`` (Go planner): GNU Go's strength, 1..10 (bare: 10).

`resolve` is the one parser of these names; the tables
(`PLANNERS`, `SKILLS`, `ESTIMATORS`: family -> `ComponentTable`) accept
``NAME:ARG`` in ``in`` and ``[]`` through it. A bad name raises `UsageError`
(a `ValueError`) naming the valid ones and the closest; `check` also loads
what a parameter names (a checkpoint) so a command can refuse it before
playing.

Families: ``mujoban`` (Sokoban states, the ball walker), ``mujoxo``
(tic-tac-toe), ``mujogo`` (Go) and ``mujoboard`` (the other OpenSpiel games,
`envs.boards.mujoboard`), all with the Jaco arm. An environment outside them
raises `ValueError` (`family`).
"""

from __future__ import annotations

import hashlib
import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Generic, Literal, NamedTuple, TypeVar, overload

from physics_planning.cli import UsageError, close_hint
from hier_agents.estimators import BoardEstimator, EntityLayerEstimator, OracleEstimator
from hier_agents.modular.agent import ModularAgent
from hier_agents.modular.families import family
from hier_agents.modular.options import T_ABS

if TYPE_CHECKING:
    from abstract_planners.base import Planner
    from hier_agents.estimators.base import Estimator
    from skills.base import Skill

__all__ = [
    "PLANNERS",
    "SKILLS",
    "ESTIMATORS",
    "ComponentTable",
    "Parameter",
    "Resolved",
    "UsageError",
    "check",
    "env_overrides",
    "estimator_name",
    "family",
    "file_hash",
    "forms",
    "is_privileged",
    "access",
    "learned_files",
    "make_agent",
    "reads_record",
    "resolve",
]

#: What a table's factories make: a `Planner`, a `Skill` or an `Estimator`.
C = TypeVar("C")
#: A component factory: ``factory(description, seed[, simulator][, arg=ARG])``.
Factory = Callable[..., C]


@dataclass(frozen=True)
class Parameter:
    """What the ``ARG`` of ``NAME:ARG`` is for one component.

    Attributes:
      metavar: how listings show it (``"PATH"``, ``"N"``, ``"LEVEL"``).
      meaning: what it is, for messages (``"tree simulations per move, an
        integer >= 1"``).
      parse: text -> value; raises ValueError when the text is not allowed.
      load: value -> None; loads what the value names (a checkpoint) without
        building the component; raises any exception when it cannot be used.
        None: nothing to load.
    """

    metavar: str
    meaning: str
    parse: Callable[[str], object]
    load: Callable[[object], object] | None = None


def _takes(parameter: Parameter):
    """Marks a factory ``factory(description, seed[, simulator], arg=DEFAULT)``
    as taking ``NAME:ARG`` (the bare name calls it with its default)."""

    def mark(factory):
        factory.parameter = parameter
        return factory

    return mark


def _int_in(low: int, high: int | None = None):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            raise ValueError(f"got {text!r}")
        return value

    return parse


def _path(text: str) -> str:
    if not text:
        raise ValueError("got an empty path")
    return text


def _load_option_policy(path):
    from abstract_planners.learned_options import load_option_policy

    load_option_policy(path)


def _load_ball_policy(path):
    from skills.learned.ball import load_policy

    load_policy(path)


def _load_arm_policy(path):
    from skills.learned.arm import FEATURES
    from skills.learned.policy import load_policy

    load_policy(path, FEATURES)


def _ball_config(text: str):
    """``KEY=VALUE[,KEY=VALUE...]`` as a `skills.ball.BallConfig` with those
    fields changed; ValueError naming the problem (an unknown field, with the
    closest one, or a value of the wrong type)."""
    from physics_planning.cli import key_values
    from skills.ball import BallConfig

    items = [item for item in text.split(",") if item]
    if not items:
        raise ValueError("got no KEY=VALUE")
    overrides = key_values(items, "ball", BallConfig.field_names())
    try:
        return BallConfig().replace(**overrides)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{text!r}: {exc}") from None


_BALL_CONFIG = Parameter(
    "KEY=VALUE,...",
    "changes to the skill's BallConfig fields, comma-separated (e.g. push_speed=2.0)",
    _ball_config,
)
_SIMULATIONS = Parameter("N", "tree simulations per move, an integer >= 1", _int_in(1))
_GNUGO_LEVEL = Parameter("LEVEL", "GNU Go's strength, an integer 1..10", _int_in(1, 10))
_DEPTH = Parameter("D", "plies searched, an integer >= 1", _int_in(1))
_OPTION_POLICY = Parameter(
    "PATH",
    "a python -m hier_agents.learning.train_options checkpoint file or run directory",
    _path,
    _load_option_policy,
)
_BALL_POLICY = Parameter(
    "PATH",
    "a learned-ball checkpoint (python -m hier_agents.learning.train_skill ball)",
    _path,
    _load_ball_policy,
)
_ARM_POLICY = Parameter(
    "PATH",
    "a learned-arm checkpoint (python -m hier_agents.learning.train_skill arm)",
    _path,
    _load_arm_policy,
)


def _sokoban_solver(description, seed):
    from abstract_planners.sokoban_solver import SokobanSolverPlanner

    return SokobanSolverPlanner(time_limit=10.0)


def _sokoban_time(description, seed):
    from abstract_planners.sokoban_time_solver import TimeSolverPlanner

    return TimeSolverPlanner(time_limit=10.0)


@_takes(_OPTION_POLICY)
def _learned_options(description, seed, arg=None):
    from abstract_planners.learned_options import OptionPolicyPlanner

    return OptionPolicyPlanner(arg, seed=seed)


def _sokoban_random(description, seed):
    from abstract_planners.sokoban_random import RandomPlanner

    return RandomPlanner(seed=seed)


def _minimax(description, seed):
    from abstract_planners.tictactoe import MinimaxPlanner

    return MinimaxPlanner(seed=seed)


def _board_random(description, seed):
    from abstract_planners.board_random import RandomMovePlanner

    return RandomMovePlanner(seed=seed)


@_takes(_GNUGO_LEVEL)
def _gnugo(description, seed, arg=10):
    from abstract_planners.go import GnuGoPlanner

    return GnuGoPlanner(arg, board_size=description.board_size, komi=description.komi, seed=seed)


@_takes(_SIMULATIONS)
def _mcts(description, seed, arg=1000):
    from abstract_planners.openspiel_bots import MCTSPlanner

    return MCTSPlanner(arg, seed=seed)


@_takes(_SIMULATIONS)
def _mcts_strong(description, seed, arg=2000):
    """MCTS for the larger boards: 2,000 simulations by default."""
    return _mcts(description, seed, arg)


@_takes(_DEPTH)
def _alphabeta(description, seed, arg=4):
    from abstract_planners.openspiel_bots import AlphaBetaPlanner

    return AlphaBetaPlanner(arg, seed=seed)


@_takes(_BALL_CONFIG)
def _ball(description, seed, arg=None):
    from skills.ball import BallSkill

    return BallSkill(arg)


@_takes(_BALL_POLICY)
def _learned_ball(description, seed, arg=None):
    from skills.learned import LearnedBallSkill

    return LearnedBallSkill(arg)


def _arm(description, seed):
    from skills.arm import ArmTouchSkill

    return ArmTouchSkill()


@_takes(_ARM_POLICY)
def _learned_arm(description, seed, arg=None):
    from skills.learned.arm import LearnedArmSkill

    return LearnedArmSkill(arg)


def _lazy_estimator(module: str, name: str):
    """A factory of the estimator class ``name`` in ``module``, imported on
    first use; its ``env_overrides()`` returns the class's `envs.load`
    overrides (the cameras it reads)."""

    def cls():
        return getattr(importlib.import_module(module), name)

    def factory(description, seed, simulator=None):
        return cls()()

    factory.env_overrides = lambda: cls().env_overrides  # type: ignore[attr-defined]
    return factory


_camera = _lazy_estimator("hier_agents.estimators.camera", "CameraEstimator")
_board_camera = _lazy_estimator("hier_agents.estimators.camera_board", "BoardCameraEstimator")


def _board(description, seed, simulator=None):
    return BoardEstimator()


_board.reads_record = True  # type: ignore[attr-defined]


def _privileged(cls):
    def factory(description, seed, simulator=None):
        if simulator is None:
            raise ValueError(
                f"the {cls.name!r} estimator is privileged (it reads the "
                f"simulator): pass the environment as simulator=env"
            )
        return cls(simulator)

    factory.privileged = True
    return factory


class Resolved(NamedTuple, Generic[C]):
    """A component name resolved by `resolve`: ``name`` (the table's key),
    ``arg`` (the parsed ``ARG``, None for a bare name), ``parameter`` (the
    component's `Parameter` or None) and ``factory`` (called as the table's
    factories are, with ``arg`` bound; it keeps the factory's attributes,
    e.g. ``privileged``)."""

    name: str
    arg: object
    parameter: Parameter | None
    factory: Factory[C]


class ComponentTable(dict[str, Factory[C]], Generic[C]):
    """One family's components of one kind: name -> factory, the first entry
    the default. ``"NAME:ARG" in table`` and ``table["NAME:ARG"]`` go through
    `resolve` (``in`` is False for a name `resolve` refuses; ``[]`` raises
    its `UsageError`, a `KeyError` is never raised for a string)."""

    def __init__(self, kind: str, fam: str, entries: dict[str, Factory[C]]):
        super().__init__(entries)
        self.kind, self.family = kind, fam

    def __contains__(self, spec) -> bool:
        try:
            self.resolve(spec)
        except UsageError:
            return False
        return True

    def __getitem__(self, spec) -> Factory[C]:
        return self.resolve(spec).factory

    def resolve(self, spec: str) -> Resolved[C]:
        """See the module function `resolve`."""
        if isinstance(spec, str) and dict.__contains__(self, spec):
            named: Factory[C] = dict.__getitem__(self, spec)
            return Resolved(spec, None, getattr(named, "parameter", None), named)
        name, sep, text = str(spec).partition(":")
        factory: Factory[C] | None = dict.get(self, name) if isinstance(spec, str) else None
        parameter = getattr(factory, "parameter", None)
        if factory is not None and parameter is not None and sep:
            try:
                arg = parameter.parse(text)
            except ValueError as exc:
                raise UsageError(
                    f"bad {self.kind} {spec!r}: {name}:{parameter.metavar} takes "
                    f"{parameter.meaning}; {exc}"
                ) from None
            return Resolved(name, arg, parameter, _bind(factory, arg))
        valid = self.forms()
        if factory is not None:
            raise UsageError(
                f"the {self.kind} {name!r} takes no parameter, got {spec!r}; "
                f"valid {self.kind}s for {self.family}: {', '.join(valid)}"
            )
        raise UsageError(
            f"unknown {self.kind} {spec!r} for {self.family}"
            f"{close_hint(spec, valid)}; "
            f"valid: {', '.join(valid)}"
        )

    def forms(self) -> list[str]:
        """Every accepted form, in table order: ``NAME`` and, for a component
        with a parameter, ``NAME:METAVAR`` after it."""
        out = []
        for name, factory in dict.items(self):
            out.append(name)
            parameter = getattr(factory, "parameter", None)
            if parameter is not None:
                out.append(f"{name}:{parameter.metavar}")
        return out


def _bind(factory: Factory[C], arg) -> Factory[C]:
    def bound(*args, **kwargs):
        return factory(*args, **kwargs, arg=arg)

    bound.__dict__.update(factory.__dict__)
    bound.__name__ = getattr(factory, "__name__", "factory")
    return bound


#: family -> name -> factory(description, seed); the first entry is the default.
PLANNERS: dict[str, ComponentTable[Planner]] = {
    "mujoban": ComponentTable(
        "planner",
        "mujoban",
        {
            "sokoban-solver:time": _sokoban_time,
            "sokoban-solver": _sokoban_solver,
            "random": _sokoban_random,
            "learned": _learned_options,
        },
    ),
    "mujoxo": ComponentTable(
        "planner", "mujoxo", {"minimax": _minimax, "mcts": _mcts, "random": _board_random}
    ),
    "mujogo": ComponentTable(
        "planner", "mujogo", {"gnugo": _gnugo, "mcts": _mcts, "random": _board_random}
    ),
    "mujoboard": ComponentTable(
        "planner",
        "mujoboard",
        {"mcts": _mcts_strong, "alphabeta": _alphabeta, "random": _board_random},
    ),
}
#: family -> name -> factory(description, seed); the first entry is the default.
SKILLS: dict[str, ComponentTable[Skill]] = {
    "mujoban": ComponentTable("skill", "mujoban", {"ball": _ball, "learned-ball": _learned_ball}),
    "mujoxo": ComponentTable("skill", "mujoxo", {"arm-touch": _arm, "learned-arm": _learned_arm}),
    "mujogo": ComponentTable("skill", "mujogo", {"arm-touch": _arm, "learned-arm": _learned_arm}),
    "mujoboard": ComponentTable("skill", "mujoboard", {"arm-touch": _arm}),
}
#: family -> name -> factory(description, seed, simulator=None).
ESTIMATORS: dict[str, ComponentTable[Estimator]] = {
    "mujoban": ComponentTable(
        "estimator",
        "mujoban",
        {
            "camera": _camera,
            "oracle": _privileged(OracleEstimator),
            "entity-layer": _privileged(EntityLayerEstimator),
        },
    ),
    "mujoxo": ComponentTable("estimator", "mujoxo", {"camera": _board_camera, "board": _board}),
    "mujogo": ComponentTable("estimator", "mujogo", {"camera": _board_camera, "board": _board}),
    "mujoboard": ComponentTable(
        "estimator", "mujoboard", {"camera": _board_camera, "board": _board}
    ),
}

#: kind -> family -> table (`resolve`'s overloads give each kind its type).
_TABLES: dict[str, dict[str, ComponentTable[Any]]] = {
    "planner": PLANNERS,
    "skill": SKILLS,
    "estimator": ESTIMATORS,
}


@overload
def resolve(kind: Literal["planner"], fam: str, spec: str | None) -> Resolved[Planner]: ...
@overload
def resolve(kind: Literal["skill"], fam: str, spec: str | None) -> Resolved[Skill]: ...
@overload
def resolve(kind: Literal["estimator"], fam: str, spec: str | None) -> Resolved[Estimator]: ...
@overload
def resolve(kind: str, fam: str, spec: str | None) -> Resolved[object]: ...
def resolve(kind: str, fam: str, spec: str | None) -> Resolved[Any]:
    """The component ``spec`` (``NAME`` or ``NAME:ARG``; None: the default)
    of ``kind`` (``"planner"``, ``"skill"``, ``"estimator"``) for family
    ``fam``. Parses ``ARG``; loads nothing (see `check`).

    Raises:
      UsageError: unknown name (the message lists the valid forms and the
        closest), a parameter given to a component without one, or an ``ARG``
        its component does not allow.
    """
    table = _TABLES[kind][fam]
    if spec is None:
        name = next(iter(table))
        return table.resolve(name)
    return table.resolve(spec)


def check(kind: str, fam: str, spec: str | None) -> Resolved[object]:
    """`resolve`, then loads what ``ARG`` names (a checkpoint), so that a
    command refuses a bad one before it plays.

    Raises:
      UsageError: as `resolve`, or ``ARG`` names something that does not load
        (missing file, not a checkpoint of this component, unreadable).
    """
    resolved = resolve(kind, fam, spec)
    parameter = resolved.parameter
    if resolved.arg is not None and parameter is not None and parameter.load is not None:
        try:
            parameter.load(resolved.arg)
        except Exception as exc:  # noqa: BLE001 - whatever a file does wrong, it is the input
            if isinstance(exc, (OSError, ValueError)):
                # (torch's unpickling advice runs to paragraphs and does not apply)
                text = str(exc).split(": Weights only load failed")[0].strip()
                text = text.splitlines()[0] if text else type(exc).__name__
            else:
                text = f"{resolved.arg} is not a usable checkpoint ({type(exc).__name__})"
            raise UsageError(f"{kind} {spec!r}: {text}") from None
    return resolved


def forms(kind: str, fam: str) -> list[str]:
    """The accepted names of ``kind`` for ``fam`` (`ComponentTable.forms`)."""
    return _TABLES[kind][fam].forms()


def is_privileged(fam: str, estimator: str | None) -> bool:
    """Whether the named estimator (None: the default) reads the simulator."""
    return bool(getattr(resolve("estimator", fam, estimator).factory, "privileged", False))


def reads_record(fam: str, estimator: str | None) -> bool:
    """Whether the named estimator (None: the default) reads a board game's
    record (``board_state``, ``move_history``), which the task declares
    privileged: the ``board`` estimators. Every other observation-only
    estimator is run with all of a task's privileged observations removed."""
    return bool(getattr(resolve("estimator", fam, estimator).factory, "reads_record", False))


def access(fam: str, estimator: str | None) -> str:
    """What the named estimator (None: the default) reads, one of
    `hier_agents.agents.base.ACCESS`: ``"simulator"`` (`is_privileged`),
    ``"record"`` (`reads_record`: the observations a board game's task
    declares privileged) or ``"observations"`` (what a robot has). Either of
    the first two makes the agent privileged wherever it is reported."""
    if is_privileged(fam, estimator):
        return "simulator"
    return "record" if reads_record(fam, estimator) else "observations"


def estimator_name(fam: str, estimator: str | None) -> str:
    """The estimator's name (the default's when None)."""
    return estimator or next(iter(ESTIMATORS[fam]))


def env_overrides(env_name: str, estimator: str | None = None) -> dict:
    """`envs.load` overrides the estimator needs: every camera off except the
    ones it reads, at the frame size it asks for."""
    import envs

    fam = family(env_name)
    overrides = dict(envs.no_cameras(env_name))
    asks = getattr(resolve("estimator", fam, estimator).factory, "env_overrides", None)
    if asks is not None:
        overrides.update(asks())
    return overrides


def make_agent(
    env_name: str,
    description,
    *,
    planner: str | None = None,
    skill: str | None = None,
    estimator: str | None = None,
    seed: int | None = None,
    t_abs: int = T_ABS,
    simulator=None,
) -> ModularAgent:
    """The modular agent for an environment named ``env_name`` with the public
    ``description`` (``env.description()``), with parts named as `resolve`
    reads them (None: the family's default).

    ``simulator`` (the environment itself) is needed only by the privileged
    estimators; nothing else receives it.

    Raises:
      ValueError: an environment outside the families, a bad name
        (`UsageError`), a privileged estimator without ``simulator``, or a
        checkpoint that does not fit its component.
      FileNotFoundError: a ``NAME:PATH`` checkpoint that does not exist.
    """
    fam = family(env_name)
    make_estimator = resolve("estimator", fam, estimator).factory
    make_planner = resolve("planner", fam, planner).factory
    make_skill = resolve("skill", fam, skill).factory
    estimator_, planner_, skill_ = (
        make_estimator(description, seed, simulator),
        make_planner(description, seed),
        make_skill(description, seed),
    )
    return ModularAgent(estimator_, planner_, skill_, t_abs=t_abs)


def file_hash(path: str | Path) -> str:
    """SHA-256 (16 hex digits) of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:16]


def learned_files(env: str, parts: dict) -> dict:
    """The checkpoint files a modular agent's learned parts load, by part
    (``{"skill": "<hash>"}``): the shipped default for a bare ``learned*``
    name, the named file or run directory's policy for ``NAME:PATH``."""
    out = {}
    for key, value in sorted(parts.items()):
        resolved = resolve(key, family(env), value)
        if not resolved.name.startswith("learned"):
            continue
        path = Path(str(resolved.arg)) if resolved.arg is not None else _shipped(key, resolved.name)
        if path.is_dir():
            found = sorted(path.glob("*_policy.pt")) or sorted(path.glob("*.pt"))
            path = found[0] if found else path
        out[key] = file_hash(path) if path.is_file() else f"missing:{path}"
    return out


def _shipped(kind: str, name: str) -> Path:
    if kind == "planner":
        from abstract_planners.learned_options import SHIPPED

        return SHIPPED
    if name == "learned-arm":
        from skills.learned.arm import POLICY_PATH

        return POLICY_PATH
    from skills.learned.ball import POLICY_PATH

    return POLICY_PATH
