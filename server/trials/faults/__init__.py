"""Surprise campaigns: thousands of virtual-time runs, each with one seeded fault put into the
physics world, the robot or the link, judged from the physics' own truth (``teleprog trial faults``).

- ``catalogue``: the fault kinds and their seeded draw;
- ``inject``: putting a fault into a running session at its moment (``link``: the faulty link);
- ``judge``: ground truth every servo period, and each run's verdict;
- ``campaign``: groups of runs on one world (a fault-free twin and its faulted runs), executors, replay;
- ``results``: the run records, the summary and its table.
"""
