"""The engine process under `abstract_planners.gtp.GTPClient`: finding GNU Go
(`find_gnugo`, `default_gnugo_command`), starting an engine with reader
threads on its pipes (`start_process`), killing it (`kill_process`), and the
errors `GTPError` and `GnuGoNotFoundError` (all importable from
`abstract_planners.gtp`).
"""

from __future__ import annotations

import collections
import os
import queue
import shutil
import subprocess
import threading

__all__ = [
    "GTPError",
    "GnuGoNotFoundError",
    "EngineDied",
    "find_gnugo",
    "default_gnugo_command",
    "start_process",
    "kill_process",
    "close_quietly",
    "DEBIAN_GNUGO",
    "INSTALL_HINT",
    "GNUGO_FLAGS",
]

#: Where Debian/Ubuntu's ``gnugo`` package installs the binary (not on a
#: non-login PATH on every system).
DEBIAN_GNUGO = "/usr/games/gnugo"

INSTALL_HINT = "install it with `sudo apt-get install gnugo` (Debian/Ubuntu)"


class GTPError(Exception):
    """A GTP command failed: failure reply, timeout or engine death.

    Attributes:
      command: the GTP command that failed (without the numeric id), or None.
      reply: the engine's reply text (after ``?``), or None when there was none.
    """

    def __init__(self, message: str, command: str | None = None, reply: str | None = None):
        super().__init__(message)
        self.command = command
        self.reply = reply

    def __reduce__(self):
        return (type(self), (str(self), self.command, self.reply))


class GnuGoNotFoundError(GTPError, FileNotFoundError):
    """The GTP engine executable (GNU Go by default) was not found.

    Subclasses `GTPError` and `FileNotFoundError`; the message carries the
    ``sudo apt-get install gnugo`` hint.
    """


def find_gnugo() -> str:
    """The path of the ``gnugo`` executable: ``$PATH`` first, then /usr/games.

    Raises:
      GnuGoNotFoundError: GNU Go is not installed.
    """
    path = shutil.which("gnugo")
    if path:
        return path
    if os.path.isfile(DEBIAN_GNUGO) and os.access(DEBIAN_GNUGO, os.X_OK):
        return DEBIAN_GNUGO
    raise GnuGoNotFoundError(
        f"GNU Go not found (no `gnugo` on PATH, no {DEBIAN_GNUGO}); {INSTALL_HINT}"
    )


#: GNU Go's flags as the original MuJoGo ran it: area (Chinese) scoring, which
#: agrees with the Tromp-Taylor scoring of the game, and dead stones captured
#: before the engine passes.
GNUGO_FLAGS = ("--mode", "gtp", "--chinese-rules", "--capture-all-dead")


def default_gnugo_command() -> list[str]:
    """``[<gnugo>, *GNUGO_FLAGS]`` with the executable resolved by `find_gnugo`."""
    return [find_gnugo(), *GNUGO_FLAGS]


class EngineDied(Exception):
    """The engine process exited or its pipe broke (`GTPClient` restarts it)."""


def start_process(command: list, name: str, stderr_tail: collections.deque):
    """(process, stdout line queue): ``command`` started with pipes; daemon
    threads move its stdout lines into the queue (None at EOF) and keep its
    last stderr lines in ``stderr_tail``.

    Raises:
      GnuGoNotFoundError: the executable does not exist.
      GTPError: any other failure to start it.
    """
    try:
        proc = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
    except FileNotFoundError as exc:
        raise GnuGoNotFoundError(
            f"GTP engine executable {command[0]!r} not found ({exc}); for GNU Go, {INSTALL_HINT}"
        ) from exc
    except OSError as exc:
        raise GTPError(f"cannot start {name} engine {command}: {exc}") from exc
    lines: queue.Queue = queue.Queue()
    threading.Thread(
        target=_pump_lines, args=(proc.stdout, lines), name=f"gtp-{name}-stdout", daemon=True
    ).start()
    threading.Thread(
        target=_pump_stderr, args=(proc.stderr, stderr_tail), name=f"gtp-{name}-stderr", daemon=True
    ).start()
    return proc, lines


def kill_process(proc) -> None:
    """Kills ``proc`` (a `subprocess.Popen` or None) if it runs, waits for it
    (5 s at most) and closes its stdin."""
    if proc is None:
        return
    if proc.poll() is None:
        try:
            proc.kill()
        except OSError:
            pass
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:  # pragma: no cover - unkillable process
        pass
    # stdout/stderr are closed by their reader threads at EOF (closing them
    # here could race with a blocked read).
    try:
        proc.stdin.close()
    except (OSError, ValueError):
        pass


def close_quietly(obj) -> None:
    """``obj.close()``, swallowing any exception (for finalisers)."""
    try:
        obj.close()
    except Exception:  # noqa: BLE001 - never raise from a finaliser
        pass


def _pump_lines(stream, lines: queue.Queue) -> None:
    """Reader thread: engine stdout lines into the queue, then None at EOF."""
    try:
        for raw in iter(stream.readline, b""):
            lines.put(raw.decode("utf-8", errors="replace"))
    except (OSError, ValueError):
        pass
    finally:
        lines.put(None)
        try:
            stream.close()
        except (OSError, ValueError):
            pass


def _pump_stderr(stream, tail: collections.deque) -> None:
    """Reader thread: keeps the last stderr lines (for error messages), never blocks the engine."""
    try:
        for raw in iter(stream.readline, b""):
            tail.append(raw.decode("utf-8", errors="replace").strip())
    except (OSError, ValueError):
        pass
    finally:
        try:
            stream.close()
        except (OSError, ValueError):
            pass
