"""Every code block of the README and of the documentation's guide pages
(`DOCUMENTS`) runs as written, or says it is an excerpt.

A block whose first line is ``# excerpt: WHY`` is documentation only (it
needs something the suite does not have, such as the original environment
built by ``../shared/peer/setup.sh``). Every other block runs:

- ``python`` blocks in a fresh interpreter, as written (slow: some train);
- ``bash`` blocks command by command, in order, in one scratch folder per
  block (slow: they play and train), with two rewrites so that they fit the
  suite: budgets shrink (`SMALL_BUDGETS`: ``--episodes 100`` plays 1 episode,
  frame budgets keep their proportions at a tenth, at most 8,000 frames) and
  output paths (``runs/...``, ``--json``/``--video``/``--picture`` files) go to
  the scratch folder. The set-up block's ``bash scripts/install.sh`` is what
  CI itself runs first (``.ci/run``), so here only the job after it runs, and the
set-up's test command is CI's own (checked against ``.ci/run``).
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from child_env import child_env

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: The pages whose code blocks run: the README, getting started and the user guide.
DOCUMENTS = [
    README,
    ROOT / "docs" / "getting-started.md",
    *sorted((ROOT / "docs" / "guide").glob("*.md")),
]
_BLOCK = re.compile(r"^( *)```(\w*)\n(.*?)^\1```", re.M | re.S)  # indented in lists too
INSTALL = "bash scripts/install.sh && "


def _tenth(limit: int | None = None):
    """Budgets keep their proportions (a warm start that is the whole budget
    stays so; a resumed run still adds PPO iterations): a tenth, at most
    `limit`."""
    return lambda value: str(min(int(value) // 10, limit or int(value)))


#: flag -> the value the suite plays instead of the README's (a function of it).
SMALL_BUDGETS = {
    "--episodes": lambda value: "1",
    "--levels": lambda value: "1" if value.isdigit() else value,  # a count, not a file
    "--eval-episodes": lambda value: "2",
    "--seeds": lambda value: "1",
    "--bc-epochs": lambda value: "2",
    "--frames": _tenth(8000),
    "--bc-frames": _tenth(),
    "--dagger-frames": _tenth(),
    "--abstract-steps": _tenth(8000),
    "--option-steps": lambda value: "128",  # one update at --envs 2, --rollout 64
    "--cpu-minutes": lambda value: "2",
}
#: flags whose value is an output file, sent to the scratch folder.
OUTPUT_FLAGS = ("--json", "--video", "--picture", "--logdir", "--cache")


def readme_blocks(path: Path = README) -> list[tuple[int, str, str]]:
    """(line number, language, body) of every fenced block of ``path``."""
    text = path.read_text()
    return [
        (text.count("\n", 0, m.start()) + 1, m.group(2), textwrap.dedent(m.group(3)))
        for m in _BLOCK.finditer(text)
    ]


def all_blocks() -> list[tuple[str, str, str]]:
    """(``FILE:LINE``, language, body) of every fenced block of `DOCUMENTS`."""
    return [
        (f"{path.relative_to(ROOT)}:{line}", lang, body)
        for path in DOCUMENTS
        for line, lang, body in readme_blocks(path)
    ]


def is_excerpt(body: str) -> bool:
    return body.lstrip().startswith("# excerpt")


def commands(body: str) -> list[str]:
    """The block's commands: continuation lines joined, comments and blank
    lines dropped."""
    joined = re.sub(r"\\\n\s*", " ", body)
    out = []
    for line in joined.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            out.append(line)
    return out


def shrink(command: str, scratch: Path) -> str:
    """`command` with `SMALL_BUDGETS` applied and its outputs in `scratch`."""
    if command.startswith(INSTALL):
        command = command[len(INSTALL) :]
    words = shlex.split(command, comments=True)
    out = []
    i = 0
    while i < len(words):
        word = words[i]
        flag, eq, value = word.partition("=")
        if word in SMALL_BUDGETS and i + 1 < len(words):
            out += [word, SMALL_BUDGETS[word](words[i + 1])]
            i += 2
            continue
        if eq and flag in SMALL_BUDGETS:
            out.append(f"{flag}={SMALL_BUDGETS[flag](value)}")
            i += 1
            continue
        if word in OUTPUT_FLAGS and i + 1 < len(words):
            out += [word, str(scratch / words[i + 1])]
            i += 2
            continue
        out.append(re.sub(r"(^|:)(runs/)", lambda m: f"{m.group(1)}{scratch}/runs/", word))
        i += 1
    return shlex.join(out)


PYTHON_BLOCKS = [
    (where, body) for where, lang, body in all_blocks() if lang == "python" and not is_excerpt(body)
]
#: The set-up's test command is what CI runs (checked by
#: `test_the_set_up_commands_are_what_ci_runs`), not a block to run inside it.
TEST_COMMAND = "python -m pytest -q"
BASH_BLOCKS = [
    (where, body)
    for where, lang, body in all_blocks()
    if lang == "bash" and not is_excerpt(body) and body.strip() != TEST_COMMAND
]


def test_every_block_is_python_bash_or_a_listing():
    for where, lang, body in all_blocks():
        assert lang in ("python", "bash", "toml", "text", ""), f"{where}: unknown language {lang!r}"
        if lang in ("", "text"):  # a listing (the layout), not code
            assert not re.search(r"^\s*(python|bash|import) ", body, re.M), (
                f"{where}: code in a block without a language"
            )


def test_toml_blocks_are_the_shipped_files_they_name():
    import tomllib

    blocks = [(where, body) for where, lang, body in all_blocks() if lang == "toml"]
    assert blocks
    for where, body in blocks:
        named = re.match(r"# excerpt: (\S+\.toml)", body.strip())
        assert named, f"{where}: a TOML block starts with '# excerpt: FILE.toml'"
        assert tomllib.loads(body) == tomllib.loads((ROOT / named.group(1)).read_text()), (
            f"{where}: differs from {named.group(1)}"
        )


def test_the_set_up_commands_are_what_ci_runs():
    bodies = [body.strip() for _, lang, body in readme_blocks() if lang == "bash"]
    assert bodies[0].startswith(INSTALL), bodies[0]
    test_command = bodies[1]
    assert test_command == TEST_COMMAND
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert "bash scripts/install.sh" in ci
    assert test_command in ci


def test_shrink_rewrites_budgets_and_outputs(tmp_path):
    got = shrink(
        "python -m hier_agents.train mujoban/level1 --frames 5000000 "
        "--logdir runs/x --json out/a.json",
        tmp_path,
    )
    assert got == (
        f"python -m hier_agents.train mujoban/level1 --frames "
        f"8000 --logdir {tmp_path}/runs/x "
        f"--json {tmp_path}/out/a.json"
    )
    got = shrink(
        "python -m hier_agents.run mujoban/level1 --agent checkpoint:runs/e --episodes=100",
        tmp_path,
    )
    assert f"checkpoint:{tmp_path}/runs/e" in got and "--episodes=1" in got
    got = shrink(
        "python -m hier_agents.learning.train_skill arm --frames 65000 "
        "--bc-frames 45000 --dagger-frames 20000",
        tmp_path,
    )
    assert got.endswith("--frames 6500 --bc-frames 4500 --dagger-frames 2000")
    assert shrink(INSTALL + "python -m hier_agents.run", tmp_path) == "python -m hier_agents.run"


@pytest.mark.slow
@pytest.mark.parametrize("where,body", PYTHON_BLOCKS, ids=[w for w, _ in PYTHON_BLOCKS])
def test_python_block_runs(where, body, tmp_path):
    result = subprocess.run(
        [sys.executable, "-c", body],
        cwd=ROOT,
        env=child_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, f"{where}:\n{result.stderr[-3000:]}"


@pytest.mark.slow
@pytest.mark.parametrize("where,body", BASH_BLOCKS, ids=[w for w, _ in BASH_BLOCKS])
def test_bash_block_runs(where, body, tmp_path):
    for command in commands(body):
        small = shrink(command, tmp_path)
        result = subprocess.run(
            small,
            shell=True,
            cwd=ROOT,
            env=child_env(),
            capture_output=True,
            text=True,
            timeout=1200,
        )
        assert result.returncode == 0, (
            f"{where}: {small}\n{result.stdout[-2000:]}\n{result.stderr[-3000:]}"
        )
