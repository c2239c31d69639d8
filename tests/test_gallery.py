"""The environment gallery's generator (docs/gallery/generate.py): its failures, a card's
sections, ``--check``; and the committed gallery has a card and a picture per name.

Only cheap runs: one tic-tac-toe environment, without the animation (no episode played).
"""

import importlib.util
from pathlib import Path

import gymnasium
import pytest

import envs
from envs.boards import make_mujoxo
from envs.registry import _REGISTRY, EnvEntry, register
from physics_planning.cli import UsageError, run_main

GALLERY = Path(__file__).resolve().parent.parent / "docs" / "gallery"
CHEAP = "mujoxo/random"


def _load_generator():
    spec = importlib.util.spec_from_file_location("gallery_generate", GALLERY / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


generate = _load_generator()


@pytest.fixture
def nameless():
    """A temporarily registered environment without a description (removed after)."""
    name = "gallery-test/nameless"
    register(EnvEntry(name, make_mujoxo, {"epsilon": 1.0}))
    try:
        yield name
    finally:
        _REGISTRY.pop(name, None)
        gymnasium.envs.registration.registry.pop(name, None)


def test_an_environment_without_a_description_fails_in_one_line(nameless, tmp_path, capsys):
    with pytest.raises(UsageError, match=f"{nameless}: registered without a description"):
        generate.main(["--only", nameless, "--out", str(tmp_path), "--no-animation"])
    assert not list(tmp_path.rglob("*.md")) and not list(tmp_path.rglob("*.png"))
    with pytest.raises(SystemExit) as exit_info:
        run_main(generate.PROG, generate.main, ["--only", nameless, "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and nameless in err and "description" in err
    # --check names it too, before looking at any file.
    with pytest.raises(UsageError, match=nameless):
        generate.main(["--check", "--out", str(tmp_path)])


def test_an_unmatched_only_pattern_fails_with_the_closest_name():
    with pytest.raises(UsageError, match="matches no environment.*did you mean 'mujoxo/random'"):
        generate.select(["mujoxo/randon"])


@pytest.fixture(scope="module")
def cheap_gallery(tmp_path_factory):
    """The card and picture of `CHEAP` (no animation) in a temporary folder."""
    out = tmp_path_factory.mktemp("gallery")
    assert generate.main(["--only", CHEAP, "--out", str(out), "--no-animation"]) == 0
    return out


def test_a_card_has_every_section(cheap_gallery):
    stem = generate.slug(CHEAP)
    assert stem == "mujoxo-random"
    card = (cheap_gallery / f"{stem}.md").read_text()
    assert (cheap_gallery / "img" / f"{stem}.png").stat().st_size > 1000
    assert card.startswith(f"# {CHEAP}\n\n{envs.describe(CHEAP)}\n")
    for section in ("## Make it", "## Observations", "## Actions", "## Episode", "## Options"):
        assert f"\n{section}\n" in card
    assert f"](img/{stem}.png)" in card and ".webp)" not in card and ".gif)" not in card
    assert f'envs.load("{CHEAP}", seed=0)' in card and f'gymnasium.make("{CHEAP}")' in card
    assert "The name fixes `epsilon=1.0`" in card
    assert "| `board_state` | (3, 3, 3) | bool | yes |" in card
    assert "| `front_camera` | (84, 84, 3) | uint8 | no |" in card
    assert "| 0 | `joint_1` |" in card and "| 8 | `finger_3` |" in card
    assert "- Control timestep: 0.05 s per `env.step`." in card
    assert "- Time limit: 600 control steps (30 s)." in card
    env = envs.load(CHEAP, seed=0, lazy_cameras=True)
    try:
        assert f"- Reward: {env.task.reward_rule}" in card and "0.5 for a draw" in card
        assert f"- Success: {env.task.success_rule}" in card
    finally:
        env.close()
    for option in envs.overrides(CHEAP):
        assert f"\n| `{option}` | " in card
    assert "| `time_limit` | `30.0` |" in card
    index = (cheap_gallery / "index.md").read_text()
    assert f"[![{CHEAP}](img/{stem}.png)]({stem}.md)" in index
    assert "## MuJoBan" in index and "## MuJoXO" in index


def test_check_passes_then_names_a_missing_picture_and_a_stale_card(cheap_gallery, tmp_path):
    generate.main(["--check", "--only", CHEAP, "--out", str(cheap_gallery)])
    out = tmp_path / "copy"
    (out / "img").mkdir(parents=True)
    stem = generate.slug(CHEAP)
    for path in (f"{stem}.md", "index.md"):
        (out / path).write_text((cheap_gallery / path).read_text())
    with pytest.raises(UsageError, match=f"{CHEAP}: no picture"):
        generate.main(["--check", "--only", CHEAP, "--out", str(out)])
    (out / "img" / f"{stem}.png").write_bytes((cheap_gallery / "img" / f"{stem}.png").read_bytes())
    (out / f"{stem}.md").write_text((cheap_gallery / f"{stem}.md").read_text() + "edited\n")
    with pytest.raises(UsageError, match=f"{CHEAP}: card .* is out of date"):
        generate.main(["--check", "--only", CHEAP, "--out", str(out)])


def test_the_committed_gallery_has_a_card_and_a_picture_per_environment():
    """Files only (no environment built): ``--check`` compares their text."""
    missing = [
        name
        for name in envs.names()
        if not (GALLERY / f"{generate.slug(name)}.md").is_file()
        or not (GALLERY / "img" / f"{generate.slug(name)}.png").is_file()
    ]
    assert not missing, f"run python docs/gallery/generate.py --only NAME for {missing}"
    assert (GALLERY / "index.md").is_file()
