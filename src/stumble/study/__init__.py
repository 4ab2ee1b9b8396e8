"""Studies: many trips over a grid of conditions, on local processes or a Dask cluster.

- ``grid``: the grid (command line or TOML), its validation and each run's stable key;
- ``store``: the crash-safe result store (Parquet parts, journals, ``results.parquet``);
- ``runner``: ``run_one``, the executors, progress, ``run_study`` and the summary table;
- ``cli``: ``stumble study``.

A package rather than one ``study.py``: the grid, the store and the executors are three
separate concerns. The grid's tests are ``grid_test.py``; the store's and the executors'
run through ``run_study`` and the command line, in ``runner_test.py``.
"""

from stumble.study.grid import AXES, Grid, load_toml, parse_values, run_key
from stumble.study.runner import StudyInterrupted, StudyResult, run_one, run_study, summary_table
from stumble.study.store import load_results

__all__ = ["AXES", "Grid", "StudyInterrupted", "StudyResult", "load_results", "load_toml",
           "parse_values", "run_key", "run_one", "run_study", "summary_table"]
