"""MicroRacer League: a didactic deep-RL racing environment, student toolkit and league server.

`import league` registers the Gymnasium id "league/MicroRacer-v0".
"""
from gymnasium.envs.registration import register

from league.env import MicroRacerEnv
from league.parallel_env import MicroRacerParallelEnv, env, parallel_env
from league.physics import RaceOptions
from league.track import Track, generate_track

__version__ = "0.1.0"

register(id="league/MicroRacer-v0", entry_point="league.env:MicroRacerEnv")

__all__ = ["MicroRacerEnv", "MicroRacerParallelEnv", "RaceOptions", "Track", "env", "generate_track", "parallel_env"]

# The thesis' interface (section 3.4-3.6) and the toolkit's entry points.
from league.agents import AgentError, heuristic_agent, load_agent  # noqa: E402
from league.compat import Racer, metrics_run, newrun  # noqa: E402

__all__ += ["AgentError", "Racer", "heuristic_agent", "load_agent", "metrics_run", "newrun"]
