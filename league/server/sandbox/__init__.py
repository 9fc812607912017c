"""Run untrusted models in sandbox processes; the worker and the API never load a model themselves.

    agent.py       SandboxedAgent: a league.agents.Agent whose model lives in a child process, with
                   deadlines and restarts; the worker runs the toolkit's metrics_run and race on it
    process.py     the child process seen from the worker: the fork server that starts it, who it
                   runs as, its environment and directory, the pipe protocol
    child.py       the child itself (run by path, as a script): isolates itself, loads the model,
                   answers observation batches
    validation.py  validating an upload: checks, load and dry run in a sandbox, timed from outside
    log.py         what a sandbox printed, within a size limit

The static checks, the checked load, the CPU budgets and the limits' defaults are the toolkit's
(league.validation), which `league check` runs on a student's machine without a sandbox.

Isolation of the child, done by the child itself before it reads the model (child.confine):
rlimits (CPU, files, address space), a new network namespace, a user id of its own when the worker
is root (else the worker's user), the parent-death signal, no new privileges, Landlock (it reads
only this Python and our package, writes only its own directory, opens no TCP connection, signals
no one outside it) and seccomp (no program, process, namespace, socket, trace, mount, identity
change, session, IPC object, nor any call acting on another process). Besides: a private temporary
directory holding a copy of the model, no inherited file descriptors but its pipes, a clean
environment. Which of these a machine gives is found once by a probe sandbox (process.isolation),
logged with what is missing, and shown by /api/health; unless isolation is full (for a root
worker: with a user id of its own per sandbox) no model runs unless the settings allow it.
"""
