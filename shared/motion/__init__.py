"""Interpreter and trajectory planner: the code both the preview and the telerobot execute."""
