"""One run-directory convention for every trainer.

A run directory holds:

* ``config.json``: the run's configuration (JSON) and ``trainer`` (the
  command that made the run), written at start; on resume the saved one is
  checked (the same trainer, keys that must not change) and merged (the new
  values win), then rewritten; `RunDir.record` adds facts learnt later (what
  the agent observes);
* ``checkpoint.pt``: the latest checkpoint, written atomically (a temporary
  file in the same directory, then ``os.replace``): the trainer's payload
  plus ``config`` and ``rng`` (torch, numpy and python ``random`` states),
  loadable with ``torch.load(weights_only=True)`` when the payload is;
  ``checkpoints/NAME.pt``: copies kept on request (learning curves), which
  may leave out what only resuming needs (`RunDir.save`'s ``keep_without``);
* ``scalars.jsonl``: one JSON object per log call (``{"step": S, ...}``),
  and the same scalars as TensorBoard events (``torch.utils.tensorboard``).

Whether a run starts or continues is the trainer's ``resume`` mode: ``None``
continues a run found there and starts one otherwise, ``True`` requires one
to continue, ``False`` requires a directory without a checkpoint (nothing is
overwritten). Every refusal is a `physics_planning.cli.UsageError` (one line on a
command's stderr), raised before anything is written.

`RunDir` also draws a progress bar on stderr (tqdm when installed) and, inside
``with run.interruptible():``, turns SIGINT/SIGTERM into ``run.stop_requested``
so that the trainer finishes its update, saves and stops (a second SIGINT
raises ``KeyboardInterrupt``); the previous handlers come back on exit.
"""

from __future__ import annotations

import contextlib
import json
import math
import random
import shutil
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import torch

from physics_planning.cli import UsageError, atomic_write

CONFIG = "config.json"
CHECKPOINT = "checkpoint.pt"
SCALARS = "scalars.jsonl"
KEPT = "checkpoints"


# -- files and random states -----------------------------------------------------------------


def atomic_save(obj, path: str | Path) -> None:
    """``torch.save(obj)`` to ``path`` atomically (no partial file, ever)."""
    atomic_write(Path(path), lambda tmp: torch.save(obj, tmp))


def atomic_write_text(text: str, path: str | Path) -> None:
    """Writes ``text`` to ``path`` atomically."""
    atomic_write(Path(path), lambda tmp: Path(tmp).write_text(text))


def rng_state() -> dict:
    """torch, numpy (global) and python ``random`` states, as tensors and
    python primitives (loadable with ``weights_only=True``)."""
    legacy = np.random.get_state()
    assert isinstance(legacy, tuple)  # the global generator is a legacy MT19937
    _, keys, pos, has_gauss, cached = legacy
    version, internal, gauss = random.getstate()
    return {
        "torch": torch.get_rng_state(),
        "numpy": {
            "keys": torch.as_tensor(keys.astype(np.int64)),
            "pos": int(pos),
            "has_gauss": int(has_gauss),
            "cached": float(cached),
        },
        "python": [version, list(internal), gauss],
    }


def set_rng_state(state: dict) -> None:
    """Restores what `rng_state` returned."""
    torch.set_rng_state(state["torch"])
    n = state["numpy"]
    np.random.set_state(
        ("MT19937", n["keys"].numpy().astype(np.uint32), n["pos"], n["has_gauss"], n["cached"])
    )
    version, internal, gauss = state["python"]
    random.setstate((version, tuple(internal), gauss))


def seed_everything(seed: int) -> None:
    """Seeds torch, numpy's global RNG and python ``random`` with ``seed``."""
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def jsonable(config: dict) -> dict:
    """``config`` with paths and other non-JSON values as strings."""
    return json.loads(json.dumps(config, default=str))


# -- progress ------------------------------------------------------------------------------


class _SimpleBar:
    """A minimal stand-in for tqdm: one stderr line every few seconds."""

    def __init__(self, total, initial=0, desc="", unit="it", disable=False, **_):
        self.total, self.n, self.desc, self.unit, self.disable = total, initial, desc, unit, disable
        self.postfix, self._last = "", 0.0

    def update(self, n=1):
        self.n += n
        if not self.disable and time.monotonic() - self._last > 5:
            self._last = time.monotonic()
            print(f"{self.desc}: {self.n}/{self.total} {self.unit} {self.postfix}", file=sys.stderr)

    def set_postfix(self, values=None, refresh=True, **kw):
        self.postfix = " ".join(f"{k}={v}" for k, v in {**(values or {}), **kw}.items())

    def close(self):
        pass


def progress_bar(
    total: int | None, initial: int = 0, desc: str = "", unit: str = "it", disable: bool = False
):
    """A progress bar on stderr: tqdm when installed, else `_SimpleBar`."""
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is installed here
        return _SimpleBar(total, initial, desc, unit, disable)
    return tqdm(
        total=total,
        initial=initial,
        desc=desc,
        unit=unit,
        file=sys.stderr,
        disable=disable,
        dynamic_ncols=True,
        mininterval=2,
        smoothing=0.1,
    )


# -- the run directory ---------------------------------------------------------------------


def _recorded(saved: dict, key: str) -> dict:
    import envs

    try:
        return envs.recorded_options(saved["env"], saved.get(key) or {})
    except KeyError:  # an environment no longer registered: as saved
        return dict(saved.get(key) or {})


class RunDir:
    """The run directory ``path`` of a trainer with configuration ``config``
    (a JSON-able dict).

    Args:
      path: the directory (created, with its parents, when missing).
      config: the run's configuration; saved as ``config.json`` with
        ``trainer`` added.
      resume: ``None``: continue the run found there (a checkpoint) or start
        one; ``True``: continue it, refusing a directory without a
        checkpoint; ``False``: start one, refusing a directory that holds a
        checkpoint. A fresh run restarts ``scalars.jsonl``.
      fixed: keys whose saved value a continued run must share.
      env_key: the config key holding the run's `envs.load` overrides of its
        ``env`` (``config`` names every deviating default in them,
        `envs.explicit_options`): a saved run's are read as the settings they
        stood for (`envs.recorded_options`), so a run made before a default
        changed continues on its own settings or is refused, never silently
        continued on new ones.
      trainer: the command that trains (e.g. ``"python -m hier_agents.train"``);
        a continued run must have been made by it. A directory made before
        runs recorded their trainer is taken as the trainer's when its config
        has ``fixed[0]``.
      tensorboard: also write TensorBoard events.
      checkpoint: the name of the latest checkpoint's file, whose presence
        marks a run to continue (`load` and `save` are for ``checkpoint.pt``
        payloads; a trainer with its own format writes that file itself).

    Raises:
      UsageError: ``path`` is a file; ``resume`` is True without a checkpoint
        or False with one; the directory holds another trainer's run; a
        ``fixed`` key differs from the saved run's (the message names it).
    """

    def __init__(
        self,
        path: str | Path,
        config: dict,
        *,
        resume: bool | None = False,
        fixed=(),
        env_key: str | None = None,
        trainer: str = "",
        tensorboard: bool = True,
        checkpoint: str = CHECKPOINT,
    ) -> None:
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise UsageError(f"the run directory {str(self.path)!r} is a file; give a folder")
        self.checkpoint_path = self.path / checkpoint
        found = self.checkpoint_path.is_file()
        if resume is True and not found:
            raise UsageError(
                f"nothing to resume: no {checkpoint} in {str(self.path)!r} "
                f"(drop --resume to start a run there)"
            )
        if resume is False and found:
            raise UsageError(
                f"{str(self.path)!r} already holds a run ({checkpoint}); "
                f"continue it with --resume or choose another directory"
            )
        self.resumed = found and resume is not False
        config = jsonable({**config, "trainer": trainer} if trainer else config)
        if self.resumed:
            saved = self._saved_config()
            if env_key is not None and "env" in saved:
                saved = {**saved, env_key: _recorded(saved, env_key)}
            self._check_same_run(saved, config, fixed, trainer)
            config = {**saved, **config}
        self.path.mkdir(parents=True, exist_ok=True)
        self.config = config
        atomic_write_text(json.dumps(config, indent=2) + "\n", self.path / CONFIG)
        self._jsonl = open(self.path / SCALARS, "a" if self.resumed else "w")
        self._tb = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter

                self._tb = SummaryWriter(str(self.path))
            except ImportError:  # pragma: no cover - tensorboard is a dependency
                print(
                    f"tensorboard is not installed: scalars go to {SCALARS} only", file=sys.stderr
                )
        self.stop_requested = False
        self.bar = None

    def _check_same_run(self, saved: dict, config: dict, fixed, trainer: str) -> None:
        """Raises `UsageError` unless ``saved`` is a run ``config`` may continue."""
        where = str(self.path)
        made_by = saved.get("trainer")
        if trainer and made_by and made_by != trainer:
            raise UsageError(
                f"{where!r} holds a run of {made_by}, not of {trainer}; choose another directory"
            )
        if trainer and not made_by and fixed and fixed[0] not in saved:
            raise UsageError(
                f"{where!r} holds a checkpoint that is not a run of {trainer} "
                f"(its config has no {fixed[0]!r}); choose another directory"
            )
        for key in fixed:
            if key in saved and saved[key] != config.get(key):
                raise UsageError(
                    f"{where!r} holds a run trained with {key}={saved[key]!r}, "
                    f"not {config.get(key)!r}; choose another directory or "
                    f"the same {key}"
                )

    def _saved_config(self) -> dict:
        """The saved run's configuration: ``config.json``, else (a run from
        before config.json) the checkpoint's ``config``.

        Raises:
          UsageError: neither can be read as a run's configuration."""
        try:
            if (self.path / CONFIG).exists():
                saved = json.loads((self.path / CONFIG).read_text())
            else:
                saved = torch.load(self.checkpoint_path, map_location="cpu", weights_only=False)
                saved = saved.get("config") if isinstance(saved, dict) else None
        except Exception as exc:  # noqa: BLE001 - whatever is wrong with the files, it is the input
            raise UsageError(
                f"{str(self.path)!r} holds a {self.checkpoint_path.name} whose run cannot be "
                f"read ({type(exc).__name__}); choose another directory"
            ) from None
        if not isinstance(saved, dict):
            raise UsageError(
                f"{str(self.path)!r} holds a {self.checkpoint_path.name} without a run "
                f"configuration; choose another directory"
            )
        return dict(saved)

    def record(self, **fields) -> None:
        """Adds ``fields`` (JSON-able) to the run's configuration: ``config.json``
        now, and the checkpoints saved from now on."""
        self.config.update(jsonable(fields))
        atomic_write_text(json.dumps(self.config, indent=2) + "\n", self.path / CONFIG)

    # checkpoints

    def load(self, restore_rng: bool = True) -> dict | None:
        """The checkpoint's payload when resuming (None for a fresh run);
        ``restore_rng``: the torch/numpy/python RNGs continue where they were."""
        if not self.resumed:
            return None
        data = torch.load(self.checkpoint_path, map_location="cpu", weights_only=False)
        if restore_rng and "rng" in data:
            set_rng_state(data["rng"])
        return data

    def save(self, payload: dict, keep: str | None = None, lean=None) -> Path:
        """Writes ``payload`` + ``config`` + ``rng`` atomically to ``checkpoint.pt``;
        ``keep``: also as ``checkpoints/KEEP.pt``, the same data or, with
        ``lean`` (a function of the data), ``lean(data)`` (e.g. without the
        optimiser: a kept copy for evaluation, which resuming never reads).
        Returns the checkpoint's path."""
        data = {**payload, "config": self.config, "rng": rng_state()}
        atomic_save(data, self.checkpoint_path)
        if keep is not None:
            kept = self.path / KEPT
            kept.mkdir(exist_ok=True)
            if lean is not None:
                atomic_save(lean(data), kept / f"{keep}.pt")
            else:
                atomic_write(
                    kept / f"{keep}.pt", lambda tmp: shutil.copyfile(self.checkpoint_path, tmp)
                )
        return self.checkpoint_path

    # scalars and progress

    def log(self, step: int, scalars: dict, tb_prefix: str = "") -> None:
        """One ``scalars.jsonl`` line ``{"step": step, **scalars}``; the finite
        numbers also as TensorBoard scalars ``tb_prefix + key`` at ``step``."""
        self._jsonl.write(json.dumps({"step": int(step), **scalars}, default=float) + "\n")
        self._jsonl.flush()
        if self._tb is not None:
            for key, value in scalars.items():
                if (
                    isinstance(value, (int, float, np.number))
                    and not isinstance(value, bool)
                    and math.isfinite(value)
                ):
                    self._tb.add_scalar(tb_prefix + key, value, step)

    def progress(
        self,
        total: int | None,
        initial: int = 0,
        desc: str = "",
        unit: str = "it",
        disable: bool = False,
    ):
        """Opens (and returns) the run's progress bar; `close` closes it."""
        if self.bar is not None:
            self.bar.close()
        self.bar = progress_bar(total, initial, desc, unit, disable)
        return self.bar

    # Ctrl-C

    @contextlib.contextmanager
    def interruptible(self, signals=(signal.SIGINT, signal.SIGTERM)):
        """Inside: the first of ``signals`` sets ``stop_requested`` (the trainer
        finishes its update, saves, stops); a second SIGINT raises
        KeyboardInterrupt. Outside the main thread: no handlers."""
        if threading.current_thread() is not threading.main_thread():
            yield self
            return

        def handler(signum, frame):
            if self.stop_requested and signum == signal.SIGINT:
                raise KeyboardInterrupt
            self.stop_requested = True
            print(
                f"\n{signal.Signals(signum).name}: stopping after this update "
                f"(Ctrl-C again to abort)",
                file=sys.stderr,
            )

        previous = {s: signal.signal(s, handler) for s in signals}
        try:
            yield self
        finally:
            for s, h in previous.items():
                signal.signal(s, h)

    def close(self) -> None:
        """Closes the bar, ``scalars.jsonl`` and the TensorBoard writer."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        if not self._jsonl.closed:
            self._jsonl.close()
        if self._tb is not None:
            self._tb.close()
            self._tb = None

    def __enter__(self) -> "RunDir":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
