"""Every shipped command fails cleanly on bad input, names itself in --help,
takes ``NAME:ARG`` component parameters, and writes its results as it goes.

The error table runs each command's ``main(argv)`` in-process: a wrong,
missing or out-of-range argument must end in `SystemExit` with status 2,
exactly one line on stderr (naming what was wrong, and the closest name
where there is one), no traceback, and nothing played. One subprocess per
command family checks that the real entry point behaves the same.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest
from fast_cover import cover

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
BALL_POLICY = "skills/learned/ball_policy.pt"
QUICK = str(ROOT / "experiments" / "quick.toml")

#: Commands run as modules: name -> module.
MODULES = {
    "run": "hier_agents.run",
    "envs": "envs.__main__",
    "train": "hier_agents.train",
    "train_skill": "hier_agents.learning.train_skill",
    "train_options": "hier_agents.learning.train_options",
    "compare": "hier_agents.compare.__main__",
    "compare_migrate": "hier_agents.compare.migrate",
}


def _main_of(command: str):
    """The ``main(argv)`` of a command: a module of `MODULES` or a benchmark
    script (``bench/NAME``, loaded from ``benchmarks/NAME.py``)."""
    if command.startswith("bench/"):
        name = command.split("/", 1)[1]
        if str(BENCHMARKS) not in sys.path:
            sys.path.insert(0, str(BENCHMARKS))  # the scripts import `_common`
        module_name = f"benchmark_{name}"
        if module_name not in sys.modules:
            spec = importlib.util.spec_from_file_location(module_name, BENCHMARKS / f"{name}.py")
            module = importlib.util.module_from_spec(spec)
            sys.modules[module_name] = module
            spec.loader.exec_module(module)
        return sys.modules[module_name].main
    return importlib.import_module(MODULES[command]).main


def _prog(command: str) -> str:
    if command.startswith("bench/"):
        return f"python benchmarks/{command.split('/', 1)[1]}.py"
    return f"python -m {MODULES[command].removesuffix('.__main__')}"


# Placeholders in argv, filled per test by `_paths`.
MISSING, GARBAGE, FOLDER, LEVELS = "{missing}", "{garbage}", "{folder}", "{levels}"

GOOD_LEVEL = """; 0
##########
#        #
#  $  .  #
#        #
#   @    #
#        #
##########
"""

#: (command, argv, a piece of the one-line message). Every row must end in
#: exit status 2 before any work.
CASES = [
    # python -m hier_agents.run
    ("run", ["mujoban/levl1"], "did you mean 'mujoban/level1'"),
    ("run", ["cartpole/swingup"], "unknown environment 'cartpole/swingup'"),
    ("run", ["mujoban/level1", "--seed", "-1"], "--seed: expected an integer >= 0"),
    ("run", ["mujoban/level1", "--episodes", "0"], "--episodes: expected an integer >= 1"),
    ("run", ["mujoban/level1", "--episodes", "two"], "--episodes: expected an integer >= 1"),
    ("run", ["mujoban/level1", "--levels", MISSING], "cannot read the level file"),
    ("run", ["mujoban/level1", "--levels", GARBAGE], "unknown character"),
    ("run", ["mujoban/level1", "--levels", FOLDER], "cannot read the level file"),
    ("run", ["mujoxo/mixture", "--levels", LEVELS], "only applies to mujoban"),
    ("run", ["mujoban/level1", "--planner", "sokoban-solvr"], "did you mean 'sokoban-solver"),
    ("run", ["mujoban/level1", "--planner", "learnt"], "did you mean 'learned"),
    ("run", ["mujoxo/mixture", "--skill", "arm-tuch"], "did you mean 'arm-touch'"),
    ("run", ["mujogo/7x7", "--estimator", "bord"], "did you mean 'board'"),
    ("run", ["mujoban/level1", "--estimator", "orcale"], "did you mean 'oracle'"),
    ("run", ["mujoxo/mixture", "--planner", "mcts:abc"], "mcts:N takes tree simulations"),
    ("run", ["mujoxo/mixture", "--planner", "mcts:0"], "an integer >= 1; got '0'"),
    ("run", ["mujogo/7x7", "--planner", "gnugo:11"], "GNU Go's strength, an integer 1..10"),
    ("run", ["mujoxo/mixture", "--planner", "minimax:3"], "takes no parameter"),
    ("run", ["mujoban/level1", "--skill", "ball:push_sped=2"], "did you mean 'push_speed'"),
    ("run", ["mujoban/level1", "--skill", "ball:push_speed=fast"], "could not convert"),
    ("run", ["mujoban/level1", "--skill", "ball:"], "got no KEY=VALUE"),
    ("run", ["mujoban/level1", "--planner", "mcts:50"], "unknown planner 'mcts:50' for mujoban"),
    ("run", ["mujoban/level1", "--skill", f"learned-ball:{MISSING}"], "no skill checkpoint"),
    ("run", ["mujoban/level1", "--skill", f"learned-ball:{GARBAGE}"], "not a usable checkpoint"),
    ("run", ["mujoban/level1", "--planner", f"learned:{GARBAGE}"], "not a readable torch"),
    ("run", ["mujoxo/mixture", "--skill", f"learned-arm:{BALL_POLICY}"], "do not match"),
    ("run", ["mujoban/level1", "--env-option", "time_limt=3"], "did you mean 'time_limit'"),
    ("run", ["mujoban/level1", "--env-option", "pad_tolerance=2.0"], "pad_tolerance must be"),
    ("run", ["mujoban/level1", "--env-option", "sleep=maybe"], "sleep must be True or False"),
    ("run", ["mujoban/level1", "--env-option", "time_limit"], "must be KEY=VALUE"),
    ("run", ["mujoban/level1", "--env-option", f"levels={LEVELS}"], "--levels FILE"),
    ("run", ["mujoban/level1", "--json", FOLDER], "--json"),
    ("run", ["mujoban/level1", "--video", FOLDER], "--video"),
    ("run", ["mujoban/level1", "--json", f"{GARBAGE}/out.json"], "cannot create its folder"),
    ("run", ["mujoban/level1", "--agent", "robot"], "unknown agent 'robot'"),
    ("run", ["mujoban/level1", "--workers", "0"], "--workers"),
    ("run", ["mujoban/level1", "--first-episode", "-1"], "--first-episode"),
    (
        "run",
        ["mujoban/level1", "--ray-address", "auto", "--video", "{folder}/v.mp4"],
        "not with --ray-address",
    ),
    ("compare", [MISSING], "no such file"),
    ("compare", [GARBAGE], "not a readable TOML spec"),
    ("compare", [QUICK, "--backend", "slurm"], "unknown --backend"),
    ("compare", [QUICK, "--ray-address", "auto"], "needs --backend ray"),
    ("compare", [QUICK, "--only", "trian"], "did you mean 'train'"),
    ("compare", [QUICK, "--cpus", "0"], "--cpus"),
    ("run", ["mujoban/level1", "--agent", "random:0"], "HOLD >= 1"),
    ("run", ["mujoban/level1", "--agent", f"checkpoint:{MISSING}"], "no checkpoint"),
    ("run", ["mujoban/level1", "--agent", f"checkpoint:{GARBAGE}"], "checkpoint"),
    (
        "run",
        ["mujoban/level1", "--agent", "random", "--planner", "random"],
        "--planner applies to the agents that take it (modular)",
    ),
    (
        "run",
        ["mujoban/level1", "--agent", "random", "--env-option", "sleep=maybe"],
        "sleep must be True or False",
    ),
    (
        "run",
        ["mujoban/level1", "--stochastic"],
        "--stochastic applies to the agents that take it (checkpoint, sb3)",
    ),
    ("run", ["mujoban/level1", "--sed", "1"], "did you mean '--seed'"),
    # python -m envs
    ("envs", ["mujoban/levl1"], "did you mean 'mujoban/level1'"),
    ("envs", ["--episodes", "0"], "--episodes: expected an integer >= 1"),
    ("envs", ["--seed", "-3"], "--seed: expected an integer >= 0"),
    ("envs", ["mujoban/level1", "--env-option", "time_limit=-1"], "time_limit must be > 0"),
    ("envs", ["mujoban/level1", "--json", FOLDER], "is a folder"),
    # python -m hier_agents.train (the helpers are the other session's)
    ("train", ["mujoban/levl1", "--logdir", FOLDER], "mujoban/level1"),
    ("train", ["mujoban/level1", "--seed", "-1", "--logdir", FOLDER], "--seed"),
    ("train", ["mujoban/level1", "--frames", "0", "--logdir", FOLDER], "--frames"),
    (
        "train",
        ["mujoban/level1", "--condition", "expert-planer", "--logdir", FOLDER],
        "did you mean 'expert-planner'",
    ),
    # python -m hier_agents.learning.train_skill
    ("train_skill", ["bal", "--frames", "10", "--logdir", FOLDER], "did you mean 'ball'"),
    ("train_skill", ["ball", "--seed", "-1"], "--seed"),
    ("train_skill", ["ball"], "--frames and --logdir"),
    ("train_skill", ["ball", "--evaluate", MISSING], "no such file"),
    # python -m hier_agents.learning.train_options
    ("train_options", ["mujoban/level1", "--logdir", FOLDER], "--option-steps"),
    (
        "train_options",
        ["mujoban/level1", "--option-steps", "-5", "--logdir", FOLDER],
        "--option-steps",
    ),
    (
        "train_options",
        ["mujoban/level1", "--option-steps", "10", "--envs", "0", "--logdir", FOLDER],
        "--envs",
    ),
    # benchmarks/*.py
    ("bench/agent_table", ["--dir", MISSING], "is not a folder"),
    ("bench/arm_skill", ["--envs", "mujoban/level1"], "unknown environment 'mujoban/level1'"),
    ("bench/arm_skill", ["--episodes", "0"], "--episodes"),
    ("bench/ball_skill", ["--envs", "mujoban/levl1"], "did you mean 'mujoban/level1'"),
    ("bench/ball_skill", ["--envs", "boxoban/unfiltered-valid-00"], "did you mean"),
    ("bench/ball_skill", ["--estimator", "orcle"], "did you mean 'oracle'"),
    ("bench/ball_skill", ["--json", FOLDER], "is a folder"),
    ("bench/env_speed", ["--envs", "mujoban/levl1"], "did you mean 'mujoban/level1'"),
    ("bench/env_speed", ["--cameras", "nne"], "did you mean 'none'"),
    ("bench/env_speed", ["--steps", "0"], "--steps"),
    ("bench/env_speed", ["--physics-timestep", "-1"], "--physics-timestep"),
    (
        "bench/env_speed",
        ["--envs", "mujoban/level1", "--env-option", "noslip_iteration=0"],
        "did you mean 'noslip_iterations'",
    ),
    ("bench/agent_speed", ["--env", "mujoban/levl5"], "did you mean 'mujoban/level5'"),
    ("bench/agent_speed", ["--episodes", "0"], "--episodes"),
    ("bench/agent_speed", ["--baseline", "no-such-commit", "--episodes", "1"], "--baseline"),
    ("bench/board_looks", ["--frames", "0"], "--frames"),
    ("bench/camera_speed", [], "--baseline"),
    ("bench/camera_speed", ["--baseline", "no-such-commit"], "--baseline"),
    ("bench/board_looks", ["--picture", FOLDER], "is a folder"),
    ("bench/original_speed", ["--steps", "0"], "--steps"),
    ("bench/original_speed", [], "physics_planning_games"),
    ("bench/original_boards", [], "physics_planning_games"),
    ("bench/physics_behaviour", ["--rounds", "0"], "--rounds"),
    ("bench/physics_behaviour", ["--json", FOLDER], "is a folder"),
    ("bench/board_physics", ["--envs", "mujoban/level1"], "unknown environment 'mujoban/level1'"),
    ("bench/board_physics", ["--json", FOLDER], "is a folder"),
    ("bench/physical_limit", ["--json", FOLDER], "is a folder"),
    ("bench/physical_limit", ["--plans", MISSING], "--plans"),
    ("bench/physical_limit", ["--limit-steps", "0"], "--limit-steps"),
    ("bench/original_boards", ["--xo-games", "0"], "--xo-games"),
    ("bench/original_boards", ["--json", FOLDER], "is a folder"),
    ("bench/estimator_accuracy", ["--frames", "0"], "--frames"),
    ("bench/estimator_accuracy", ["--json", FOLDER], "is a folder"),
    ("bench/execution_time", ["--levels", GARBAGE], "unknown character"),
    ("bench/execution_time", ["--levels", MISSING], "cannot read the level file"),
    ("bench/execution_time", ["--planner", "random:3"], "takes no parameter"),
    ("bench/execution_time", ["--estimator", "orcle"], "did you mean 'oracle'"),
    ("bench/go_planners", ["--black", "mctx"], "did you mean 'mcts'"),
    ("bench/go_planners", ["--white", "gnugo:11"], "1..10"),
    ("bench/go_planners", ["--board-size", "40"], "board_size"),
    ("bench/go_planners", ["--mcts-sweep", "1,a"], "--mcts-sweep"),
    ("bench/learner_speed", ["--env", "mujoban/levl1"], "did you mean 'mujoban/level1'"),
    ("bench/learner_speed", ["--condition", "expert"], "did you mean 'expert-planner'"),
    ("bench/learner_speed", ["--backend", "rey"], "did you mean 'ray'"),
    ("bench/learner_speed", ["--train-option", "action_reepat=4"], "did you mean 'action_repeat'"),
    ("bench/learner_speed", ["--train-option", "action_repeat"], "must be KEY=VALUE"),
    ("bench/learner_speed", ["--train-option", "action_repeat=0"], "action_repeat must be >= 1"),
    ("bench/learning_curve", [FOLDER], "not a hier_agents.train run directory"),
    ("bench/learning_curve", [FOLDER, "--every-frames", "0"], "--every-frames"),
    ("bench/original_env", ["--file", GARBAGE], "unknown character"),
    ("bench/original_env", ["--levels", "0"], "--levels"),
    ("bench/readme_tables", ["--table", "agent-result"], "did you mean 'agent-results'"),
    ("bench/readme_tables", ["--readme", MISSING], "no such file"),
    ("bench/soak", ["--only", "nothing-matches-this"], "matches none"),
    ("bench/soak", ["--episodes", "0"], "--episodes"),
    ("bench/sokoban_solver", ["--levels", MISSING], "no such file"),
    ("bench/sokoban_solver", ["--levels", GARBAGE], "unknown character"),
    ("bench/sokoban_solver", ["--time-limit", "0"], "--time-limit"),
    ("bench/sokoban_solver", ["--planner", "sokoban-time"], "--planner"),
    ("bench/sokoban_solver", ["--weight", "-1"], "--weight"),
    ("bench/render_profile", ["--frames", "0"], "--frames"),
]


@pytest.fixture
def paths(tmp_path):
    """The placeholders' files: a missing path, a garbage text file, an
    existing folder and a good one-level Boxoban file."""
    garbage = tmp_path / "garbage.txt"
    garbage.write_text("not a level, not a checkpoint\n")
    levels = tmp_path / "levels.txt"
    levels.write_text(GOOD_LEVEL)
    folder = tmp_path / "folder"
    folder.mkdir()
    return {
        MISSING: str(tmp_path / "missing.txt"),
        GARBAGE: str(garbage),
        FOLDER: str(folder),
        LEVELS: str(levels),
    }


def _fill(argv, paths):
    out = []
    for arg in argv:
        for key, value in paths.items():
            arg = arg.replace(key, value)
        out.append(arg)
    return out


def _case_id(case):
    command, argv, _ = case
    return f"{command}:{' '.join(argv)}"


def _assert_one_line_error(err: str, prog: str, expected: str):
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got:\n{err}"
    assert lines[0].startswith(f"{prog}: error: "), lines[0]
    assert expected in lines[0], lines[0]


@pytest.mark.parametrize("case", CASES, ids=_case_id)
def test_bad_input_ends_in_one_line_and_status_2(case, paths, capsys):
    command, argv, expected = case
    main = _main_of(command)
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(_fill(argv, paths))
    assert exc.value.code == 2
    captured = capsys.readouterr()
    _assert_one_line_error(captured.err, _prog(command), expected.replace(MISSING, paths[MISSING]))
    assert captured.out == ""  # nothing was played or printed


#: One real entry point per command family.
SUBPROCESS_CASES = [
    (["-m", "hier_agents.run", "mujoban/levl1"], "run", "did you mean 'mujoban/level1'"),
    (["-m", "envs", "--seed", "-1"], "envs", "--seed"),
    (["-m", "hier_agents.train", "mujoban/level1", "--frames", "0"], "train", "--frames"),
    (["-m", "hier_agents.learning.train_skill", "bal"], "train_skill", "did you mean 'ball'"),
    (
        ["-m", "hier_agents.learning.train_options", "mujoban/level1"],
        "train_options",
        "--option-steps",
    ),
    (
        [str(BENCHMARKS / "go_planners.py"), "--black", "mctx"],
        "bench/go_planners",
        "did you mean 'mcts'",
    ),
]


@pytest.mark.parametrize(
    "argv, command, expected",
    cover([pytest.param(*case, id=case[1]) for case in SUBPROCESS_CASES], lambda *case: ["entry"]),
)
def test_the_real_entry_points_fail_the_same_way(argv, command, expected):
    result = subprocess.run(
        [sys.executable, *argv], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 2, result.stderr
    _assert_one_line_error(result.stderr, _prog(command), expected)


HELP_COMMANDS = [
    "run",
    "envs",
    "train",
    "train_skill",
    "train_options",
    "compare",
    "compare_migrate",
] + sorted(f"bench/{p.stem}" for p in BENCHMARKS.glob("[a-z]*.py"))


@pytest.mark.parametrize("command", HELP_COMMANDS)
def test_help_names_the_command_as_users_start_it_and_shows_defaults(command, capsys):
    main = _main_of(command)
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: {_prog(command)} "), out.splitlines()[0]
    assert "(default: " in " ".join(out.split()), out  # (help lines wrap anywhere)


def test_list_shows_the_parameterised_forms(capsys):
    from hier_agents import run as run_lib

    assert run_lib.main(["--list"]) == 0
    out = capsys.readouterr().out
    for form in (
        "learned:PATH",
        "learned-ball:PATH",
        "learned-arm:PATH",
        "mcts:N",
        "gnugo:LEVEL",
        "oracle (privileged: the simulator)",
    ):
        assert form in out, form
    # Every board family's record estimator is marked; the camera one is not.
    families = out.split("\nmujoxo:")[1]
    assert families.count("board (privileged: the referee's record)") == 3
    assert "camera (privileged" not in out


def test_one_parser_reads_component_names_everywhere():
    from hier_agents.modular.components import PLANNERS, SKILLS, UsageError, check, resolve

    assert resolve("planner", "mujoxo", "mcts:50")[:2] == ("mcts", 50)
    assert resolve("planner", "mujoxo", None).name == "minimax"  # the default
    assert resolve("skill", "mujoban", f"learned-ball:{BALL_POLICY}")[:2] == (
        "learned-ball",
        BALL_POLICY,
    )
    assert "mcts:50" in PLANNERS["mujogo"] and "mcts:x" not in PLANNERS["mujogo"]
    assert f"learned-arm:{BALL_POLICY}" in SKILLS["mujoxo"]  # `in` parses, loads nothing
    with pytest.raises(UsageError, match="do not match"):
        check("skill", "mujoxo", f"learned-arm:{BALL_POLICY}")  # check loads the checkpoint
    with pytest.raises(ValueError, match="valid: minimax, mcts, mcts:N, random"):
        PLANNERS["mujoxo"]["nope"]


def test_mcts_takes_its_simulation_count_by_name(tmp_path):
    import envs
    from hier_agents.modular.components import make_agent
    from hier_agents import run as run_lib

    env = envs.load("mujoxo/mixture", **envs.no_cameras("mujoxo/mixture"))
    try:
        agent = make_agent("mujoxo/mixture", env.description(), planner="mcts:50", seed=0)
        assert agent.planner.simulations == 50
        agent.close()
    finally:
        env.close()
    out = tmp_path / "xo.json"
    assert (
        run_lib.main(
            [
                "mujoxo/mixture",
                "--planner",
                "mcts:50",
                "--episodes",
                "1",
                "--env-option",
                "time_limit=2",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    assert summary["planner"] == "mcts:50" and summary["episodes"] == 1
    assert summary["finished"] is True


def test_a_learned_skill_takes_a_checkpoint_path(tmp_path, capsys):
    from hier_agents import run as run_lib

    out = tmp_path / "ball.json"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--skill",
                f"learned-ball:{BALL_POLICY}",
                "--estimator",
                "oracle",
                "--episodes",
                "1",
                "--env-option",
                "time_limit=2",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    assert summary["skill"] == f"learned-ball:{BALL_POLICY}"
    assert summary["training_frames"] > 0  # the checkpoint's, read from the file given
    printed = capsys.readouterr().out
    assert "1 episode," in printed and "1 episodes" not in printed


def test_a_learned_skill_takes_a_training_run_directory(tmp_path):
    import shutil
    from skills.learned.ball import load_policy

    run_dir = tmp_path / "runs" / "ball"
    run_dir.mkdir(parents=True)
    with pytest.raises(FileNotFoundError, match="no \\*_policy.pt"):
        load_policy(run_dir)
    shutil.copy(BALL_POLICY, run_dir / "ball_policy.pt")  # what train_skill writes
    assert load_policy(run_dir).layers[0][0].shape == load_policy(BALL_POLICY).layers[0][0].shape
    shutil.copy(BALL_POLICY, run_dir / "arm_policy.pt")
    with pytest.raises(ValueError, match="several skill checkpoints"):
        load_policy(run_dir)


def test_outputs_go_into_new_folders_and_the_json_is_written_after_every_episode(
    tmp_path, monkeypatch
):
    from hier_agents import run as run_lib

    out = tmp_path / "new" / "deeper" / "run.json"
    video = tmp_path / "other" / "first.mp4"
    seen = []
    from hier_agents.agents import runner

    play = runner.play_episode

    def watched(env, view, agent, description, episode, *rest):
        seen.append((episode, json.loads(out.read_text())))  # the file before this episode
        return play(env, view, agent, description, episode, *rest)

    monkeypatch.setattr(runner, "play_episode", watched)
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--episodes",
                "2",
                "--estimator",
                "oracle",
                "--env-option",
                "time_limit=1",
                "--json",
                str(out),
                "--video",
                str(video),
            ]
        )
        == 0
    )
    (first, before_first), (second, before_second) = seen
    assert (first, before_first["episodes"], before_first["finished"]) == (0, 0, False)
    assert (second, before_second["episodes"], before_second["finished"]) == (1, 1, False)
    assert before_second["rows"][0]["episode"] == 0
    assert video.stat().st_size > 0  # written when the first episode ended
    final = json.loads(out.read_text())
    assert final["episodes"] == 2 and final["finished"] is True
    assert final["episodes_requested"] == 2 and final["env_options"] == {"time_limit": 1}
    assert {"command", "commit"} <= set(final["provenance"])


def test_an_interrupted_run_keeps_the_episodes_it_played(tmp_path, monkeypatch, capsys):
    from hier_agents import run as run_lib

    out = tmp_path / "run.json"
    from hier_agents.agents import runner

    play = runner.play_episode

    def interrupted(env, view, agent, description, episode, *rest):
        if episode == 1:
            raise KeyboardInterrupt
        return play(env, view, agent, description, episode, *rest)

    monkeypatch.setattr(runner, "play_episode", interrupted)
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--episodes",
                "3",
                "--estimator",
                "oracle",
                "--env-option",
                "time_limit=1",
                "--json",
                str(out),
            ]
        )
        == 130
    )
    summary = json.loads(out.read_text())
    assert summary["episodes"] == 1 and summary["interrupted"] is True
    assert "1 of 3 episodes played" in capsys.readouterr().out


def test_plurals_in_the_table():
    from hier_agents.run_report import format_table

    summary = {
        "env": "mujoban/level1",
        "agent": "random:1",
        "episodes": 1,
        "seed": 0,
        "condition": "uniform random actions, held 1 step",
        "success_rate": 0.0,
        "success_interval": (0.0, 0.9),
        "mean_return": 0.0,
        "mean_steps": 3.0,
        "subgoal_success_rate": None,
        "errors": 1,
        "wall_s": 0.1,
        "rows": [{"error": "RuntimeError: x"}],
    }
    table = format_table(summary)
    assert "1 episode," in table and "1 episode ended by an error" in table
    assert "1 episodes" not in table


def test_a_checkpoint_agent_takes_levels_and_env_options(tmp_path, paths, capsys):
    from hier_agents import run as run_lib
    from hier_agents.baselines.impala.learner import TrainConfig, train

    train(
        TrainConfig(
            env="mujoban/level1",
            condition="vanilla",
            steps=10,
            logdir=str(tmp_path / "run"),
            unroll_length=5,
            batch_size=2,
            actors=1,
            envs_per_actor=2,
            cameras=False,
            checkpoint_every_s=1e9,
            log_every_s=0.0,
            progress=False,
        )
    )
    out = tmp_path / "eval" / "checkpoint.json"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--agent",
                f"checkpoint:{tmp_path / 'run'}",
                "--levels",
                paths[LEVELS],
                "--env-option",
                "time_limit=1",
                "--episodes",
                "1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    assert summary["levels"] == paths[LEVELS] and summary["env_options"] == {"time_limit": 1}
    assert summary["rows"][0]["steps"] <= 20  # the 1 s limit at 20 control steps/s
    assert summary["privileged"] is False and summary["observations"]
    assert summary["finished"] is True
    table = capsys.readouterr().out
    assert "levels from" in table and "reads " in table


def test_random_and_checkpoint_agents_report_after_every_episode():
    # The same hook serves every agent: once built, then after every episode.
    from hier_agents import run as run_lib

    seen = []
    summary = run_lib.run(
        "mujoban/level1", 2, 0, agent="random:10", progress=False, on_progress=seen.append
    )
    assert [(s["episodes"], s["finished"]) for s in seen] == [(0, False), (1, False), (2, False)]
    assert seen[1]["rows"][0]["episode"] == 0
    assert summary["finished"] is True and summary["episodes"] == 2
