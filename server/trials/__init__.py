"""Trials (thesis §4.6): headless, repeatable experiments run through the real console API, the
delayed link and the telerobot, each run a whole ``teleprog up`` session.

Built so far: the approach trial (``teleprog trial approach``), online teleprogramming against
step by step. The parts:

| module | what it holds |
|---|---|
| ``script.py`` | the scripted operator motion: the approach path cut into statements of about 1 s |
| ``session.py`` | one ``teleprog up`` as a child process and a small client of its HTTP API |
| ``approach.py`` | the approach trial's two modes and a batch of runs |
| ``results.py`` | typed results per statement, mode and run, the summary with the thesis's figures |
| ``report.py`` | the terminal table, results.json and results.csv |
"""
