"""The environment gallery: one card per registered environment, generated from the registry.

    python docs/gallery/generate.py                        # every card, picture and animation
    python docs/gallery/generate.py --only 'mujoxo/*'      # some of them (the index too)
    python docs/gallery/generate.py --check                # cards current, pictures present
    python docs/gallery/generate.py --only mujoxo/random --no-animation --out /tmp/gallery

For every name of `envs.names()` it writes ``OUT/<slug>.md`` (``mujoban/level1``
is ``mujoban-level1``), ``OUT/img/<slug>.png`` (the main camera after reset,
seed 0, 320x240) and ``OUT/img/<slug>.webp`` (``.gif`` where Pillow has no
WebP): the default modular agent's episode 0 (`hier_agents.agents.Player`),
its first `ANIMATION_SECONDS` of simulated time at most, a frame every
`FRAME_EVERY` s shown at `ANIMATION_FPS` fps, 128 px. ``OUT/index.md`` is a
grid of the pictures by family, each linking to its card.

A card holds: the registry's description, the picture and the animation,
how to make the environment (``envs.load``, ``gymnasium.make``) and the
settings its name fixes, the observation spec (shape, dtype, privileged:
`envs.Environment.privileged_observations`), the action spec (shape,
bounds, what each component drives), control timestep and time limit (the
task's description), the reward and success rules (the task's
``reward_rule`` and ``success_rule``, so the card cannot drift from the
code) and every override with its default (the factory's signature).

The card's text is a function of the registry, the task and whether the
animation exists; it holds no timing and no result of the episode.
``--check`` builds each environment (lazy cameras: nothing is rendered) and
fails unless every card and picture exists and every card and the index
equal what the generator would write now; it also names cards of
environments no longer registered.

Errors are one line (`physics_planning.cli`): an environment registered
without a description, a picture that could not be made, an animation
whose episode could not start, an ``--only`` pattern that matches nothing.
"""

from __future__ import annotations

import fnmatch
import inspect
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

import envs
from envs.registry import _entry
from physics_planning.cli import Parser, UsageError, atomic_write, close_hint, plural, run_main

PROG = "python docs/gallery/generate.py"
#: The gallery's folder (cards, ``index.md``, ``img/``).
HERE = Path(__file__).resolve().parent
#: (height, width) of the picture.
PICTURE_SIZE = (240, 320)
#: Side (pixels) of the animation's frames (the runner's 256x256 frames, shrunk).
ANIMATION_SIZE = 128
ANIMATION_FPS = 10
#: Simulated seconds of the episode the animation shows at most.
ANIMATION_SECONDS = 12.0
#: Simulated seconds between two frames of the animation.
FRAME_EVERY = 0.3
#: How long (ms) the animation holds its last frame.
LAST_FRAME_MS = 1000
#: The families' titles in the index, in its order; other prefixes follow, as they are.
FAMILIES = {"mujoban": "MuJoBan", "mujoxo": "MuJoXO", "mujogo": "MuJoGo", "mujoboard": "MuJoBoard"}
#: Thumbnails per row of the index.
COLUMNS = 3


def slug(name: str) -> str:
    """The file stem of ``name``'s card and images: ``mujoban/level1`` -> ``mujoban-level1``."""
    return name.replace("/", "-")


def animation_format() -> str:
    """``"webp"`` where Pillow writes (animated) WebP, else ``"gif"``."""
    from PIL import features

    return "webp" if features.check("webp") else "gif"


def select(patterns: Sequence[str] | None) -> list[str]:
    """The registered names matching any of ``patterns`` (shell globs; all names for None).

    Raises:
      UsageError: a pattern matches no name (the message names the closest).
    """
    names = envs.names()
    if not patterns:
        return names
    chosen = set()
    for pattern in patterns:
        matched = fnmatch.filter(names, pattern)
        if not matched:
            raise UsageError(
                f"--only {pattern!r} matches no environment"
                f"{close_hint(pattern, names)}; known: {', '.join(names)}"
            )
        chosen.update(matched)
    return sorted(chosen)


def description_of(name: str) -> str:
    """The registry's description of ``name``; `UsageError` naming it when it has none."""
    text = envs.describe(name).strip()
    if not text:
        raise UsageError(
            f"{name}: registered without a description (give its "
            f"envs.registry.EnvEntry a description); no card written"
        )
    return text


# -- the card ---------------------------------------------------------------------------------


def _code(value) -> str:
    """``value`` as inline Markdown code (its repr; tuples and numbers as Python writes them)."""
    return f"`{value!r}`"


def _number(value: float) -> str:
    return f"{float(value):g}"


def _bounds(values, shape) -> str:
    """One number when every component shares it, else the list."""
    flat = np.broadcast_to(np.asarray(values, float), shape).ravel()
    if flat.size and np.all(flat == flat[0]):
        return _number(flat[0])
    return "[" + ", ".join(_number(v) for v in flat) + "]"


def _action_names(env, spec) -> list[str] | None:
    """What each action component drives: the description's ``action_names``,
    else the spec's comma-separated name (the arm's actuators), else None."""
    try:
        names = getattr(env.description(), "action_names", None)
    except NotImplementedError:
        names = None
    if not names and spec.name and "," in spec.name:
        names = spec.name.split(",")
    if names and len(names) == int(np.prod(spec.shape)):
        return list(names)
    return None


def _rule(env, name: str, attribute: str) -> str:
    text = getattr(env.task, attribute, None)
    if not isinstance(text, str) or not text.strip():
        raise UsageError(
            f"{name}: its task ({type(env.task).__name__}) states no {attribute} "
            f"(a class attribute or property the card reads)"
        )
    return text.strip()


def card_text(name: str, env, animation: str | None) -> str:
    """The Markdown card of ``name`` from ``env`` (built with `envs.load`,
    seed 0, defaults but for cameras' laziness and the render size, which
    change nothing shown); ``animation`` is the animation's file name in
    ``img/``, or None when there is none."""
    description = description_of(name)
    entry = _entry(name)
    stem = slug(name)
    task = env.task
    camera = task.main_camera
    lines = [
        f"# {name}",
        "",
        description,
        "",
        f"![{name}: the {camera} after reset](img/{stem}.png)",
        "",
    ]
    if animation is not None:
        steps = int(round(ANIMATION_SECONDS / env.control_timestep))
        speed = FRAME_EVERY * ANIMATION_FPS
        lines += [
            f"![The modular agent playing {name}](img/{animation})",
            "",
            f"*Picture: the `{camera}` camera after reset (seed 0), "
            f"{PICTURE_SIZE[1]}x{PICTURE_SIZE[0]}. Animation: the default modular agent, "
            f'`Player(Play("{name}", seed=0)).play(0)`, its first '
            f"{_number(ANIMATION_SECONDS)} s of play at most ({steps} control steps; the "
            f"episode is cut there for the animation only), a frame every "
            f"{_number(FRAME_EVERY)} s shown at {ANIMATION_FPS} fps "
            f"({_number(speed)}x real time), the last one held "
            f"{_number(LAST_FRAME_MS / 1000)} s.*",
            "",
        ]
    else:
        lines += [
            f"*Picture: the `{camera}` camera after reset (seed 0), "
            f"{PICTURE_SIZE[1]}x{PICTURE_SIZE[0]}.*",
            "",
        ]

    lines += [
        "## Make it",
        "",
        "```python",
        "import envs",
        "",
        f'env = envs.load("{name}", seed=0)  # a dm_env.Environment',
        "",
        "import gymnasium",
        "",
        f'gym_env = gymnasium.make("{name}")  # the same, as gymnasium',
        "```",
        "",
    ]
    if entry.kwargs:
        fixed = ", ".join(f"`{k}={v!r}`" for k, v in sorted(entry.kwargs.items()))
        lines += [
            f"The name fixes {fixed} (`{entry.factory.__module__}.{entry.factory.__name__}`).",
            "",
        ]
    else:
        lines += [f"Built by `{entry.factory.__module__}.{entry.factory.__name__}`.", ""]

    privileged = env.privileged_observations
    lines += ["## Observations", "", "| key | shape | dtype | privileged |", "|---|---|---|---|"]
    for key, spec in sorted(env.observation_spec().items()):
        lines.append(
            f"| `{key}` | {tuple(spec.shape)} | {np.dtype(spec.dtype).name} | "
            f"{'yes' if key in privileged else 'no'} |"
        )
    lines += [
        "",
        "Privileged keys are ground truth from the simulator or the referee, not "
        "sensor readings: `gymnasium.make` leaves them out of its default observation "
        '(`obs="sensors"`), and the modular agent does not see them.',
        "",
    ]

    action = env.action_spec()
    shape = tuple(action.shape)
    names = _action_names(env, action)
    bounds = (
        "bounds per component below"
        if names is not None
        else f"bounds [{_bounds(action.minimum, shape)}, {_bounds(action.maximum, shape)}]"
    )
    lines += ["## Actions", "", f"Shape {shape}, {np.dtype(action.dtype).name}, {bounds}.", ""]
    if names is not None:
        low = np.broadcast_to(np.asarray(action.minimum, float), shape).ravel()
        high = np.broadcast_to(np.asarray(action.maximum, float), shape).ravel()
        lines += ["| component | drives | min | max |", "|---|---|---|---|"]
        lines += [
            f"| {i} | `{n}` | {_number(low[i])} | {_number(high[i])} |" for i, n in enumerate(names)
        ]
        lines.append("")

    public = env.description()
    timestep = float(public.control_timestep)
    limit = int(public.time_limit_steps)
    lines += [
        "## Episode",
        "",
        f"- Control timestep: {_number(timestep)} s per `env.step`.",
        f"- Time limit: {limit} control steps ({_number(limit * timestep)} s).",
        f"- Reward: {_rule(env, name, 'reward_rule')}",
        f"- Success: {_rule(env, name, 'success_rule')}",
        "",
    ]

    params = inspect.signature(entry.factory).parameters
    lines += [
        "## Options",
        "",
        f'Overrides of `envs.load("{name}", **options)` (also keywords of '
        "`gymnasium.make`), with their defaults:",
        "",
        "| option | default |",
        "|---|---|",
    ]
    for option in envs.overrides(name):
        default = params[option].default
        shown = "required" if default is inspect.Parameter.empty else _code(default)
        lines.append(f"| `{option}` | {shown} |")
    lines += [
        "",
        "---",
        "",
        "*Generated by `python docs/gallery/generate.py`; do not edit by hand.*",
        "",
    ]
    return "\n".join(lines)


def index_text(names: Sequence[str]) -> str:
    """``index.md``: the pictures of ``names`` in a grid by family, each linking to its card."""
    groups: dict[str, list[str]] = {}
    for name in names:
        groups.setdefault(name.split("/", 1)[0], []).append(name)
    order = [f for f in FAMILIES if f in groups] + sorted(set(groups) - set(FAMILIES))
    lines = [
        "# Environment gallery",
        "",
        f"{plural(len(names), 'registered environment')} (`envs.names()`), one card each: "
        "its picture and an animation of the modular agent playing it, the observation "
        "and action specs, reward, success rule, time limit, privileged keys and every "
        "option with its default.",
        "",
    ]
    for family in order:
        members = groups[family]
        lines += [
            f"## {FAMILIES.get(family, family)}",
            "",
            "| " + " | ".join([""] * COLUMNS) + " |",
            "|" + "---|" * COLUMNS,
        ]
        for start in range(0, len(members), COLUMNS):
            row = members[start : start + COLUMNS]
            cells = [
                f"[![{n}](img/{slug(n)}.png)]({slug(n)}.md)<br>[`{n}`]({slug(n)}.md)" for n in row
            ]
            cells += [""] * (COLUMNS - len(cells))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["---", "", "*Generated by `python docs/gallery/generate.py` from the registry.*", ""]
    return "\n".join(lines)


# -- pictures and animations ------------------------------------------------------------------


def make_picture(name: str, env, path: Path) -> None:
    """Writes the main camera's frame after reset to ``path`` (PNG).

    Raises:
      UsageError: the frame could not be rendered, or shows one flat colour.
    """
    from PIL import Image

    height, width = PICTURE_SIZE
    try:
        env.reset()
        frame = env.render(env.task.main_camera, height, width)
    except Exception as exc:  # any rendering failure is this environment's
        raise UsageError(
            f"{name}: its picture could not be made ({type(exc).__name__}: {exc})"
        ) from exc
    frame = np.asarray(frame)
    if frame.shape != (height, width, 3) or frame.min() == frame.max():
        raise UsageError(
            f"{name}: its picture could not be made (the frame is "
            f"{'blank' if frame.size else 'empty'}, shape {frame.shape})"
        )
    _write(path, lambda tmp: Image.fromarray(frame).save(tmp, format="PNG", optimize=True))


class _Enough(Exception):
    """Ends the animated episode at its last frame (the runner records it as the
    episode's error; the animation needs no more)."""


class _Frames(list):
    """The runner's ``frames`` list (`hier_agents.agents.runner.play_episode`
    appends the 256x256 main-camera frame before every action): keeps every
    ``every``-th frame, shrunk, and ends the episode (`_Enough`) at the
    ``limit``-th action."""

    def __init__(self, every: int, limit: int):
        super().__init__()
        self.every, self.limit, self.seen = every, limit, 0

    def append(self, frame) -> None:
        if self.seen >= self.limit:
            raise _Enough(f"the animation's {self.limit} control steps are played")
        if self.seen % self.every == 0:
            super().append(_shrink(frame))
        self.seen += 1


def _shrink(frame):
    from PIL import Image

    return Image.fromarray(np.asarray(frame)).resize(
        (ANIMATION_SIZE, ANIMATION_SIZE), Image.Resampling.LANCZOS
    )


def make_animation(name: str, path: Path) -> str | None:
    """Plays episode 0 of the default modular agent (seed 0) on ``name`` and
    writes its frames to ``path`` (animated WebP or GIF, by suffix). Returns
    the episode's error other than the cut, if any (the animation shows the
    episode up to it).

    Raises:
      UsageError: the player could not be built or the episode gave no frame.
    """
    from hier_agents.agents import Play, Player

    try:
        player = Player(Play(name, seed=0))
    except Exception as exc:
        raise UsageError(
            f"{name}: its animation could not be made: the modular agent "
            f"could not be built ({type(exc).__name__}: {exc})"
        ) from exc
    try:
        every = max(1, int(round(FRAME_EVERY / player.env.control_timestep)))
        limit = int(round(ANIMATION_SECONDS / player.env.control_timestep))
        frames = _Frames(every, limit)
        row, _ = player.play(0, frames=frames)
        env = player.env
        list.append(frames, _shrink(env.render(env.task.main_camera, 256, 256)))
    finally:
        player.close()
    if len(frames) < 2:
        raise UsageError(
            f"{name}: its animation could not be made: the episode gave no frame "
            f"({row.get('error', 'no error')})"
        )
    durations = [1000 // ANIMATION_FPS] * (len(frames) - 1) + [LAST_FRAME_MS]

    def write(tmp: str) -> None:
        options = (
            {"format": "WEBP", "quality": 70, "method": 6}
            if path.suffix == ".webp"
            else {"format": "GIF", "optimize": True}
        )
        frames[0].save(
            tmp, save_all=True, append_images=frames[1:], duration=durations, loop=0, **options
        )

    _write(path, write)
    error = row.get("error")
    return None if error is None or error.startswith(_Enough.__name__) else error


def _write(path: Path, write) -> None:
    """`atomic_write`, the file then readable by all (as a checked-out file is)."""
    atomic_write(path, write).chmod(0o644)


def existing_animation(out: Path, name: str) -> str | None:
    """The file name of ``name``'s animation in ``out/img`` (WebP first), or None."""
    for suffix in ("webp", "gif"):
        if (out / "img" / f"{slug(name)}.{suffix}").is_file():
            return f"{slug(name)}.{suffix}"
    return None


# -- the command ------------------------------------------------------------------------------


def generate(names: Sequence[str], out: Path, animation: bool = True, log=print) -> None:
    """Writes the cards, pictures and (with ``animation``) animations of
    ``names`` into ``out``, and the index of every registered name. Without
    ``animation`` a card shows the animation already in ``out/img``, if any.

    Raises:
      UsageError: the first environment without a description, picture or
        animation (checked for every name before anything is rendered).
    """
    for name in names:
        description_of(name)
    (out / "img").mkdir(parents=True, exist_ok=True)
    for name in names:
        start = time.perf_counter()
        made = ["card", "picture"]
        env = envs.load(name, seed=0, render_size=PICTURE_SIZE)
        try:
            make_picture(name, env, out / "img" / f"{slug(name)}.png")
            if animation:
                suffix = animation_format()
                error = make_animation(name, out / "img" / f"{slug(name)}.{suffix}")
                for other in {"webp", "gif"} - {suffix}:  # no stale one of the other kind
                    (out / "img" / f"{slug(name)}.{other}").unlink(missing_ok=True)
                made.append("animation" + (f" (its episode ended with {error})" if error else ""))
            text = card_text(name, env, existing_animation(out, name))
        finally:
            env.close()
        _write(out / f"{slug(name)}.md", lambda tmp, t=text: Path(tmp).write_text(t))
        log(f"{name}: {', '.join(made)} ({time.perf_counter() - start:.1f} s)")
    _write(out / "index.md", lambda tmp: Path(tmp).write_text(index_text(envs.names())))


def check(names: Sequence[str], out: Path, every: bool = True) -> list[str]:
    """The problems of the gallery in ``out`` for ``names`` (none: it is
    current): a card or picture missing, a card or the index whose text is
    not what `generate` would write now, and (with ``every``) a card of a
    name no longer registered. Renders nothing."""
    problems = []
    for name in names:
        description_of(name)
    for name in names:
        card, picture = out / f"{slug(name)}.md", out / "img" / f"{slug(name)}.png"
        if not picture.is_file():
            problems.append(f"{name}: no picture {picture}")
        if not card.is_file():
            problems.append(f"{name}: no card {card}")
            continue
        env = envs.load(name, seed=0, lazy_cameras=True)
        try:
            expected = card_text(name, env, existing_animation(out, name))
        finally:
            env.close()
        if card.read_text() != expected:
            problems.append(f"{name}: card {card} is out of date")
    index = out / "index.md"
    if not index.is_file() or index.read_text() != index_text(envs.names()):
        problems.append(f"{index} is missing or out of date")
    if every:
        cards = {f"{slug(n)}.md" for n in envs.names()} | {"index.md"}
        problems += [
            f"{path}: a card of no registered environment"
            for path in sorted(out.glob("*.md"))
            if path.name not in cards
        ]
    return problems


def build_parser() -> Parser:
    parser = Parser(PROG, description="\n\n".join(__doc__.split("\n\n")[:2]))
    parser.add_argument(
        "--only",
        action="append",
        metavar="GLOB",
        help="only the environments matching this shell pattern (repeatable), "
        "e.g. 'mujoxo/*'; the index is always rewritten",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="render nothing; fail unless every card and picture exists and "
        "the cards and the index are what the generator writes now",
    )
    parser.add_argument(
        "--no-animation",
        action="store_true",
        help="skip the animations (the agent's episodes); a card shows the "
        "animation already there, if any",
    )
    parser.add_argument("--out", type=Path, default=HERE, help="the gallery's folder")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    names = select(args.only)
    out = args.out
    if args.check:
        problems = check(names, out, every=not args.only)
        if problems:
            shown = "; ".join(problems[:5]) + (
                f"; and {len(problems) - 5} more" if len(problems) > 5 else ""
            )
            raise UsageError(
                f"the gallery in {out} is not current "
                f"({plural(len(problems), 'problem')}): {shown}; run {PROG}"
            )
        print(f"{plural(len(names), 'card')} and the index are current in {out}")
        return 0
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {str(out)!r} is a file; give a folder")
    start = time.perf_counter()
    generate(
        names,
        out,
        animation=not args.no_animation,
        log=lambda line: print(line, file=sys.stderr, flush=True),
    )
    print(f"{plural(len(names), 'card')} written to {out} ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(PROG, main))
