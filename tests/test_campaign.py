"""Robustness campaigns without a cluster: distributions, seeds, campaign files, one run's row, the store,
the Wilson interval, the command line's refusals; the runs on Dask are in tests/test_campaign_dask.py.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from helpers import SHORT_HOP
from scipy import stats

from fpr.model.errors import CampaignError
from fpr.robustness.campaign_file import campaign_to_toml, load_campaign
from fpr.robustness.outcomes import fly
from fpr.robustness.runner import make_flight
from fpr.robustness.spec import Campaign, parse_distribution
from fpr.robustness.store import RunStore
from fpr.robustness.summary import Z95, failure_kind, summarise, wilson_interval


@pytest.fixture(scope="module")
def short_mission(tmp_path_factory):
    path = tmp_path_factory.mktemp("mission") / "short.toml"
    path.write_text(SHORT_HOP)
    return str(path)


def _draws(text, n=4000, seed=3):
    (dist,) = parse_distribution(text)
    rng = np.random.default_rng(seed)
    return np.array([dist.draw(rng, i, n) for i in range(n)])


def test_distributions_match_their_definitions():
    u = _draws("uniform(0.9, 1.1)")
    assert u.min() >= 0.9 and u.max() <= 1.1 and stats.kstest(u, stats.uniform(0.9, 0.2).cdf).pvalue > 1e-3
    g = _draws("normal(1, 0.03)")
    assert stats.kstest(g, stats.norm(1, 0.03).cdf).pvalue > 1e-3
    t = _draws("truncnormal(0, 1, -0.5, 2)")
    reference = stats.truncnorm(-0.5, 2, loc=0, scale=1)  # scipy's own truncated normal
    assert t.min() >= -0.5 and t.max() <= 2 and stats.kstest(t, reference.cdf).pvalue > 1e-3
    ln = _draws("lognormal(2, 0.1)")
    assert stats.kstest(ln, stats.lognorm(0.1, scale=2).cdf).pvalue > 1e-3
    lu = _draws("loguniform(0.1, 10)")
    assert stats.kstest(lu, stats.loguniform(0.1, 10).cdf).pvalue > 1e-3
    c = _draws("choice(1, 2, 4)")
    assert set(np.unique(c)) == {1.0, 2.0, 4.0} and abs((c == 4).mean() - 1 / 3) < 0.03
    assert np.allclose(_draws("linspace(-1, 1)", n=5), [-1, -0.5, 0, 0.5, 1])
    assert np.all(_draws("0.25", n=3) == 0.25)


@pytest.mark.parametrize("text", ["uniform(2, 1)", "normal(0, -1)", "gamma(1, 1)", "uniform(1)",
                                  "uniform(0, inf)", "loguniform(0, 1)", "uniform(0, 'a')", "normal(0, 1"])
def test_a_wrong_distribution_is_refused(text):
    with pytest.raises(CampaignError):
        parse_distribution(text)


def test_vectors_take_one_distribution_per_component():
    campaign = Campaign(runs=3).with_vary("wind", "normal([0, 2, 0], [1, 1, 0.5])")
    assert campaign.columns == ("wind_x", "wind_y", "wind_z")
    assert campaign.vary["wind_y"].params == (2.0, 1.0) and campaign.vary["wind_z"].params == (0.0, 0.5)
    with pytest.raises(CampaignError, match="one number per component"):
        Campaign().with_vary("wind", "normal([0, 1], 1)")
    with pytest.raises(CampaignError, match="NAME=DISTRIBUTION"):
        Campaign().with_vary("wind y", "1")


def test_a_run_draws_from_its_own_child_of_the_campaign_seed():
    base = (Campaign(runs=10, seed=42).with_vary("model_mass_scale", "uniform(0.9, 1.1)")
            .with_vary("wind", "normal(0, 1)"))
    children = np.random.SeedSequence(42).spawn(10)  # what SeedSequence.spawn gives, independently
    for i in (0, 3, 9):
        rng = np.random.default_rng(children[i].spawn(1)[0])  # spawn_key (i, 0)
        expected = [rng.uniform(0.9, 1.1)] + [rng.standard_normal() for _ in range(3)]
        assert np.allclose(list(base.values(i).values()), expected, rtol=0, atol=0)
    bigger = Campaign(**{**base.__dict__, "runs": 1000})
    assert bigger.values(7) == base.values(7)  # not a function of the number of runs
    assert base.key("m") == bigger.key("m") != Campaign(**{**base.__dict__, "seed": 43}).key("m")
    assert len({base.noise_seed(i) for i in range(10)}) == 10


def test_the_wilson_interval_inverts_the_score_test():
    assert wilson_interval(0, 10)[0] == 0 and math.isclose(wilson_interval(0, 10)[1], Z95**2 / (10 + Z95**2))
    for k, n in ((3, 10), (97, 100), (50, 200)):
        p_hat = k / n
        for p in wilson_interval(k, n):  # each end: |p_hat - p| = z sqrt(p (1 - p) / n)
            assert math.isclose(abs(p_hat - p), Z95 * math.sqrt(p * (1 - p) / n), rel_tol=1e-9)


def test_a_campaign_file_round_trips(tmp_path, short_mission):
    campaign = Campaign(mission=short_mission, method="none", runs=12, seed=5, hold=0.5, tracking_tolerance=0.02,
                        robot_parameters={"link_length": 0.8})
    campaign = campaign.with_vary("wind", "normal(0, 1)").with_vary("initial_error.q1", "uniform(-0.01, 0.01)")
    path = tmp_path / "c.toml"
    path.write_text(campaign_to_toml(campaign))
    assert load_campaign(path) == campaign
    path.write_text('runs = 3\nspeed = 1\n')
    with pytest.raises(CampaignError, match="unknown field"):
        load_campaign(path)
    path.write_text('[vary]\nwind = "uniform(1, 0)"\n')
    with pytest.raises(CampaignError, match=r"c.toml: wind=uniform\(1.0, 0.0\): give the lower bound first"):
        load_campaign(path)


def test_a_run_row_says_what_happened(short_mission):
    campaign = Campaign(mission=short_mission, method="none", runs=3, hold=0.2).with_vary("wind_y", "choice(0, 300)")
    flight, result = make_flight(campaign)
    assert result.feasible and flight.chain == ("q1", "q2")
    calm = fly(flight, 0, {"wind_y": 0.0}, 1)
    assert calm["success"] and not calm["lost"] and calm["error"] == "" and calm["saturated_ticks"] == 0
    assert max(calm["max_error_q1"], calm["max_error_q2"]) < 0.01 and 0 < calm["least_clearance_m"] < 1.0
    assert math.isclose(calm["simulated_s"], 1.2, abs_tol=1e-9)
    storm = fly(flight, 1, {"wind_y": 300.0}, 1)  # 300 N sideways on a 1 kg drone
    assert not storm["success"] and storm["lost"] and storm["simulated_s"] < 1.0
    assert storm["failure_time_s"] == pytest.approx(storm["simulated_s"] + 0.0, abs=2e-3)
    # a value out of its range: a row with its error
    broken = fly(flight, 2, {"wind_y": 0.0, "model_mass_scale": -1.0}, 1)
    assert not broken["success"] and broken["error"].startswith("ModelArgumentError") and broken["index"] == 2
    summary = summarise([calm, storm, broken], ["wind_y"], list(flight.columns))
    assert summary["successes"] == 1 and summary["lost"] == 1 and summary["errors"] == 1
    assert summary["outcomes"]["least_clearance_m"]["count"] == 2  # the error row has no outcomes
    assert list(summary["lost_by_kind"]) == [failure_kind(storm["failure"])]


def test_the_store_keeps_finished_runs_and_refuses_other_folders(tmp_path):
    store = RunStore(tmp_path / "c", "k1", {})
    store.put({"index": 3, "success": True, "x": math.nan, "failure": ""})
    again = RunStore(tmp_path / "c", "k1", {})
    rows = again.load(5)
    assert list(rows) == [3] and math.isnan(rows[3]["x"]) and rows[3]["success"] is True
    json.loads(again.path(3).read_text())  # strict JSON (NaN as null)
    with pytest.raises(CampaignError, match="another campaign"):
        RunStore(tmp_path / "c", "k2", {})
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(CampaignError, match="something else"):
        RunStore(tmp_path / "mine", "k1", {})


@pytest.mark.parametrize("options, words", [
    (["--vary", "model_mass_scale=uniform(0, 1.1)"], "it can give 0"),
    (["--vary", "speed=uniform(0, 1)"], "not a quantity"),
    (["--vary", "wind=normal([0, 1], 1)"], "one number per component"),
    (["--vary", "initial_error.q7=normal(0, 1)"], "unknown coordinate"),
    (["--vary", "link_length=uniform(0.01, 1)"], "link_length"),
    (["--runs", "0"], "--runs"),
])
def test_the_command_line_refuses_bad_input_in_one_line(options, words, short_mission, tmp_path):
    command = [sys.executable, "-m", "fpr.campaign", "--mission", short_mission, "--method", "none", "--runs", "2",
               "--out", str(tmp_path / "out"), *options]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and words in lines[0]
    assert not (tmp_path / "out").exists()
