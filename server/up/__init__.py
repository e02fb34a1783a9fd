"""``teleprog up``, the whole product in one command: ``run`` serves the console (or the
sedimentation view) under uvicorn and prints the URL to open; ``stack`` starts, watches and
stops the telerobot and link child processes."""
