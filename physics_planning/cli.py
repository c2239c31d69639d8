"""The command-line toolkit: the conventions every shipped command follows.

It imports nothing of the project, so every package (`abstract_planners`,
`envs`, `skills`, `hier_agents`) and every script may import it.

- `Parser`: an ``argparse.ArgumentParser`` whose usage line names the module
  (``python -m hier_agents.run``), whose help shows every default that is
  set, and whose errors are one line on stderr (``PROG: error: MESSAGE (see
  PROG --help)``), exit status 2, no traceback and no usage dump.
- `UsageError`: raised anywhere below a command's ``main`` for a bad input
  the user can fix; `run_main` turns it (and the input errors listed in
  `INPUT_ERRORS`) into that one line.
- Argument types that fail with the setting's name and the allowed range:
  `non_negative_int`, `positive_int`, `positive_float`, `non_negative_float`,
  `fraction`, `existing_file`; `choice` for names with a close-match hint
  (`Parser` also names the closest option of an unrecognized one);
  `output_file` creates the folder of an output path up front and fails
  before any work is done when it cannot be written.
- Environment inputs (a registered name, ``--env-option`` items, a level
  file) are checked by `envs.cli`, which builds on this module.
- `write_json`: replaces a JSON file in one step, so a reader (or a run
  stopped mid-write) never sees half a file.
- `plural`: ``plural(1, "episode")`` is ``"1 episode"``.

Unexpected exceptions (bugs) keep their traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import ast
import difflib
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Callable, Iterable, Sequence

__all__ = [
    "INPUT_ERRORS",
    "Parser",
    "UsageError",
    "atomic_write",
    "choice",
    "close_hint",
    "existing_file",
    "fail",
    "fraction",
    "non_negative_float",
    "non_negative_int",
    "output_file",
    "plural",
    "positive_float",
    "positive_int",
    "run_main",
    "write_json",
]


class UsageError(ValueError):
    """A bad input the user can fix; the message is the whole explanation."""


#: Exceptions `run_main` reports as one line (exit status 2). Input errors of
#: the packages above (an unknown environment, a malformed level file)
#: subclass `UsageError`, so this module imports none of them.
INPUT_ERRORS: tuple[type[BaseException], ...] = (
    UsageError,
    FileNotFoundError,
    IsADirectoryError,
    NotADirectoryError,
    PermissionError,
)


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the description's layout; appends ``(default: X)`` to options
    whose default is set (not None, not False, not already in the help) and
    ``(required)`` to required options."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.help is argparse.SUPPRESS:
            return text
        if action.required and action.option_strings:
            return f"{text} (required)".strip()
        default = action.default
        if (
            "%(default)" not in text
            and "default:" not in text
            and default is not None
            and default is not False
            and default is not argparse.SUPPRESS
            and default != []
            and not isinstance(action, argparse._HelpAction)
        ):
            text = f"{text} (default: %(default)s)".strip()
        return text

    def _format_action(self, action: argparse.Action) -> str:
        # argparse prints nothing after an option without help text; the
        # default and "(required)" are shown for those too.
        if action.help is None:
            text = self._get_help_string(action)
            if text:
                action = copy.copy(action)
                action.help = text
        return super()._format_action(action)


class Parser(argparse.ArgumentParser):
    """An argument parser that follows the project's conventions (module
    name in usage, defaults in help, one-line errors).

    Args:
      prog: how users start the command, e.g. ``"python -m hier_agents.run"``.
      description, epilog: as for argparse; their line breaks are kept.
    """

    def __init__(
        self, prog: str, description: str | None = None, epilog: str | None = None, **kwargs
    ):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(prog=prog, description=description, epilog=epilog, **kwargs)

    def error(self, message: str):  # noqa: D102 - argparse's contract: never returns
        prefix = "unrecognized arguments: "
        if message.startswith(prefix):  # name the closest option of each unknown one
            options = [o for o in self._option_string_actions if o.startswith("--")]
            hints = [
                close_hint(word.split("=", 1)[0], options)
                for word in message[len(prefix) :].split()
                if word.startswith("-")
            ]
            message += "".join(h for h in hints if h)
        fail(self.prog, message)


def fail(prog: str, message: str, status: int = 2):
    """Writes ``PROG: error: MESSAGE (see PROG --help)`` as one line and exits."""
    message = " ".join(str(message).split())  # one line, whatever the message held
    sys.stderr.write(f"{prog}: error: {message} (see {prog} --help)\n")
    sys.stderr.flush()
    raise SystemExit(status)


def run_main(
    prog: str, main: Callable[[Sequence[str] | None], int | None], argv: Sequence[str] | None = None
) -> int:
    """Calls ``main(argv)``; an `INPUT_ERRORS` exception becomes one line on
    stderr and exit status 2, Ctrl-C one line and status 130. Returns main's
    status (0 for None)."""
    try:
        status = main(argv)
    except INPUT_ERRORS as exc:
        if os.environ.get("PHYSICS_PLANNING_TRACEBACK"):
            raise
        text = str(exc)
        if isinstance(exc, OSError) and exc.filename is not None:
            text = f"{exc.strerror or exc}: {exc.filename}"
        fail(prog, text)
    except KeyboardInterrupt:
        sys.stderr.write(f"{prog}: interrupted\n")
        return 130
    return 0 if status is None else int(status)


def close_hint(word: str, candidates: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest candidates, or ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=2, cutoff=0.6)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""


def choice(kind: str, value: str, allowed: Iterable[str]) -> str:
    """`value` if it is in `allowed`, else `UsageError` naming the allowed
    values and the closest one."""
    allowed = list(allowed)
    if value not in allowed:
        raise UsageError(
            f"unknown {kind} {value!r}{close_hint(value, allowed)}; "
            f"valid: {', '.join(map(str, allowed))}"
        )
    return value


def key_values(items: Iterable[str], flag: str, valid: Iterable[str], scope: str = "") -> dict:
    """``KEY=VALUE`` command-line items as a dict, each VALUE a Python literal
    if it parses as one, else its text.

    Args:
      flag: the option the items came from, for messages (``--env-option``).
      valid: the keys allowed.
      scope: what the keys belong to, for messages (``" for mujoban/level1"``).

    Raises:
      UsageError: an item without ``=`` or without a key, or a key not in
        ``valid`` (the message names the closest one and the valid keys).
    """
    valid = list(valid)
    keys = f"; keys{scope}: {', '.join(valid)}"
    options = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise UsageError(f"{flag} must be KEY=VALUE, got {item!r}{keys}")
        if key not in valid:
            raise UsageError(
                f"{flag} {item!r}: unknown key {key!r}{scope}{close_hint(key, valid)}{keys}"
            )
        try:
            options[key] = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            options[key] = text
    return options


def _number(convert, test, what: str):
    def parse(text: str):
        try:
            value = convert(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not test(value):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    parse.__name__ = what  # argparse names the type in "invalid ... value"
    return parse


#: argparse types: ``type=positive_int`` etc.
non_negative_int = _number(int, lambda v: v >= 0, "an integer >= 0")
positive_int = _number(int, lambda v: v >= 1, "an integer >= 1")
positive_float = _number(float, lambda v: v > 0 and v == v and v != float("inf"), "a number > 0")
non_negative_float = _number(float, lambda v: v >= 0 and v != float("inf"), "a number >= 0")
fraction = _number(float, lambda v: 0.0 <= v <= 1.0, "a number in [0, 1]")


def add_save_at(parser: argparse.ArgumentParser, kept: str, rule: str = "") -> None:
    """Adds a trainer's ``--save-at FRAMES [FRAMES ...]`` (positive integers,
    default none): keep ``kept`` (a path with ``N``, e.g.
    ``LOGDIR/checkpoints/frames-N.pt``) exactly at each frame count; ``rule``
    says which counts the trainer accepts."""
    parser.add_argument(
        "--save-at",
        type=positive_int,
        nargs="+",
        default=[],
        metavar="FRAMES",
        help=f"also keep {kept} exactly at each of these frame counts "
        f"({rule + '; ' if rule else ''}evaluation at equal budgets)",
    )


def existing_file(text: str) -> Path:
    """argparse type: a path to a file that exists."""
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a file" if path.exists() else f"no such file: {text!r}"
        )
    return path


def output_file(path: str | os.PathLike | None, flag: str) -> Path | None:
    """Prepares an output path before any work: creates its folder and checks
    that the file can be written. None stays None.

    Raises:
      UsageError: the path is a folder, or its folder cannot be made or
        written (the message names `flag`).
    """
    if path is None:
        return None
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{flag} {str(path)!r} is a folder; give a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(
            f"{flag} {str(path)!r}: cannot create its folder ({exc.strerror})"
        ) from exc
    if not os.access(path.parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise UsageError(f"{flag} {str(path)!r}: not writable")
    return path


def atomic_write(path: str | os.PathLike, write: Callable[[str], object]) -> Path:
    """Calls ``write(tmp_path)`` on a temporary file in ``path``'s folder, then
    renames it onto ``path``: the old file stays whole until the new one is
    complete, and on any error the temporary file is removed. Returns the
    path."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def write_json(path: str | os.PathLike, data, indent: int = 2) -> Path:
    """Writes ``data`` as JSON to ``path`` atomically (`atomic_write`).
    Returns the path."""
    text = json.dumps(data, indent=indent) + "\n"
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def plural(count: int | float, noun: str, plural_form: str | None = None, spec: str = "") -> str:
    """``"1 episode"``, ``"2 episodes"``, ``"0 episodes"``; ``spec`` formats
    the count (``plural(12000, "frame", spec=",")`` is ``"12,000 frames"``)."""
    word = noun if count == 1 else (plural_form or f"{noun}s")
    return f"{count:{spec}} {word}"
