"""The ``league`` command: evaluate agents, race them, watch replays, draw tracks.

    league evaluate model.onnx --episodes 100 --seed 0
    league race model.onnx heuristic --seed 3 --save race.gif --replay race.json
    league replay race.json --save race.mp4
    league track --seed 3 --save track.png
    league check model.onnx && league submit model.onnx --wait      (a league server: league login)

Errors print one line saying what went wrong and what to do, and exit with status 2
(``LEAGUE_DEBUG=1`` shows the traceback). Output into a pipe whose reader quit (``league ... |
head``) ends the command quietly, with status 141 as SIGPIPE would (league/command.py runs every
command; league/exit_codes.py names the statuses).

This module composes the command: the toolkit's commands are here; the baselines' (``train``,
``export``), the client's (league/client/) and, when the server extra is installed, the server's
(``serve``, ``worker``, ``init``, ``migrate``, ``backup``, ``restore``, ``config``, ``users``, through
``league.server.cli.add_commands``) are added to it. None of them imports this module.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence

from league.command import UsageError, add_env_switches, add_version, env_options, run
from league.exit_codes import EXIT_OK

AGENT_HELP = "an ONNX (.onnx) or TorchScript (.pt) file, or 'heuristic' (the built-in driver)"


def _env_flags() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    add_env_switches(parent.add_argument_group("environment options (all on by default, as in the thesis)"))
    return parent


def _save_or_show(parser: argparse.ArgumentParser, save_help: str,
                  show_help: str = "play it in a window (needs a display)") -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--show", action="store_true", help=show_help)
    group.add_argument("--save", metavar="FILE", help=save_help)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="league", description="MicroRacer League: evaluate and race driving agents.")
    add_version(parser)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    env_flags = _env_flags()

    evaluate = subparsers.add_parser(
        "evaluate", parents=[env_flags], help="run an agent over many random tracks and print its metrics",
        description="Run an agent over EPISODES random tracks (seeded: the same seed gives every agent the same "
                    "tracks) and print completed laps, mean return, mean steps and mean speed.")
    evaluate.add_argument("agent", metavar="AGENT", help=AGENT_HELP)
    evaluate.add_argument("--episodes", type=_positive_int, default=100, help="number of episodes (default 100)")
    evaluate.add_argument("--seed", type=_seed, default=0, help="the run's seed (default 0)")
    evaluate.add_argument("--json", action="store_true", help="print the full result as JSON instead of a table")
    evaluate.add_argument("--per-episode", action="store_true", help="also list every episode")
    evaluate.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    evaluate.set_defaults(run=run_evaluate)

    race = subparsers.add_parser(
        "race", parents=[env_flags], help="race agents on one track and print the classification",
        description="Race agents against each other on one shared random track (one car per AGENT).")
    race.add_argument("agents", metavar="AGENT", nargs="+", help=AGENT_HELP)
    race.add_argument("--seed", type=_seed, default=0, help="seed of the track and start speed (default 0)")
    race.add_argument("--names", nargs="+", metavar="NAME", help="display names, one per agent")
    _save_or_show(race, "save the animation to a .gif or .mp4 file")
    race.add_argument("--replay", metavar="FILE", help="save the race's replay (JSON) to FILE")
    race.add_argument("--json", action="store_true", help="print the classification as JSON")
    race.set_defaults(run=run_race)

    replay = subparsers.add_parser("replay", help="show or save the animation of a saved race",
                                   description="Print a saved race's classification and show or save its animation.")
    replay.add_argument("replay", metavar="REPLAY", help="a replay file written by 'league race --replay'")
    _save_or_show(replay, "save the animation to a .gif or .mp4 file")
    replay.set_defaults(run=run_replay)

    track = subparsers.add_parser(
        "track", parents=[env_flags], help="draw a random track",
        description="Draw the track of 'league race --seed SEED' (or, with --episode I, the track of episode I "
                    "of 'league evaluate --seed SEED').")
    track.add_argument("--seed", type=_seed, default=0, help="seed (default 0)")
    track.add_argument("--episode", type=_non_negative_int, help="the track of this episode of an evaluation")
    _save_or_show(track, "save the picture to a .png file", "show it in a window (needs a display)")
    track.set_defaults(run=run_track)

    _add_server_commands(subparsers)
    return parser


def _add_server_commands(subparsers) -> None:
    from league.baselines.cli import add_commands as add_baseline_commands  # imports torch only when run
    from league.client.parser import add_commands as add_client_commands  # imports httpx only when run

    add_baseline_commands(subparsers)
    add_client_commands(subparsers)
    try:
        from league.server.cli import add_commands
    except ImportError:  # the server extra is not installed
        return
    add_commands(subparsers)


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _non_negative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {value}")
    return value


def _seed(text: str) -> int:
    value = int(text)
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"a seed is an integer in [0, 2**63), got {value}")
    return value


# --------------------------------------------------------------------------- commands


def run_evaluate(args: argparse.Namespace) -> int:
    from league.evaluation import metrics_run

    agent = _load(args.agent)
    result = metrics_run(agent, episodes=args.episodes, seed=args.seed, progress=not args.no_progress,
                         **env_options(args))
    print(json.dumps(result.to_dict(), indent=2) if args.json else result.table(per_episode=args.per_episode))
    return EXIT_OK


def run_race(args: argparse.Namespace) -> int:
    from league.evaluation import race, save_replay

    if args.names is not None and len(args.names) != len(args.agents):
        raise UsageError(f"--names gives {len(args.names)} names for {len(args.agents)} agents; give one per agent")
    _check_animation_output(args.save)
    _check_output(args.replay, (".json",))
    if args.show:
        _require_display()
    agents = [_load(path) for path in args.agents]
    result = race(agents, seed=args.seed, names=args.names, **env_options(args))
    print(json.dumps(result.to_dict(), indent=2) if args.json else f"race on seed {args.seed}\n{result.table()}")
    if args.replay:
        print(f"replay saved to {save_replay(result, args.replay)}", file=sys.stderr)
    _animate(result.replay, args)
    return EXIT_OK


def run_replay(args: argparse.Namespace) -> int:
    from league.evaluation import classification_table, load_replay

    if not os.path.isfile(args.replay):
        raise UsageError(f"no such replay file: {args.replay} (write one with 'league race ... --replay FILE')")
    _check_animation_output(args.save)
    replay = load_replay(args.replay)
    print(f"race on seed {replay['seed']}\n{classification_table(replay['classification'])}")
    if not (args.show or args.save):
        print("add --show to watch it or --save race.gif to save the animation", file=sys.stderr)
    _animate(replay, args)
    return EXIT_OK


def run_track(args: argparse.Namespace) -> int:
    from league import render
    from league.env import MicroRacerEnv
    from league.evaluation import episode_seeds

    if not (args.show or args.save):
        raise UsageError("say what to do with the track: --save track.png or --show")
    _check_output(args.save, (".png",))
    seed = args.seed if args.episode is None else episode_seeds(args.seed, args.episode + 1)[args.episode]
    env = MicroRacerEnv(**env_options(args))
    env.reset(seed=seed)  # the very track an episode or race with this seed is run on
    title = f"seed {args.seed}" + ("" if args.episode is None else f", episode {args.episode}")
    if args.save:
        print(f"track saved to {render.save_track_png(env.track, args.save, title=title)}", file=sys.stderr)
    else:
        _require_display()
        render.show_track(env.track, title=title)
    return EXIT_OK


def _load(path: str):
    """Load an agent; a failure names the file it came from."""
    from league.agents import AgentError, load_agent

    try:
        return load_agent(path)
    except AgentError as error:
        reason = error.reason if os.path.basename(path) in error.reason else f"{path}: {error.reason}"
        raise AgentError(reason) from error


def _animate(replay: dict, args: argparse.Namespace) -> None:
    from league import render

    if args.save:
        path = render.animate_replay(replay, save=args.save)
        print(f"animation saved to {path}", file=sys.stderr)
    elif args.show:
        render.animate_replay(replay, show=True)


def _check_output(path: str | None, suffixes: tuple[str, ...]) -> None:
    """Fail before the work, not after it: the file type must be known and its folder must exist."""
    if path is None:
        return
    if not path.lower().endswith(suffixes):
        raise UsageError(f"cannot write {path}: use a file name ending in {' or '.join(suffixes)}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise UsageError(f"cannot write {path}: the folder {folder} does not exist")


def _check_animation_output(path: str | None) -> None:
    from league import render

    _check_output(path, (".gif", ".mp4"))
    if path is not None:
        render.check_animation_path(path)


def _require_display() -> None:
    from league import render

    render.require_display()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``league`` console script; returns the exit status."""
    return run(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
