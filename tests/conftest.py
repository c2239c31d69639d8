"""Test-session set-up.

``envs`` is imported first so that it chooses the headless OpenGL backend
(``MUJOCO_GL=egl`` unless set) before any test module imports ``mujoco``,
whose rendering reads the variable once, at import.

* ``gnugo`` (fixture): the one place that decides whether GNU Go is there.
  A test that needs it takes the fixture (or ``@pytest.mark.usefixtures("gnugo")``);
  without GNU Go it is skipped, unless ``REQUIRE_GNUGO=1`` (CI), where it fails.
  Hard dependencies (mujoco, dm_control, torch, gymnasium, mink, open_spiel,
  hypothesis, ray) are imported, never skipped: a broken install fails.
* Hypothesis profiles: ``dev`` (default, a few hundred examples per property)
  and ``ci`` (10,000), chosen with ``HYPOTHESIS_PROFILE``.
* Parallel workers (pytest-xdist, ``-n auto --dist loadgroup`` in
  pyproject.toml): the tests that use Ray share the ``xdist_group`` "ray" and
  so run one after another in one worker (`RAY_TESTS`), so do the tests of a
  module-scoped fixture that trains (`TRAINING_FIXTURES`, made once), and the
  longest tests start first (`LONG_TESTS`) so that no worker is left with
  one at the end.
"""

import os
import tempfile

import pytest
from hypothesis import HealthCheck, settings
from hypothesis.configuration import set_hypothesis_home_dir

import envs  # noqa: F401
from abstract_planners.gtp import GnuGoNotFoundError, find_gnugo

# Hypothesis' caches (and failure patches) go to a temporary directory, not the checkout.
set_hypothesis_home_dir(
    os.environ.get("HYPOTHESIS_HOME")
    or os.path.join(tempfile.gettempdir(), "physics-planning-hypothesis")
)
settings.register_profile(
    "dev",
    max_examples=300,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "ci",
    max_examples=10_000,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


def _find_gnugo():
    try:
        return find_gnugo()
    except GnuGoNotFoundError:
        return None


#: The GNU Go executable, or None. Tests use the `gnugo` fixture, not this.
GNUGO = _find_gnugo()


@pytest.fixture(scope="session")
def gnugo() -> str:
    """The GNU Go executable's path; skips the test without GNU Go (fails with
    ``REQUIRE_GNUGO=1``)."""
    if GNUGO is None:
        message = "GNU Go is not installed (sudo apt-get install gnugo)"
        if os.environ.get("REQUIRE_GNUGO") == "1":
            pytest.fail(message + "; REQUIRE_GNUGO=1 demands it")
        pytest.skip(message)
    return GNUGO


#: Tests that use Ray. ``ray stop --force`` (the two-node cluster of
#: test_compare_cluster.py) ends every Ray process of the user, and
#: ``ray.init()`` without an address joins the cluster ``ray start`` made, so
#: none of them may run while another does. Node ids, or a README block's text.
RAY_TESTS = (
    "tests/test_compare_cluster.py::",
    "tests/test_train.py::test_ray_actors_feed_the_learner",
)
RAY_README_BLOCK = "--backend ray"

#: Module-scoped fixtures that train (seconds each): the tests that take one
#: share an ``xdist_group``, so the run is made once, not once per worker.
TRAINING_FIXTURES = ("tiny_run", "tiny_impala_run")

#: The longest tests of the fast suite (node-id prefixes; 15-75 s each in
#: ``python -m pytest -q -n 2 --durations=0`` on a loaded machine), longest
#: first: they start before the short ones, so that the workers finish
#: together. Other tests keep their order. (xdist_group groups start first.)
LONG_TESTS = (
    "tests/test_camera_board.py::test_mujoxo_markers_anywhere_on_their_pad",
    "tests/test_compare.py::test_a_worker_killed_mid_run_is_replaced",
    "tests/test_compare.py::test_a_modular_episode_plays_the_same_whatever",
    "tests/test_ppo.py::test_ppo_learns_the_shorter_option",
    "tests/test_train.py::test_a_state_input_run_trains_resumes_only_as_state",
    "tests/test_compare.py::test_two_workers_give_the_rows_of_one",
    "tests/test_reliability.py::test_the_soak_benchmark_samples_and_closes_everything",
    "tests/test_train.py::test_the_checkpoint_plays_through_hier_agents_run",
    "tests/test_arm_skill.py::test_mujogo_every_point_and_the_pass_register",
    "tests/test_reliability.py::test_the_same_seed_gives_the_same_rows_in_two_processes",
    "tests/test_skill_env.py::test_gymnasium_check_env",
    "tests/test_gymnasium_observations.py::test_no_default_observation_holds_a_privileged_key",
    "tests/test_boundary.py::test_every_listed_combination_plays_through_the_boundary[mujogo-",
)


def _uses_ray(item) -> bool:
    if item.nodeid.startswith(RAY_TESTS):
        return True
    callspec = getattr(item, "callspec", None)
    body = callspec.params.get("body") if callspec else None
    return (
        item.nodeid.startswith("tests/test_readme_code.py::")
        and isinstance(body, str)
        and RAY_README_BLOCK in body
    )


def _rank(item) -> int:
    for rank, prefix in enumerate(LONG_TESTS):
        if item.nodeid.startswith(prefix):
            return rank
    return len(LONG_TESTS)


def pytest_collection_modifyitems(config, items):
    for item in items:
        if _uses_ray(item):
            item.add_marker(pytest.mark.xdist_group("ray"))
        for name in TRAINING_FIXTURES:
            if name in getattr(item, "fixturenames", ()):
                item.add_marker(pytest.mark.xdist_group(f"{item.path.name}::{name}"))
    items.sort(key=_rank)  # stable: the other tests keep their order
