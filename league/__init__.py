"""MicroRacer League: a didactic deep-RL racing environment, student toolkit and league server.

`import league` registers the Gymnasium id "league/MicroRacer-v0" (with its native vector env:
``gymnasium.make_vec("league/MicroRacer-v0", num_envs=8, vectorization_mode="vector_entry_point")``).
"""
import gymnasium
from gymnasium.envs.registration import register

from league.env import MicroRacerEnv
from league.parallel_env import MicroRacerParallelEnv, env, parallel_env
from league.physics import MAX_EPISODE_STEPS, RaceOptions
from league.track import Track, generate_track

# The native vector env follows Gymnasium 1.x's vector API (autoreset modes); the single and the
# PettingZoo envs also run on Gymnasium 0.29 (the lower bound, which CleanRL's scripts pin).
VECTOR_API = hasattr(gymnasium.vector, "AutoresetMode")
if VECTOR_API:
    from league.vector_env import MicroRacerVectorEnv, vector_env
else:
    MicroRacerVectorEnv = None

    def vector_env(num_envs: int = 8, render_mode: str | None = None, **options):
        raise RuntimeError(f"league.vector_env needs Gymnasium >= 1.0 (its vector API); this is Gymnasium "
                           f"{gymnasium.__version__}: pip install -U gymnasium")

__version__ = "0.1.0"

# The time limit is Gymnasium's TimeLimit wrapper, so gym.make(..., max_episode_steps=N) sets it;
# the entry point turns the env's own limit (for direct construction) off. make_vec passes the
# limit to the vector env as its max_episode_steps option.
register(id="league/MicroRacer-v0", entry_point="league.env:registered_env", max_episode_steps=MAX_EPISODE_STEPS,
         **({"vector_entry_point": "league.vector_env:MicroRacerVectorEnv"} if VECTOR_API else {}))

__all__ = ["MicroRacerEnv", "MicroRacerParallelEnv", "MicroRacerVectorEnv", "RaceOptions", "Track", "env",
           "generate_track", "parallel_env", "vector_env"]

# The thesis' interface (section 3.4-3.6) and the toolkit's entry points.
from league.agents import AgentError, heuristic_agent, load_agent  # noqa: E402
from league.compat import Racer, metrics_run, newrun  # noqa: E402

__all__ += ["AgentError", "Racer", "heuristic_agent", "load_agent", "metrics_run", "newrun"]
