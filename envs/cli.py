"""Environment inputs of the command lines, checked without building anything
(`envs.check`): `environment` (a registered name, with a close-match hint),
`env_options` (``--env-option KEY=VALUE`` items, the flag added by
`add_env_option`), `checked_options` (overrides from any other source) and `levels_file`
(``--levels``: a Boxoban file that exists and parses). Each raises
`physics_planning.cli.UsageError`; the rest of the command-line conventions
live in `physics_planning.cli`.
"""

from __future__ import annotations

import os
from typing import Callable, Iterable

from physics_planning.cli import UsageError, close_hint, key_values

__all__ = ["add_env_option", "checked_options", "env_options", "environment", "levels_file"]


def environment(name: str, allowed: Iterable[str] | None = None) -> str:
    """``name`` if it is a registered environment (or one of ``allowed``),
    else `UsageError` naming the closest and listing the valid ones."""
    import envs

    allowed = list(envs.names() if allowed is None else allowed)
    if name not in allowed:
        raise UsageError(
            f"unknown environment {name!r}{close_hint(name, allowed)}; valid: {', '.join(allowed)}"
        )
    return name


def checked_options(env_name: str, options: dict, where: str) -> dict:
    """``options`` if ``env_name`` accepts them as `envs.load` overrides
    (`envs.check`, nothing built), else `UsageError` prefixed by ``where``
    (the flag or spec key they came from)."""
    import envs

    try:
        envs.check(env_name, **options)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"{where}: {exc}") from None
    return options


def add_env_option(parser, example: str = "time_limit=5", applies: str = "") -> None:
    """Adds the repeatable ``--env-option KEY=VALUE`` flag (an `envs.load`
    override; `env_options` reads its items) to an argparse ``parser``;
    ``example`` shows one item, ``applies`` says to what it applies."""
    note = f"; {applies}" if applies else ""
    parser.add_argument(
        "--env-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"an envs.load override, e.g. {example} (repeatable; VALUE is a Python "
        f"literal; sleep=False gives MuJoBan the original's physics{note})",
    )


def env_options(
    env_name: str,
    items: Iterable[str],
    flag: str = "--env-option",
    exclude: Callable[[str], bool] = lambda key: False,
) -> dict:
    """The `envs.load` overrides of ``KEY=VALUE`` items (VALUE a Python
    literal, else the text), checked by `envs.check` without building the
    environment.

    Args:
      exclude: keys the command does not let users set (e.g. cameras).

    Raises:
      UsageError: an item without ``=``, a key the environment does not have
        (with the valid keys and the closest one), or a value it refuses (its
        own message: which setting, what is allowed).
    """
    import envs

    valid = [key for key in envs.overrides(env_name) if not exclude(key)]
    options = key_values(items, flag, valid, f" for {env_name}")
    return checked_options(env_name, options, flag)


def levels_file(env_name: str, path: str | os.PathLike, flag: str = "--levels") -> str:
    """``path`` if it is a level file ``env_name`` can play (it exists and
    every level in it parses and fits), else `UsageError` naming the file and,
    for a malformed level, the level, line and column."""
    import envs

    try:
        envs.check(env_name, levels=os.fspath(path))
    except TypeError:
        raise UsageError(f"{flag} does not apply to {env_name} (it has no level files)") from None
    except ValueError as exc:
        raise UsageError(f"{flag}: {exc}") from None
    return os.fspath(path)
