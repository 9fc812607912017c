"""`python -m league.server serve|worker|users ...`: the server's commands without the toolkit's CLI."""
import sys

from league.server.cli import main

sys.exit(main())
