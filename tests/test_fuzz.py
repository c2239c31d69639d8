"""Property-based tests (Hypothesis): bad input fails with a clear error, never a crash.

* arbitrary text to the Boxoban level reader: only `LevelError`;
* arbitrary configurations (overrides of any type) to `envs.check`, the
  validation `envs.load` runs before building anything: only `LevelError`,
  `ValueError` or `TypeError`, with a message naming the bad setting or value;
  and `envs.load` of a rejected configuration fails the same way without
  building a model;
* configurations that pass the check build, reset and step (few examples:
  each builds physics).

Example counts come from the Hypothesis profile (`tests/conftest.py`):
``HYPOTHESIS_PROFILE=ci`` runs 10,000 examples per property (the building
property: 50).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np
from hypothesis import HealthCheck, assume, event, given, note, settings
from hypothesis import strategies as st

import envs
from envs import core as core_lib
from envs.mujoban.levels import Level, LevelError, parse_levels

BOXOBAN = Path(envs.__file__).parent / "mujoban" / "data" / "boxoban"
CI = os.environ.get("HYPOTHESIS_PROFILE") == "ci"
ALLOWED = (LevelError, ValueError, TypeError)

# -- the level reader ----------------------------------------------------------

SOKOBAN_TEXT = st.text(alphabet="#@$.+* _-\n;\r\t0123456789", max_size=200)
ROWS = st.lists(st.text(alphabet="#@$.+* ", min_size=1, max_size=12), min_size=1, max_size=12)
LEVEL_TEXT = st.one_of(
    st.text(max_size=200),
    SOKOBAN_TEXT,
    ROWS.map("\n".join),
    st.lists(ROWS.map("\n".join), min_size=1, max_size=3).map(
        lambda levels: "".join(f"; {i}\n{text}\n\n" for i, text in enumerate(levels))
    ),
)


@given(LEVEL_TEXT)
def test_the_level_reader_raises_only_level_errors(text):
    for read in (parse_levels, Level.from_text):
        try:
            read(text)
        except LevelError as exc:
            assert str(exc)
        # any other exception fails the property


# -- envs.load configurations ---------------------------------------------------

NAMES = envs.names()
KEYS = sorted({key for name in NAMES for key in envs.overrides(name)} | {"bogus", "seed "})
_tmp = tempfile.mkdtemp(prefix="fuzz-levels-")
SPECIAL_STRINGS = [
    "sequential",
    "shuffle",
    "arm",
    "fingers",
    "fingertips",
    "",
    "gnugo",
    "/nonexistent/levels.txt",
    _tmp,
    str(BOXOBAN / "unfiltered-valid-000.txt"),
    "/bin/true",
]
SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.integers(-3, 20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1, 100),
    st.sampled_from(SPECIAL_STRINGS),
    st.text(max_size=8),
    st.binary(max_size=4),
    st.sampled_from([np.int64(3), np.float32(0.5), np.bool_(True), np.nan, 1e308, -0.0]),
)
VALUES = st.one_of(
    SCALARS,
    st.tuples(st.integers(-2, 5000), st.integers(-2, 5000)),
    st.lists(SCALARS, max_size=3),
    st.tuples(SCALARS, SCALARS),
    st.dictionaries(st.text(max_size=3), SCALARS, max_size=2),
    st.just(Path("/nonexistent/levels.txt")),
    st.just(object()),
)


@st.composite
def configs(draw):
    """A name, a seed and overrides: mostly the name's own settings (so values,
    not unknown keys, are what gets rejected), sometimes any key at all."""
    name = draw(st.sampled_from(NAMES))
    own = envs.overrides(name)
    keys = st.one_of(
        st.sampled_from(own), st.sampled_from(own), st.sampled_from(own), st.sampled_from(KEYS)
    )
    chosen = draw(st.lists(keys, unique=True, max_size=4))
    kwargs = {key: draw(st.one_of(VALUES, EDGES.get(key, VALUES))) for key in chosen}
    return name, draw(st.one_of(st.none(), SCALARS, st.integers())), kwargs


NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(),
    st.floats(-1e-3, 1.0),
    st.sampled_from([0, 1e-300, 1e300, -1, 0.05, 0.002]),
)
PAIRS = st.one_of(
    st.tuples(st.integers(), st.integers()),
    st.tuples(st.integers(-1, 70), st.integers(-1, 70)),
    st.lists(st.integers(0, 5000), max_size=3),
    st.tuples(NUMBERS, NUMBERS),
)
#: Values of the right type, often out of range, per setting.
EDGES = {
    **{
        key: NUMBERS
        for key in (
            "time_limit",
            "control_timestep",
            "physics_timestep",
            "pad_tolerance",
            "piece_noise",
            "komi",
            "gnugo_timeout",
            "epsilon",
        )
    },
    **{
        key: st.one_of(st.integers(), st.integers(-2, 12))
        for key in ("noslip_iterations", "level", "board_size", "difficulty")
    },
    **{
        key: PAIRS
        for key in ("grid_shape", "top_camera", "egocentric_camera", "front_camera", "render_size")
    },
    "levels": st.one_of(st.sampled_from(SPECIAL_STRINGS), st.text(max_size=20)),
    "gnugo_command": st.one_of(
        st.lists(st.text(max_size=6), max_size=3),
        st.sampled_from(["/bin/true", "", "no-such-engine --mode gtp"]),
    ),
}


CONFIGS = configs()


def _names_the_bad_value(message: str, seed, kwargs: dict) -> bool:
    if any(key.strip() in message for key in kwargs) or "seed" in message:
        return True
    values = [seed, *kwargs.values()]
    return any(text and text in message for v in values for text in (str(v), repr(v)[:40]))


@settings(suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(CONFIGS)
def test_any_configuration_is_rejected_cleanly_before_anything_is_built(config):
    name, seed, kwargs = config
    try:
        envs.check(name, seed, **kwargs)
    except ALLOWED as exc:
        event(f"rejected: {type(exc).__name__}")
        message = str(exc)
        assert _names_the_bad_value(message, seed, kwargs), message
        # envs.load fails the same way, before a model is built.
        with mock.patch.object(
            core_lib.Environment,
            "__init__",
            side_effect=AssertionError("physics built for a bad config"),
        ):
            try:
                envs.load(name, seed, **kwargs)
            except ALLOWED as again:
                assert type(again) is type(exc) and str(again) == message
            else:
                raise AssertionError(f"envs.load accepted what envs.check rejected: {message}")
    else:
        event("accepted")
        note(f"valid configuration: {name} {seed} {kwargs}")


def test_an_unknown_name_is_a_key_error_and_a_value_error():
    for bad in ("mujoban/level9", "", None, 3, ("a",)):
        try:
            envs.load(bad)
        except KeyError as exc:
            assert isinstance(exc, ValueError) and "unknown environment" in str(exc)
        else:
            raise AssertionError(bad)


PLAUSIBLE = {
    "seed": st.one_of(st.none(), st.integers(0, 2**32)),
    "time_limit": st.floats(0.05, 100),
    "control_timestep": st.sampled_from([0.05, 0.02, 0.1]),
    "physics_timestep": st.sampled_from([0.001, 0.002, 0.005, 0.01]),
    "top_camera": st.one_of(st.none(), st.tuples(st.integers(1, 64), st.integers(1, 64))),
    "egocentric_camera": st.none(),
    "front_camera": st.one_of(st.none(), st.tuples(st.integers(1, 64), st.integers(1, 64))),
    "render_size": st.tuples(st.integers(1, 128), st.integers(1, 128)),
    "pad_tolerance": st.floats(0, 0.6),
    "noslip_iterations": st.integers(-1, 10),
    "multisamples": st.integers(-1, 17),
    "grid_shape": st.tuples(st.integers(2, 14), st.integers(2, 14)),
    "piece_noise": st.one_of(st.none(), st.floats(-0.1, 1.1)),
    "level": st.integers(0, 11),
    "komi": st.floats(-10, 10),
    "arm_reset": st.booleans(),
    "sleep": st.booleans(),
    "lazy_cameras": st.booleans(),
    "randomize_appearance": st.booleans(),
    "allow_double_pass": st.booleans(),
    "registering": st.sampled_from(["arm", "fingers", "fingertips"]),
}


@st.composite
def plausible_configs(draw):
    name = draw(st.sampled_from(NAMES))
    keys = [k for k in envs.overrides(name) if k in PLAUSIBLE]
    chosen = draw(st.lists(st.sampled_from(keys), unique=True, max_size=4))
    return name, {k: draw(PLAUSIBLE[k]) for k in chosen}


@settings(max_examples=50 if CI else 8, suppress_health_check=list(HealthCheck))
@given(plausible_configs())
def test_configurations_that_pass_the_check_build_reset_and_step(config):
    name, kwargs = config
    seed = kwargs.pop("seed", None)
    try:
        envs.check(name, seed, **kwargs)
    except ALLOWED:
        assume(False)
    with envs.load(name, seed, **kwargs) as env:
        timestep = env.reset()
        assert timestep.first()
        env.step(np.zeros(env.action_spec().shape))


@given(LEVEL_TEXT)
def test_any_level_file_is_checked_without_building(text):
    with tempfile.NamedTemporaryFile(
        "w", suffix=".txt", delete=False, encoding="utf-8", errors="surrogatepass"
    ) as f:
        try:
            f.write(text)
        except UnicodeEncodeError:
            assume(False)
    try:
        envs.check("mujoban/level1", levels=f.name)
    except (LevelError, ValueError) as exc:
        assert f.name in str(exc) or "level" in str(exc), str(exc)
    finally:
        os.unlink(f.name)


def test_the_strategies_reach_valid_and_invalid_configs():
    """A sanity check of the generators: a shipped file and a default config pass."""
    envs.check("mujoban/level1", levels=str(BOXOBAN / "unfiltered-valid-000.txt"))
    envs.check("mujogo/7x7", front_camera=None, komi=7.5)
