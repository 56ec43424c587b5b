"""Robustness campaigns on Dask: the same table from 1 worker, 2 workers, a separately started scheduler and
its workers, after a killed worker and after Ctrl-C and a rerun. A short prototype hop keeps each run ~1 s.
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time

import pyarrow.parquet as pq
import pytest
from helpers import SHORT_HOP

from fpr.cli.campaign import main
from fpr.robustness.runner import local_client, make_flight, mission_of, run_campaign
from fpr.robustness.spec import Campaign
from fpr.robustness.store import RunStore

RUNS = 4
DASK = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    path = tmp_path_factory.mktemp("mission") / "short.toml"
    path.write_text(SHORT_HOP)
    return str(path)


def _options(mission, out, runs=RUNS):
    return ["--mission", mission, "--method", "none", "--runs", str(runs), "--seed", "11", "--hold", "0.2",
            "--vary", "wind=normal(0, 1)", "--vary", "model_mass_scale=uniform(0.9, 1.1)", "--noise", "0.0005,0.005",
            "--no-plots", "--out", str(out)]


@pytest.fixture(scope="module")
def reference(mission, tmp_path_factory):
    """The campaign on one local worker: its folder."""
    out = tmp_path_factory.mktemp("reference") / "c"
    assert main([*_options(mission, out), "--workers", "1", "--quiet"]) == 0
    return out


def _comparable(rows):
    """Rows with NaN as None (NaN != NaN)."""
    return [{k: None if isinstance(v, float) and math.isnan(v) else v for k, v in r.items()} for r in rows]


def _table(folder):
    return (folder / "runs.parquet").read_bytes()


def test_one_worker_gives_a_complete_table(reference):
    rows = pq.read_table(reference / "runs.parquet").to_pylist()
    assert [r["index"] for r in rows] == list(range(RUNS))
    assert all(r["success"] and r["error"] == "" for r in rows)  # a gentle campaign: every run flies
    assert len({r["wind_y"] for r in rows}) == RUNS and all(0.9 <= r["model_mass_scale"] <= 1.1 for r in rows)
    assert sorted(p.name for p in (reference / "runs").iterdir()) == [f"{i:06d}.json" for i in range(RUNS)]


def test_two_workers_give_the_same_table_and_a_rerun_reuses_every_run(mission, reference, tmp_path, capsys):
    out = tmp_path / "c"
    assert main([*_options(mission, out), "--workers", "2"]) == 0
    assert _table(out) == _table(reference)
    first = capsys.readouterr()
    assert "0 reused, 4 simulated" in first.out and f"{RUNS}/{RUNS} runs" in first.err
    assert main([*_options(mission, out), "--workers", "2"]) == 0
    assert f"{RUNS} reused, 0 simulated" in capsys.readouterr().out and _table(out) == _table(reference)


def test_a_killed_worker_costs_only_its_runs(mission, reference, tmp_path):
    campaign = Campaign(mission=mission, method="none", runs=RUNS, seed=11, hold=0.2)
    for name, text in (("wind", "normal(0, 1)"), ("model_mass_scale", "uniform(0.9, 1.1)"),
                       ("noise", "[0.0005, 0.005]")):
        campaign = campaign.with_vary(name, text)
    flight, _ = make_flight(campaign)
    store = RunStore(tmp_path / "c", campaign.key(mission_of(campaign).to_toml()), {})
    client = local_client(2)
    killed = []

    def kill_a_busy_worker():
        pids = client.run(os.getpid)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not killed:
            busy = [w for w, keys in client.processing().items() if keys and w in pids]
            if busy:
                time.sleep(0.5)  # well inside its first run
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])
            time.sleep(0.05)

    try:
        killer = threading.Thread(target=kill_a_busy_worker, daemon=True)
        killer.start()
        done = run_campaign(campaign, flight, store, client)
        killer.join(5)
    finally:
        client.close()
        client.cluster.close()
    assert killed, "no worker was killed"
    expected = pq.read_table(reference / "runs.parquet").to_pylist()
    got = [{k: row[k] for k in expected[0]} for row in done.rows]
    assert _comparable(got) == _comparable(expected) and done.computed == RUNS


@pytest.mark.skipif(DASK is None, reason="the dask command line is not installed")
def test_an_external_scheduler_and_workers_give_the_same_table(mission, reference, tmp_path, capsys):
    scheduler_file = tmp_path / "scheduler.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [os.getcwd(), os.environ.get("PYTHONPATH")]))}
    common = dict(env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path)
    scheduler = subprocess.Popen([DASK, "scheduler", "--scheduler-file", str(scheduler_file), "--port", "0",
                                  "--no-dashboard", "--host", "127.0.0.1"], **common)
    workers = None
    try:
        deadline = time.monotonic() + 120
        while not scheduler_file.is_file() and time.monotonic() < deadline:
            time.sleep(0.2)
        import json

        address = json.loads(scheduler_file.read_text())["address"]
        workers = subprocess.Popen([DASK, "worker", address, "--nworkers", "2", "--nthreads", "1",
                                    "--no-dashboard"], **common)
        from distributed import Client

        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=180)
        out = tmp_path / "c"
        assert main([*_options(mission, out), "--scheduler", address]) == 0
        assert "on 2 workers" in capsys.readouterr().out
        assert _table(out) == _table(reference)
    finally:
        for process in (workers, scheduler):
            if process is not None:
                process.send_signal(signal.SIGINT)
        for process in (workers, scheduler):
            if process is not None:
                try:
                    process.wait(30)
                except subprocess.TimeoutExpired:
                    process.kill()


def test_ctrl_c_keeps_the_finished_runs_and_the_same_command_resumes(mission, tmp_path, capsys):
    out, runs = tmp_path / "c", 6
    command = [sys.executable, "-m", "fpr.campaign", *_options(mission, out, runs), "--workers", "1"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and process.poll() is None:
        if (out / "runs").is_dir() and len(list((out / "runs").glob("*.json"))) >= 2:
            break
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    kept = len(list((out / "runs").glob("*.json")))
    assert 2 <= kept < runs and f"interrupted: {kept} of {runs} runs stored" in stderr
    assert not (out / "runs.parquet").exists()
    assert main([*_options(mission, out, runs), "--workers", "1", "--quiet"]) == 0
    rows = pq.read_table(out / "runs.parquet").to_pylist()
    assert [r["index"] for r in rows] == list(range(runs))
    capsys.readouterr()
    # the table of a campaign run in one go: the same bytes
    fresh = tmp_path / "fresh"
    assert main([*_options(mission, fresh, runs), "--workers", "2", "--quiet"]) == 0
    assert _table(fresh) == _table(out)
