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
"""

import os
import tempfile

import pytest
from hypothesis import HealthCheck, settings
from hypothesis.configuration import set_hypothesis_home_dir

import envs  # noqa: F401
from abstract_planners.gtp import GnuGoNotFoundError, find_gnugo

# Hypothesis' caches (and failure patches) go to a temporary directory, not the checkout.
set_hypothesis_home_dir(os.environ.get("HYPOTHESIS_HOME")
                        or os.path.join(tempfile.gettempdir(), "physics-planning-hypothesis"))
settings.register_profile("dev", max_examples=300, deadline=None, database=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("ci", max_examples=10_000, deadline=None, database=None,
                          suppress_health_check=[HealthCheck.too_slow])
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
