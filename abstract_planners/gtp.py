"""A small, robust client for Go engines speaking GTP (the Go Text Protocol).

`GTPClient` drives one engine subprocess (GNU Go by default: ``gnugo --mode
gtp``) over its stdin/stdout pipes::

    with GTPClient() as engine:
        engine.boardsize(7)
        engine.komi(5.5)
        engine.set_level(10)
        engine.play("b", "D4")
        vertex = engine.genmove("w")      # "C3", "pass" or "resign"

Robustness:

* **Timeout per command.** A reader thread moves the engine's output lines
  into a queue, so waiting for a reply never blocks longer than ``timeout``
  seconds. On timeout the engine process is killed and `GTPError` names the
  command and the timeout (the next command starts a fresh engine, see below).
* **Dead engine recovery.** The client records the game set-up and the game
  so far: the last ``boardsize``, ``komi``, ``level`` and ``set_random_seed``,
  and, since the last ``clear_board``/``boardsize``, every successful
  ``play``, ``genmove``/``kgs-genmove_cleanup`` result (as a ``play``),
  ``undo``, ``fixed_handicap`` and ``set_free_handicap``. When the process has
  exited or the pipe breaks (EOF, ``BrokenPipeError``) the client starts a new
  process, replays that record on it and retries the command once; if the
  retry fails too it raises `GTPError`. Other state-changing commands
  (``loadsgf``, ``gg-undo``, ...) are sent but not replayed.
* **Numeric ids.** Every command is sent with an increasing numeric id (a
  command that already starts with one keeps it); replies (``=id ...`` or
  ``?id ...``, ended by a blank line) with another id are stale and skipped,
  replies without an id are accepted.

Errors: `GTPError` (attributes ``command`` and ``reply``) for failure replies
(``? ...``), timeouts and unrecoverable engine deaths. `GnuGoNotFoundError`
when the engine executable does not exist; it subclasses both `GTPError` and
the built-in `FileNotFoundError`, so either ``except`` catches it, and its
message says how to install GNU Go (``sudo apt-get install gnugo``).
"""

from __future__ import annotations

import collections
import queue
import re
import shutil
import subprocess
import time
from typing import Sequence

from abstract_planners.gtp_process import (
    DEBIAN_GNUGO,  # noqa: F401
    GNUGO_FLAGS,  # noqa: F401 (re-exported)
    INSTALL_HINT,
    EngineDied,
    GnuGoNotFoundError,
    GTPError,
    close_quietly,
    default_gnugo_command,
    find_gnugo,
    kill_process,
    start_process,
)

__all__ = [
    "GTPError",
    "GnuGoNotFoundError",
    "GTPClient",
    "find_gnugo",
    "default_gnugo_command",
]

_ID_REPLY = re.compile(r"^([=?])(\d*)\s?(.*)$", re.DOTALL)
_ID_COMMAND = re.compile(r"^(\d+)\s+(.*)$", re.DOTALL)


# Set-up commands whose last value is replayed on a restarted engine, in this order.
_SETUP_ORDER = ("boardsize", "komi", "level", "set_random_seed")
_GENMOVE = ("genmove", "kgs-genmove_cleanup")


class GTPClient:
    """One GTP engine subprocess with per-command timeouts and crash recovery.

    Args:
      command: the engine command line (a list of strings, or a string split
        on whitespace); default ``gnugo --mode gtp --chinese-rules
        --capture-all-dead`` (see `find_gnugo`, `GNUGO_FLAGS`).
      timeout: seconds to wait for each reply (> 0). A command that times out
        kills the engine and raises `GTPError`.
      name: a label used in error messages.

    Raises:
      GnuGoNotFoundError: the executable does not exist.
      ValueError: ``timeout`` is not a positive number.

    See the module docstring for the recovery rules. Not thread-safe: use one
    client per thread.
    """

    def __init__(
        self,
        command: Sequence[str] | str | None = None,
        *,
        timeout: float = 10.0,
        name: str = "gnugo",
    ):
        self._proc: subprocess.Popen | None = None
        self._closed = True
        try:
            timeout = float(timeout)
        except (TypeError, ValueError):
            raise ValueError(
                f"timeout must be a positive number of seconds, got {timeout!r}"
            ) from None
        if not timeout > 0:
            raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
        if command is None:
            command = default_gnugo_command()
        elif isinstance(command, str):
            command = command.split()
        command = [str(part) for part in command]
        if not command:
            raise ValueError("command must name an executable, got an empty command")
        executable = shutil.which(command[0])
        if executable is None:
            raise GnuGoNotFoundError(
                f"GTP engine executable {command[0]!r} not found; for GNU Go, {INSTALL_HINT}"
            )
        command[0] = executable
        self.command: list[str] = command
        self.timeout = timeout
        self.name = name
        #: Number of engine processes started (1 + restarts).
        self.starts = 0
        self._next_id = 1
        self._setup: dict[str, str] = {}
        self._game: list[str] = []
        self._lines: queue.Queue | None = None
        self._stderr_tail: collections.deque = collections.deque(maxlen=20)
        self._closed = False
        self._start()

    # ------------------------------------------------------------------ process

    @property
    def pid(self) -> int | None:
        """The pid of the current engine process (None when closed)."""
        return None if self._proc is None else self._proc.pid

    @property
    def alive(self) -> bool:
        """Whether the current engine process is running."""
        return self._proc is not None and self._proc.poll() is None

    @property
    def moves(self) -> list[str]:
        """The recorded game commands since the last clear (replayed on restart)."""
        return list(self._game)

    def _start(self) -> None:
        self._proc, self._lines = start_process(self.command, self.name, self._stderr_tail)
        self.starts += 1

    def _kill(self) -> None:
        kill_process(self._proc)

    def _restart(self, reason: str) -> None:
        """Kills what is left of the engine, starts a new one and replays the record."""
        self._kill()
        self._start()
        replay = [self._setup[key] for key in _SETUP_ORDER if key in self._setup]
        replay += self._game
        for command in replay:
            try:
                self._exchange(command)
            except EngineDied as exc:
                raise GTPError(
                    f"{self.name} engine died again while replaying {command!r} after a "
                    f"restart ({reason}): {exc}{self._stderr_hint()}",
                    command=command,
                ) from None
            except GTPError as exc:
                raise GTPError(
                    f"{self.name} engine restarted ({reason}) but replaying the game failed "
                    f"at {command!r}: {exc}",
                    command=command,
                    reply=exc.reply,
                ) from None

    def _stderr_hint(self) -> str:
        tail = " | ".join(line for line in self._stderr_tail if line)
        return f" (engine stderr: {tail})" if tail else ""

    # ----------------------------------------------------------------- protocol

    def _exchange(self, command: str) -> str:
        """Sends one command and waits for its reply; no retry, no recording.

        Raises:
          EngineDied: the process is gone or the pipe broke.
          GTPError: a failure reply, or a timeout (the engine is then killed).
        """
        proc, lines = self._proc, self._lines
        if proc is None or proc.poll() is not None:
            code = None if proc is None else proc.returncode
            raise EngineDied(f"process exited with code {code}")
        match = _ID_COMMAND.match(command)
        if match:
            cmd_id, body = int(match.group(1)), match.group(2)
        else:
            cmd_id, body = self._next_id, command
            self._next_id += 1
        # Both set by `start_process`, which opens the engine with stdin=PIPE.
        assert lines is not None and proc.stdin is not None
        try:
            proc.stdin.write(f"{cmd_id} {body}\n".encode())
            proc.stdin.flush()
        except (BrokenPipeError, ConnectionResetError, OSError, ValueError) as exc:
            raise EngineDied(f"cannot write to the engine: {exc!r}") from None

        deadline = time.monotonic() + self.timeout
        reply_lines: list[str] | None = None
        while True:
            remaining = deadline - time.monotonic()
            try:
                line = (
                    lines.get(timeout=max(remaining, 0.0)) if remaining > 0 else lines.get_nowait()
                )
            except queue.Empty:
                self._kill()
                raise GTPError(
                    f"{self.name} engine did not answer {body!r} within {self.timeout:g} s "
                    f"(timeout); the engine was killed and will be restarted on the next command",
                    command=body,
                ) from None
            if line is None:  # EOF
                raise EngineDied(
                    f"engine closed its output (exit code {proc.poll()}){self._stderr_hint()}"
                )
            line = line.rstrip("\r\n").replace("\t", " ")
            if reply_lines is None:
                if not line.strip():
                    continue  # blank lines between replies
                if line[0] not in "=?":
                    continue  # noise before a reply (engine banners); not GTP
                reply_lines = [line]
            elif line.strip():
                reply_lines.append(line)
            else:
                head = _ID_REPLY.match(reply_lines[0])
                assert head is not None  # the line starts with "=" or "?": it matches
                status, reply_id = head.group(1), head.group(2)
                text = "\n".join([head.group(3)] + reply_lines[1:]).strip("\n")
                if reply_id and int(reply_id) != cmd_id:
                    reply_lines = None  # stale reply to an earlier command
                    continue
                if status == "?":
                    raise GTPError(
                        f"{self.name} engine rejected {body!r}: ? {text.strip()}",
                        command=body,
                        reply=text.strip(),
                    )
                return text.strip() if "\n" not in text else text.rstrip()

    def _record(self, command: str, reply: str) -> None:
        match = _ID_COMMAND.match(command)
        body = match.group(2) if match else command
        words = body.split()
        name = words[0].lower()
        if name == "boardsize":
            self._setup["boardsize"] = body
            self._game.clear()
        elif name in ("komi", "level", "set_random_seed"):
            self._setup[name] = body
        elif name == "clear_board":
            self._game.clear()
        elif name in ("play", "fixed_handicap", "set_free_handicap"):
            self._game.append(body)
        elif name == "place_free_handicap":
            self._game.append(f"set_free_handicap {reply}")
        elif name in _GENMOVE and len(words) > 1:
            if reply.strip().lower() != "resign":
                self._game.append(f"play {words[1]} {reply.strip()}")
        elif name == "undo" and self._game:
            self._game.pop()

    def send(self, command: str) -> str:
        """Sends one GTP command and returns the success reply text (after ``=``).

        Multi-line replies (``showboard``) keep their line breaks; one-line
        replies are stripped. A dead engine is restarted, the game replayed
        and the command retried once (see the module docstring).

        Raises:
          GTPError: the engine answered ``? ...`` (``reply`` holds its text),
            timed out, or died twice; also for a closed client or a command
            containing a line break.
        """
        if self._closed:
            raise GTPError(
                f"{self.name} GTP client is closed; cannot send {command!r}", command=command
            )
        if not isinstance(command, str):
            raise TypeError(f"command must be a str, got {type(command).__name__}")
        command = command.strip()
        if not command or "\n" in command or "\r" in command:
            raise GTPError(f"a GTP command is one non-empty line, got {command!r}", command=command)
        for attempt in range(2):
            try:
                if not self.alive:
                    self._restart("engine was not running")
                reply = self._exchange(command)
            except EngineDied as exc:
                if attempt == 1:
                    raise GTPError(
                        f"{self.name} engine died on {command!r} twice (restarted and "
                        f"replayed once): {exc}",
                        command=command,
                    ) from None
                self._restart(str(exc))
                continue
            self._record(command, reply)
            return reply
        raise AssertionError("unreachable")  # pragma: no cover

    # ------------------------------------------------------------ conveniences

    def boardsize(self, n: int) -> None:
        """``boardsize n`` (also clears the board and the recorded game)."""
        self.send(f"boardsize {int(n)}")

    def komi(self, k: float) -> None:
        """``komi k``."""
        self.send(f"komi {float(k):g}")

    def clear_board(self) -> None:
        """``clear_board`` (and forgets the recorded moves)."""
        self.send("clear_board")

    def play(self, color: str, vertex: str) -> None:
        """``play color vertex``; color ``b``/``w``/``black``/``white``, vertex
        e.g. ``D4`` or ``pass``."""
        self.send(f"play {_color(color)} {vertex}")

    def genmove(self, color: str, *, cleanup: bool = False) -> str:
        """Lets the engine move for ``color``; returns the vertex (``"D4"``,
        ``"pass"``, ``"resign"``).

        The move is played on the engine's board (and recorded). With
        ``cleanup=True`` uses ``kgs-genmove_cleanup`` (GNU Go: do not pass
        while dead opponent stones remain on the board; needed for area
        scoring without dead-stone removal, such as Tromp-Taylor).
        Vertex letters follow GTP (no ``I``), upper case; pass/resign lower case.
        """
        name = "kgs-genmove_cleanup" if cleanup else "genmove"
        reply = self.send(f"{name} {_color(color)}").strip()
        lower = reply.lower()
        return lower if lower in ("pass", "resign") else reply.upper()

    def set_level(self, level: int) -> None:
        """``level l`` (GNU Go's strength, 1..10 in practice)."""
        self.send(f"level {int(level)}")

    def set_random_seed(self, seed: int) -> None:
        """``set_random_seed seed`` (GNU Go extension)."""
        self.send(f"set_random_seed {int(seed)}")

    def showboard(self) -> str:
        """``showboard``: the engine's text board."""
        return self.send("showboard")

    def list_stones(self, color: str) -> list[str]:
        """``list_stones color`` (GNU Go extension): sorted vertices of that colour's stones."""
        return sorted(self.send(f"list_stones {_color(color)}").split())

    def close(self) -> None:
        """Sends ``quit``, waits briefly, kills the engine if needed. Idempotent."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        proc = self._proc
        if proc is not None and proc.poll() is None:
            assert proc.stdin is not None  # `start_process` opens it with stdin=PIPE
            try:
                proc.stdin.write(b"quit\n")
                proc.stdin.flush()
                proc.wait(timeout=min(self.timeout, 2.0))
            except (OSError, ValueError, subprocess.TimeoutExpired):
                pass
        self._kill()
        self._proc = None

    def __enter__(self) -> "GTPClient":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __del__(self):
        close_quietly(self)

    def __repr__(self) -> str:
        state = "closed" if self._closed else f"pid={self.pid}"
        return f"GTPClient({self.command!r}, timeout={self.timeout:g}, {state})"


def _color(color: str) -> str:
    text = str(color).strip().lower()
    if text in ("b", "black"):
        return "b"
    if text in ("w", "white"):
        return "w"
    raise ValueError(f"color must be 'b'/'black' or 'w'/'white', got {color!r}")
