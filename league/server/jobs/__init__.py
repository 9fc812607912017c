"""Background jobs: validating, evaluating and racing submissions.

    queue.py      the jobs table is the queue; this module only wakes workers (PostgreSQL NOTIFY)
    leases.py     the jobs' leases in the database: claim, heartbeat, complete, reap
    runner.py     running one job: claim, heartbeats while its handler works, the outcome
    worker.py     a worker process: job threads claiming from the table, the reaper, its heartbeat
    registry.py   the workers table: which workers are alive (/api/health)
    placement.py  which CPUs a job thread and its sandboxes use
    alive.py      the worker's sign of life on its machine (`league worker --check`)
    handlers.py   every kind of job, by name: validate.py, evaluate.py, race.py, probe.py

Why the database is the queue: every user-visible status lives there anyway, and a separate
queue's messages can be lost (a crash after one is taken, a restore, a flushed Redis, an upgrade
that renamed the task) or delivered twice, leaving a job that waits with nothing to wake it. Here
a job is queued by its row alone; each job thread claims the fairest queued row by a conditional
UPDATE (one worker wins), results are written in the transaction that ends the lease, and the
reaper re-queues what a dead worker left behind (as fishtest scavenges dead tasks). Wake-ups only
shorten the wait: PostgreSQL's LISTEN/NOTIFY, and a short poll (`queue_poll_s`) whatever happens.
"""
