"""Trials (thesis §4.6): headless, repeatable experiments on whole sessions, in real time (real
``teleprog up`` processes driven through the console's HTTP API) or in virtual time (the same
sans-I/O cores in one process on one clock).

| module | what it holds |
|---|---|
| ``script.py`` | the approach trial's scripted operator: home to above the peg in statements of about 1 s |
| ``programs.py`` | the peg transfer for a cell, phase by phase (approach, grasp, extract, carry, insert, release) |
| ``approach.py`` | the approach trial: online against step by step |
| ``kinds.py`` | the grasp, extract, insert and transfer trials: how each mode sends its statements |
| ``drivers.py`` | the one interface a trial drives, and its real-time driver (the HTTP API) |
| ``virtual_clock.py`` | the virtual-time driver: console sender and planner, link and telerobot in one process |
| ``open.py`` | one run's session on the clock asked for |
| ``session.py`` | a real ``teleprog up`` as a child process and a small client of its API |
| ``batch.py`` | seeded worlds, one spec per run, the executors (this process, local processes, Dask) |
| ``results.py``, ``kind_results.py`` | typed results per statement, run and mode, and their summaries |
| ``stats.py`` | medians, quartiles and Wilson intervals |
| ``report.py``, ``plots.py`` | the terminal and Markdown tables, JSON and CSV, the PNG plots |
"""
