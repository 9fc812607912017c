"""The server's plumbing, which every part of it uses and which knows nothing of courses: the settings
(config), API tokens (security), the clock deadlines are decided by, the log lines' format (logs) and
the services an app or a worker opens once (services)."""
