"""MicroRacer League: a didactic deep-RL racing environment, student toolkit and league server.

`import league` registers the Gymnasium id "league/MicroRacer-v0" (with its native vector env:
``gymnasium.make_vec("league/MicroRacer-v0", num_envs=8, vectorization_mode="vector_entry_point")``)
and names the toolkit's entry points below. It imports none of them: each is loaded on first use
(a module-level ``__getattr__``), so ``import league.constants`` or ``import league.validation``
costs the registration (Gymnasium's import, about 45 ms) and that module, without PettingZoo,
the simulator or the evaluation.

    MicroRacerEnv, MicroRacerParallelEnv, MicroRacerVectorEnv   the envs (league.env, .parallel_env, .vector_env)
    make_parallel_env, make_aec_env, make_vector_env            their factories
    RaceOptions, Track, generate_track                          options and tracks (league.options, .track)
    load_agent, heuristic_agent, AgentError                     agents (league.agents)
    Racer, newrun, metrics_run                                  the thesis' interface (league.compat)
"""
import importlib
import importlib.metadata
import importlib.util


def _version() -> str:
    """The installed distribution's version: pyproject.toml's [project] version is its one home (a
    checkout installed with `pip install -e .` has it from there; reinstall after a bump)."""
    try:
        return importlib.metadata.version("microracer-league")
    except importlib.metadata.PackageNotFoundError:  # sources on PYTHONPATH, not installed
        return "0+unknown"


__version__ = _version()

ENV_ID = "league/MicroRacer-v0"

# name -> (module, attribute): what `league.<name>` loads on first use.
_LAZY = {
    "MicroRacerEnv": ("league.env", "MicroRacerEnv"),
    "MicroRacerParallelEnv": ("league.parallel_env", "MicroRacerParallelEnv"),
    "MicroRacerVectorEnv": ("league.vector_env", "MicroRacerVectorEnv"),
    "make_parallel_env": ("league.parallel_env", "parallel_env"),
    "make_aec_env": ("league.parallel_env", "env"),
    "make_vector_env": ("league.vector_env", "make_vector_env"),
    "RaceOptions": ("league.options", "RaceOptions"),
    "Track": ("league.track", "Track"),
    "generate_track": ("league.track", "generate_track"),
    "AgentError": ("league.agents", "AgentError"),
    "heuristic_agent": ("league.agents", "heuristic_agent"),
    "load_agent": ("league.agents", "load_agent"),
    "Racer": ("league.compat", "Racer"),
    "metrics_run": ("league.compat", "metrics_run"),
    "newrun": ("league.compat", "newrun"),
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    """`league.<name>`: an entry point of `_LAZY`, or a submodule (`league.env` is the module)."""
    if name in _LAZY:
        module, attribute = _LAZY[name]
        value = getattr(importlib.import_module(module), attribute)
        globals()[name] = value
        return value
    if not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(name for name in set(globals()) | set(_LAZY) if name != "importlib")


# -------------------------------------------------------------------------- the Gymnasium id


def register_envs() -> None:
    """Register "league/MicroRacer-v0" with Gymnasium (once; the import of league does it).

    The time limit is Gymnasium's TimeLimit wrapper, so gym.make(..., max_episode_steps=N) sets it;
    the entry point turns the env's own limit (for direct construction) off. make_vec passes the
    limit to the vector env as its max_episode_steps option. The native vector env follows
    Gymnasium 1.x's vector API (autoreset modes); the single and the PettingZoo envs also run on
    Gymnasium 0.29 (the lower bound, which CleanRL's scripts pin).
    """
    import gymnasium
    from gymnasium.envs.registration import register, registry

    from league.constants import MAX_EPISODE_STEPS

    if ENV_ID in registry:
        return
    vector_api = hasattr(gymnasium.vector, "AutoresetMode")  # Gymnasium >= 1.0, which league.vector_env needs
    vector = {"vector_entry_point": "league.vector_env:MicroRacerVectorEnv"} if vector_api else {}
    register(id=ENV_ID, entry_point="league.env:registered_env", max_episode_steps=MAX_EPISODE_STEPS, **vector)


register_envs()
