"""Benchmark harness only: `python benchmarks/_fixed_track.py SEED serve ...` runs the server's
CLI (`python -m league.server serve ...`) with every new championship round's track seed SEED,
in this process only.

A round's track is drawn secretly (league.server.course.races.draw_track_seed), so that no one can
derive it before its heats are raced; two trees compared round by round then race different
tracks, and a heat's time moves several-fold with its track. To compare the same track, the
benchmark (`bench_league.py --round-track-seed`) starts its API through this launcher, which
replaces the draw in the module the round is started from before the CLI runs. Nothing in
league/ reads an override: the product has no setting or variable for it.

The trees this can run (PYTHONPATH names the tree, as benchmarks/_league.py starts its servers):
this one and the earlier ones back to e7704ee, where the function has the same name and
`start_round` calls it by its module's global name (in league.server.rounds before issue 34 moved
it into the course package).
"""
from __future__ import annotations

import importlib
import sys

# where start_round lives: this tree's module, then the earlier trees'
ROUND_MODULES = ("league.server.course.races", "league.server.rounds")


def main() -> int:
    if len(sys.argv) < 3:
        print(__doc__.splitlines()[0], file=sys.stderr)
        return 2
    seed = int(sys.argv.pop(1))
    if not 0 <= seed < 2**53:
        raise SystemExit(f"a round's track seed is below 2**53, not {seed}")
    del sys.path[0]  # benchmarks/: the tree on PYTHONPATH is the one run, as with `-m league.server`

    rounds = round_module()
    if not callable(getattr(rounds, "draw_track_seed", None)):
        raise SystemExit(f"{rounds.__file__}: no draw_track_seed(); this launcher cannot fix this tree's round tracks")
    # (whether the tree's rounds really use it is checked where it counts: bench_league.py compares
    # each finished round's published track seed with N)

    def fixed_track_seed() -> int:
        return seed

    rounds.draw_track_seed = fixed_track_seed
    print(f"bench: every new round's track seed is {seed} in this process (benchmarks/_fixed_track.py)",
          file=sys.stderr, flush=True)
    from league.server.cli import main as cli

    return cli(sys.argv[1:])


def round_module():
    """The first of ROUND_MODULES this tree has."""
    for name in ROUND_MODULES:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError as error:
            if not (name + ".").startswith(f"{error.name}."):  # the module is there; something it imports is not
                raise
    raise SystemExit(f"none of {', '.join(ROUND_MODULES)} in this tree: this launcher cannot fix its round tracks")


if __name__ == "__main__":
    sys.exit(main())
