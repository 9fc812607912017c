"""The race job's pieces without a server: a car whose agent cannot start, and cleaning up."""
from __future__ import annotations

import pytest

from league.agents import heuristic_agent
from league.server.jobs.race import FailedAgent, InvalidRaceSettings, car_limits, public, race_in_sandboxes
from league.validation.limits import SandboxLimits


class Tracked:
    """A heuristic driver that records whether it was closed."""

    def __init__(self):
        self.agent, self.closed = heuristic_agent(), False
        self.obs_dim, self.name = self.agent.obs_dim, "tracked"

    def __call__(self, obs):
        return self.agent(obs)

    def close(self):
        self.closed = True


def test_a_car_whose_agent_could_not_start_is_a_dnf_with_the_reason():
    cars = [lambda: FailedAgent(5, "broken", "the model did not load: truncated file"), heuristic_agent]
    result = race_in_sandboxes(cars, ["broken", "driver"], seed=3, env_options={})
    by_name = {row["name"]: row for row in result.classification}
    assert by_name["broken"]["outcome"] == "dnf"
    assert by_name["broken"]["reason"] == "the model did not load: truncated file"
    assert by_name["broken"]["distance"] == 0.0 and by_name["driver"]["outcome"] != "dnf"
    assert [row["position"] for row in result.classification] == [1, 2] and by_name["driver"]["position"] == 1


def test_started_agents_are_closed_when_a_later_start_fails():
    first = Tracked()

    def fails():
        raise OSError("no space left on device")

    with pytest.raises(OSError, match="no space"):  # an infrastructure failure: the job is retried
        race_in_sandboxes([lambda: first, fails], ["a", "b"], seed=0, env_options={})
    assert first.closed


def test_options_the_simulator_refuses_are_invalid_race_settings_and_agents_are_closed():
    first = Tracked()
    with pytest.raises(InvalidRaceSettings, match="invalid race settings"):
        race_in_sandboxes([lambda: first], ["a"], seed=0, env_options={"curves": -1})
    assert first.closed


def test_the_public_classification_keeps_a_dnf_reason_but_not_the_models_own_words():
    rows = [{"car": "car_0", "outcome": "dnf", "reason": "the model raised RuntimeError: \u202eevil.exe; see "
                                                        "https://x.test"},
            {"car": "car_1", "outcome": "dnf", "reason": "the model returned NaN or infinite actions"},
            {"car": "car_2", "outcome": "off_road", "reason": "off road"}]
    assert [row["reason"] for row in public(rows)] == [
        "the model raised RuntimeError", "the model returned NaN or infinite actions", "off road"]


def test_the_cars_of_a_race_share_its_memory():
    limits = SandboxLimits(memory_mb=512)
    assert car_limits(limits, cars=10, race_memory_mb=2048).memory_mb == 204  # 10 x 204 MB: within the race's 2 GB
    assert car_limits(limits, cars=2, race_memory_mb=2048).memory_mb == 512  # never more than a sandbox's own cap
