"""Background jobs: validating, evaluating and racing submissions.

    queue.py      Huey, on SQLite (embedded) or Redis: its messages carry job ids only
    leases.py     the jobs' leases in the database: claim, heartbeat, complete, reap
    runner.py     running one job: claim, heartbeats while its handler works, the outcome
    worker.py     a worker process: Huey's consumer running jobs on threads, and the reaper
    placement.py  which CPUs a job thread and its sandboxes use
    alive.py      the worker's sign of life on its machine (`league worker --check`)
    handlers.py   every kind of job, by name: validate.py, evaluate.py, race.py, probe.py

Why both a queue and leases in the database: Huey is a small, well-kept queue that wakes workers
on SQLite and on Redis alike, but a message can be lost (a crash after it is taken) or delivered
twice, and Huey knows nothing of who runs what. So the database, which every user-visible status
lives in anyway, is the record of each job's lease: a message only says "try job N", the
conditional UPDATE of a claim decides who runs it, results are written in the transaction that
ends the lease, and the reaper re-sends what a dead worker or a lost message left behind (as
fishtest scavenges dead tasks). Neither alone gives at-least-once delivery with results counted
once.
"""
