"""Model validation, the toolkit's: what the server checks of an upload, and `league check` runs
on a student's machine with no server (or with one, against its limits). Below both the client
and the server: nothing here imports league.server.

    checks.py   static checks of a model file (ONNX graph, TorchScript archive and graph), on its
                structure, before anything of it runs
    loading.py  load a model after those checks, under a memory cap (the server's sandbox and
                `league check` both load models with it)
    timing.py   the CPU time a model may use per call, per run and to load, and how its speed is
                measured; the reasons given when it is over
    limits.py   SandboxLimits and the league's defaults (the server's settings default to them)
    files.py    a model file as the league takes it: its kind, what to do with other kinds, the
                ONNX external data packed into one file
    local.py    `league check`'s run: the model in a child process with the server's budgets
    report.py   ValidationReport, the verdict
"""
