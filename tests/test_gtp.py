"""The GTP client: reply parsing, errors, timeouts, crash recovery (GNU Go and fake engines)."""

from __future__ import annotations

import os
import pickle
import signal
import sys
import textwrap

import pytest

from abstract_planners import gtp
from abstract_planners.gtp import GnuGoNotFoundError, GTPClient, GTPError

needs_gnugo = pytest.mark.usefixtures("gnugo")  # conftest decides whether GNU Go is there

# A scripted GTP engine: answers by command name, echoing the numeric id.
FAKE_ENGINE = textwrap.dedent(r"""
    import sys
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        cid, name = (words[0], words[1]) if words[0].isdigit() else ("", words[0])
        out = {
            "name": f"={cid} Fake Engine\n\n",
            "multi": f"={cid}\nline one\nline two\n\n",
            "noid": "= plain\n\n",
            "stale": f"=999 old\n\n={cid} fresh\n\n",
            "crlf": f"={cid} windows\r\n\r\n",
            "banner": f"hello there\n={cid} after noise\n\n",
            "quit": f"={cid}\n\n",
        }.get(name, f"?{cid} unknown command\n\n")
        sys.stdout.write(out)
        sys.stdout.flush()
        if name == "quit":
            break
""")


@pytest.fixture()
def fake(tmp_path):
    script = tmp_path / "fake_engine.py"
    script.write_text(FAKE_ENGINE)
    with GTPClient([sys.executable, str(script)], timeout=10, name="fake") as client:
        yield client


def script_engine(tmp_path, body: str) -> list[str]:
    script = tmp_path / "engine.py"
    script.write_text(textwrap.dedent(body))
    return [sys.executable, str(script)]


# -- parsing -----------------------------------------------------------------------


def test_reply_parsing(fake):
    assert fake.send("name") == "Fake Engine"
    assert fake.send("multi") == "line one\nline two"
    assert fake.send("noid") == "plain"
    assert fake.send("stale") == "fresh"
    assert fake.send("crlf") == "windows"
    assert fake.send("banner") == "after noise"
    assert fake.send("77 name") == "Fake Engine"  # the caller's own id
    with pytest.raises(GTPError) as info:
        fake.send("frobnicate 3")
    assert info.value.command == "frobnicate 3"
    assert info.value.reply == "unknown command"
    assert "frobnicate 3" in str(info.value) and "unknown command" in str(info.value)
    assert fake.send("name") == "Fake Engine"  # still in sync
    assert fake.starts == 1


def test_bad_commands_and_closed_client(fake):
    with pytest.raises(GTPError, match="one non-empty line"):
        fake.send("name\nname")
    with pytest.raises(ValueError, match="color"):
        fake.play("red", "A1")
    fake.close()
    fake.close()  # idempotent
    assert not fake.alive
    with pytest.raises(GTPError, match="closed"):
        fake.send("name")


def test_gtp_error_pickles():
    error = pickle.loads(pickle.dumps(GTPError("boom", command="genmove b", reply="nope")))
    assert (str(error), error.command, error.reply) == ("boom", "genmove b", "nope")


# -- timeouts, deaths, missing engines ----------------------------------------------


def test_silent_engine_times_out_and_is_killed(tmp_path):
    command = script_engine(
        tmp_path,
        """
        import sys
        for line in sys.stdin:
            pass
    """,
    )
    client = GTPClient(command, timeout=0.5, name="silent")
    with pytest.raises(GTPError, match=r"genmove b.*0\.5 s") as info:
        client.send("genmove b")
    assert info.value.command == "genmove b"
    assert not client.alive
    client.close()


def test_engine_that_never_reads_times_out():
    client = GTPClient(["sleep", "1000"], timeout=0.5)
    with pytest.raises(GTPError, match="timeout"):
        client.send("name")
    client.close()
    assert client.pid is None


def test_engine_dying_on_every_command_raises_after_one_retry(tmp_path):
    command = script_engine(
        tmp_path,
        """
        import sys
        sys.stdin.readline()
        sys.exit(3)
    """,
    )
    with GTPClient(command, timeout=5) as client:
        with pytest.raises(GTPError, match="died") as info:
            client.send("name")
        assert info.value.command == "name"
        assert client.starts == 2  # the first process and one restart


def test_missing_executable_gives_the_install_hint(monkeypatch):
    with pytest.raises(GnuGoNotFoundError, match="sudo apt-get install gnugo") as info:
        GTPClient(["/nonexistent/gnugo", "--mode", "gtp"])
    assert isinstance(info.value, FileNotFoundError) and isinstance(info.value, GTPError)
    monkeypatch.setattr(gtp.shutil, "which", lambda name: None)
    monkeypatch.setattr(gtp, "DEBIAN_GNUGO", "/nonexistent/usr/games/gnugo")
    with pytest.raises(FileNotFoundError, match="sudo apt-get install gnugo"):
        GTPClient()


# -- GNU Go ------------------------------------------------------------------------

OPENING = [("b", "D4"), ("w", "C3"), ("b", "C4"), ("w", "D3"), ("b", "E3")]


def start_game(client):
    client.boardsize(7)
    client.komi(5.5)
    client.set_level(1)
    client.set_random_seed(5)
    client.clear_board()
    for color, vertex in OPENING:
        client.play(color, vertex)


@needs_gnugo
def test_gnugo_basics():
    with GTPClient(timeout=30) as client:
        assert client.send("name") == "GNU Go"
        assert client.send("protocol_version") == "2"
        start_game(client)
        assert client.list_stones("black") == ["C4", "D4", "E3"]
        assert client.list_stones("w") == ["C3", "D3"]
        board = client.showboard()
        assert board.splitlines()[0].split() == list("ABCDEFG")
        with pytest.raises(GTPError) as info:
            client.send("no_such_command")
        assert info.value.command == "no_such_command" and info.value.reply == "unknown command"
        with pytest.raises(GTPError, match="illegal move") as info:
            client.play("w", "D4")  # occupied
        assert info.value.command == "play w D4"
        vertex = client.genmove("w")
        assert vertex == "pass" or vertex[0] in "ABCDEFG"
        assert client.moves[-1] == f"play w {vertex}"
        client.send("undo")
        assert client.moves == [f"play {c} {v}" for c, v in OPENING]
        pid = client.pid
    assert client.pid is None
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


@needs_gnugo
def test_gnugo_killed_mid_game_is_restarted_with_the_same_position():
    with GTPClient(timeout=30) as killed, GTPClient(timeout=30) as reference:
        for client in (killed, reference):
            start_game(client)
        before = (killed.list_stones("b"), killed.list_stones("w"), killed.showboard())
        old_pid = killed.pid
        os.kill(old_pid, signal.SIGKILL)
        after_kill = killed.genmove("w")  # restarts, replays, retries
        assert killed.pid != old_pid and killed.starts == 2
        assert after_kill == reference.genmove("w")
        for client in (killed, reference):
            client.send("undo")
        assert (killed.list_stones("b"), killed.list_stones("w"), killed.showboard()) == before
        # and once more with the process gone before the command is written
        os.kill(killed.pid, signal.SIGKILL)
        killed._proc.wait()
        assert killed.showboard() == before[2]
        assert killed.starts == 3
