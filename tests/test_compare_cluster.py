"""`hier_agents.compare` on a real Ray cluster of two nodes on this machine.

``ray start --head`` and ``ray start --address`` make the cluster (one CPU
each, authentication off); the experiment runs through the command with
``--backend ray``; while it runs, the Ray worker process of one unfinished
job is killed (SIGKILL). Ray retries the task, the job runs again, and the
experiment ends complete: every job's record, both nodes used, the killed
job started twice. ``ray stop`` ends the cluster (and any other Ray
processes of this user on the machine). Slow: about a minute.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from child_env import child_env

ROOT = Path(__file__).resolve().parents[1]
PORT = 6397
SPEC = """
name = "cluster"
cache = "cache"
envs = ["mujoban/level1"]
seeds = [0, 1]
episodes = 8
shard_episodes = 2

[[agent]]
label = "random 10"
random = 10
"""


def _env():
    return child_env(RAY_AUTH_MODE="disabled")


def _ray(*args, check=True):
    return subprocess.run(
        ["ray", *args], env=_env(), capture_output=True, text=True, timeout=180, check=check
    )


@pytest.fixture
def cluster():
    if _ray("status", "--address", f"127.0.0.1:{PORT}", check=False).returncode == 0:
        pytest.fail(f"a Ray cluster already listens on port {PORT}")
    common = ["--num-cpus=1", "--object-store-memory=150000000", "--disable-usage-stats"]
    try:
        _ray("start", "--head", f"--port={PORT}", "--include-dashboard=false", *common)
        _ray("start", f"--address=127.0.0.1:{PORT}", *common)
        for _ in range(30):
            status = _ray("status", "--address", f"127.0.0.1:{PORT}", check=False).stdout
            if len(re.findall(r"^\s*1 node_", status, re.M)) == 2:
                break
            time.sleep(1)
        else:
            pytest.fail(f"the second node never joined: {status}")
        yield f"127.0.0.1:{PORT}"
    finally:
        _ray("stop", "--force", check=False)


@pytest.mark.slow
def test_an_experiment_survives_a_killed_worker_on_a_two_node_cluster(tmp_path, cluster):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    cache = tmp_path / "cache"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hier_agents.compare",
            str(spec),
            "--backend",
            "ray",
            "--ray-address",
            cluster,
        ],
        env=_env(),
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    killed = None
    try:
        deadline = time.time() + 240
        while killed is None and time.time() < deadline and proc.poll() is None:
            for log in (
                sorted((cache / "attempts").glob("*")) if (cache / "attempts").exists() else []
            ):
                lines = log.read_text().splitlines()
                if len(lines) == 1 and not (cache / "jobs" / f"{log.name}.json").exists():
                    worker = int(re.search(r"parent=(\d+)", lines[0]).group(1))
                    os.kill(worker, signal.SIGKILL)
                    killed = log.name
                    break
            time.sleep(0.2)
        out, _ = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert killed is not None, out
    assert proc.returncode == 0, out
    records = [json.loads(p.read_text()) for p in (cache / "jobs").glob("*.json")]
    assert len(records) == 8
    assert len((cache / "attempts" / killed).read_text().splitlines()) == 2, out
    assert len({r["ray_node"] for r in records}) == 2
    result = json.loads((cache / "comparison.json").read_text())
    (point,) = result["points"]
    assert point["seeds"] == [0, 1] and point["missing_seeds"] == []
    assert result["jobs_missing"] == 0
